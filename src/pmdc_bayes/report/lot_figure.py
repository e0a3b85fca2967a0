"""The lot's figure: per pooled parameter, every motor in the order tested (a control
chart) with its own and its pooled 90 % interval, the population's median and the band
its spread gives, outliers marked; beside it, the population's density of a motor's
value with every motor's own value and interval on it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..io.units import display_unit

__all__ = ["lot_figure"]


def _mark(ax, x, value, interval, scale, colour, label) -> None:
    lo, hi = (b * scale for b in interval)
    v = value * scale
    ax.errorbar([x], [v], yerr=[[v - lo], [hi - v]], fmt="o", ms=3, color=colour, lw=1.5,
                capsize=2, label=label)


def _density(ax, pop: dict, values, outliers) -> None:
    """The population's log-normal density of a motor's value, sideways, with each
    motor's own value and 90 % interval stacked beneath it."""
    median, spread = pop["median"], max(pop["spread"], 1e-12)
    y = median * np.exp(spread * np.linspace(-4.0, 4.0, 200))
    dens = np.exp(-0.5 * (np.log(y / median) / spread) ** 2) / (y * spread * np.sqrt(2 * np.pi))
    ax.plot(dens / dens.max(), y, color="k", lw=1.0)
    ax.fill_betweenx(y, 0.0, dens / dens.max(), color="0.9")
    for k, (v, out) in enumerate(zip(values, outliers, strict=True)):
        h = -0.05 - 0.9 * k / max(len(values), 1)
        lo, hi = v["own_interval"]
        ax.plot([h, h], [lo, hi], color="tab:red" if out else "0.35", lw=1.0)
        ax.plot([h], [v["own"]], "o", ms=2, color="tab:red" if out else "0.35")
    ax.set_xlim(-1.0, 1.05)
    ax.set_xticks([])
    ax.tick_params(labelleft=False)


def lot_figure(record: dict, path: Path) -> Path:
    """Draw ``record`` (:func:`~pmdc_bayes.inference.population.pooling.lot_record`) to ``path``."""
    names = record["parameters"]
    motors = record["motors"]
    fig = Figure(figsize=(10.0, 2.2 * len(names) + 0.6))
    FigureCanvasAgg(fig)
    grid = fig.subplots(len(names), 2, squeeze=False, sharey="row",
                        gridspec_kw={"width_ratios": (4, 1), "wspace": 0.05})
    axes = grid[:, 0]
    for ax in axes[1:]:
        ax.sharex(axes[0])
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    x = np.arange(len(motors))
    z = 1.6448536269514722  # the population's central 90 % band
    scale = 1.0
    for row, (ax, name) in enumerate(zip(axes, names, strict=True)):
        unit = display_unit(record.get("units", {}).get(name, ""))
        pop = record["population"][name]
        centre, spread = pop["median"] * scale, pop["spread"]
        ax.axhline(centre, color="k", lw=1.0, label="population median")
        ax.axhspan(centre * np.exp(-z * spread), centre * np.exp(z * spread), color="0.9",
                   label="population 90 %")
        for k, m in enumerate(motors):
            v = m["values"][name]
            colour = "tab:red" if m["outlier"] else "0.35"
            _mark(ax, k - 0.12, v["own"], v["own_interval"], scale, colour,
                  "own 90 %" if k == 0 else None)
            if v["pooled"] is not None:
                _mark(ax, k + 0.12, v["pooled"], v["pooled_interval"], scale, "tab:blue",
                      "pooled 90 %" if k == 0 else None)
        ax.set_ylabel(f"{name} ({unit})")
        _density(grid[row, 1], pop, [m["values"][name] for m in motors],
                 [m["outlier"] for m in motors])
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", fontsize=7, ncol=4, frameon=False)
    axes[-1].set_xticks(x, [m["motor"] for m in motors], rotation=60, ha="right", fontsize=7)
    axes[-1].set_xlabel("motor, in the order tested (outliers in red)")
    grid[-1, 1].set_xlabel("population density;\neach motor's own 90 %", fontsize=7)
    fig.subplots_adjust(top=0.93, bottom=0.12, left=0.09, right=0.98)
    fig.savefig(path, dpi=110, format="png")
    return path
