"""The lot's figure: per pooled parameter, every motor in the order tested (a control
chart) with its own and its pooled 90 % interval, the population's median and the band
its spread gives, outliers marked."""

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


def lot_figure(record: dict, path: Path) -> Path:
    """Draw ``record`` (:func:`~pmdc_bayes.inference.pooling.lot_record`) to ``path``."""
    names = record["parameters"]
    motors = record["motors"]
    fig = Figure(figsize=(8.0, 2.2 * len(names) + 0.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    x = np.arange(len(motors))
    z = 1.6448536269514722  # the population's central 90 % band
    scale = 1.0
    for ax, name in zip(axes, names, strict=True):
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
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", fontsize=7, ncol=4, frameon=False)
    axes[-1].set_xticks(x, [m["motor"] for m in motors], rotation=60, ha="right", fontsize=7)
    axes[-1].set_xlabel("motor, in the order tested (outliers in red)")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(path, dpi=110, format="png")
    return path
