"""Parameter figures: the corner (pair) plot and the forest plot."""

from __future__ import annotations

import numpy as np

from .._format import row_format
from ..io.units import display_unit
from ._plot import (
    COLORS,
    Line2D,
    NullLocator,
    png,
    scale_of,
    styled,
    subplots,
)
from ._render import Drawing

__all__ = ["corner_figure", "forest_figure", "forest_points", "CORNER_NAMES"]

CORNER_NAMES = ("J", "B", "K", "Tc")
_N_SCATTER = 3000


def _samples(ctx, names):
    """Posterior draws of ``names`` (SI), else draws from the Laplace approximation."""
    idx = [ctx.names.index(n) for n in names]
    if ctx.draws is not None:
        d = ctx.draws[:, idx]
        step = max(1, d.shape[0] // _N_SCATTER)
        return d[::step], "posterior draws"
    mean = np.array([ctx.values["map"][n] for n in names])
    cov = ctx.covariance()[np.ix_(idx, idx)]
    rng = np.random.default_rng(int(ctx.summary.get("seed", 0)))
    return rng.multivariate_normal(mean, cov, size=_N_SCATTER, method="eigh"), \
        "Laplace approximation (no posterior sampled)"


def _limits(x, extra):
    m, s = float(np.mean(x)), float(np.std(x))
    lo, hi = m - 5 * s, m + 5 * s
    for v in extra:  # truth and other points within 10 sd widen the view
        if v is not None and abs(v - m) < 10 * s:
            lo, hi = min(lo, v - s), max(hi, v + s)
    return lo, hi


def _mark(ax, x, y, lims, style, label):
    """A point, or an arrow at the edge pointing to it when it is off the axes."""
    (x0, x1), (y0, y1) = lims
    if x0 <= x <= x1 and y0 <= y <= y1:
        ax.plot(x, y, style["marker"], color=style["color"], ms=8, mec="k", mew=0.6,
                label=label, zorder=5)
        return
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    dx, dy = (x - cx) / (x1 - x0), (y - cy) / (y1 - y0)
    f = 0.45 / max(abs(dx), abs(dy))
    ax.annotate("", xy=(cx + f * dx * (x1 - x0), cy + f * dy * (y1 - y0)),
                xytext=(cx + 0.7 * f * dx * (x1 - x0), cy + 0.7 * f * dy * (y1 - y0)),
                arrowprops={"arrowstyle": "->", "color": style["color"], "lw": 1.6})


@styled
def corner_figure(ctx) -> Drawing:
    """PNG: pair plot of J, B, K (and Tc) with the closed form, MAP and truth."""
    names = [n for n in CORNER_NAMES if n in ctx.names]
    d, source = _samples(ctx, names)
    scales = [scale_of(n, float(np.mean(d[:, k])), ctx.unit(n)) for k, n in enumerate(names)]
    ds = d * np.array([s for s, _ in scales])
    pts = {"closed_form": ctx.values["closed_form"], "map": ctx.values["map"]}
    if ctx.truth:
        pts["truth"] = ctx.truth
    pts = {k: np.array([(v.get(n) if v.get(n) is not None else np.nan) * s
                        for n, (s, _) in zip(names, scales, strict=True)]) for k, v in pts.items()}
    styles = {"closed_form": {"marker": "s", "color": COLORS["closed_form"]},
              "map": {"marker": "P", "color": COLORS["map"]},
              "truth": {"marker": "*", "color": COLORS["truth"]}}
    labels = {"closed_form": f"{ctx.cf_label} (arrow: off the axes)", "map": "MAP",
              "truth": "truth (simulated session)"}
    n = len(names)
    fig, axes = subplots(n, n, figsize=(2.3 * n + 0.8, 2.3 * n + 0.6), squeeze=False)
    lims = [_limits(ds[:, k], [pts.get("truth", [None] * n)[k]]) for k in range(n)]
    for i in range(n):
        for j in range(n):
            ax = axes[i, j]
            if j > i:
                ax.set_axis_off()
                continue
            if i == j:
                ax.hist(ds[:, i], bins=40, color=COLORS["mean"], alpha=0.6, range=lims[i])
                ax.set_yticks([])
                for k, p in pts.items():
                    if lims[i][0] <= p[i] <= lims[i][1]:
                        ax.axvline(p[i], color=styles[k]["color"], lw=1.2)
            else:
                ax.plot(ds[:, j], ds[:, i], ".", ms=1.5, alpha=0.3, color=COLORS["mean"],
                        rasterized=True)
                for k, p in pts.items():
                    _mark(ax, p[j], p[i], (lims[j], lims[i]), styles[k], labels[k])
                ax.set_ylim(lims[i])
            ax.set_xlim(lims[j])
            ax.ticklabel_format(useOffset=False)
            ax.locator_params(axis="x", nbins=4)
            if i != j:
                ax.locator_params(axis="y", nbins=5)
            ax.tick_params(labelsize=7)
            if i == n - 1:
                ax.set_xlabel(scales[j][1])
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(scales[i][1])
            elif i != j:
                ax.set_yticklabels([])
    handles = [Line2D([], [], ls="", marker=".", ms=8, color=COLORS["mean"])]
    text = [source]
    for k in pts:
        handles.append(Line2D([], [], ls="", marker=styles[k]["marker"], ms=8,
                                  color=styles[k]["color"], mec="k", mew=0.6))
        text.append(labels[k])
    fig.legend(handles, text, loc="upper right", bbox_to_anchor=(0.98, 0.98), frameon=False)
    fig.suptitle("Pair plot of the mechanical parameters", x=0.02, ha="left")
    return png(fig)


def forest_points(ctx) -> dict[str, dict]:
    """What the forest plot shows of each positive (log-transformed) parameter, in %
    relative to the reference (posterior mean, else MAP): ``map`` and its ± 2 sd
    interval ``map_2sd``; ``hdi`` (the posterior 94 % HDI), ``closed_form`` and ``truth``
    only where there is one (None otherwise: the closed form has no Tc, as the tables
    say)."""
    ref, params = ctx.best, ctx.summary["parameters"]
    out = {}
    for n in (n for n in ctx.names if n in ctx.log_names):
        p = params[n]

        def rel(v, n=n):
            return None if v is None else 100.0 * (v / ref[n] - 1.0)

        m, s = p["map"], p["map_sd"]
        out[n] = {"map": rel(m), "map_2sd": (rel(m - 2 * s), rel(m + 2 * s)),
                  "hdi": (rel(p["hdi_3%"]), rel(p["hdi_97%"])) if "hdi_3%" in p else None,
                  "closed_form": rel(p.get("closed_form")),
                  "truth": rel(ctx.truth.get(n)) if ctx.truth else None}
    return out


def _percent(v, _pos) -> str:
    """A tick label of the forest plot's axis (a module-level function, so that the
    figure pickles for the drawing processes)."""
    return f"{v:+g} %" if v else "0"


@styled
def forest_figure(ctx, rows) -> Drawing:
    """PNG: every parameter relative to the reference (posterior mean, else MAP), in %:
    closed form, MAP ± 2 sd, posterior 94 % HDI and truth (:func:`forest_points`).  The
    axis is symmetric-log, linear within the widest ± 2 sd interval, so narrow intervals
    and far closed-form values are both visible.  Only the positive (log-transformed)
    parameters: a nuisance that may be zero (a dead time, a voltage drop) has no
    relative scale and is in the tables."""
    ref = ctx.best
    points = forest_points(ctx)
    names = list(points)
    fig, ax = subplots(figsize=(8.5, 0.75 * len(names) + 1.6))
    lin = 0.0
    labelled = set()

    def label(what, text):
        if what in labelled:
            return None
        labelled.add(what)
        return text

    for k, n in enumerate(names):
        y, pt = len(names) - 1 - k, points[n]
        m, (lo, hi) = pt["map"], pt["map_2sd"]
        lin = max(lin, abs(lo), abs(hi))
        ax.errorbar(m, y + 0.15, xerr=[[m - lo], [hi - m]], fmt="P", color=COLORS["map"],
                    ms=6, capsize=3, label=label("map", "MAP ± 2 sd (Laplace)"))
        if pt["hdi"] is not None:
            ax.plot(pt["hdi"], [y - 0.05] * 2, "-", color=COLORS["mean"], lw=4,
                    label=label("hdi", "posterior 94 % HDI"))
            ax.plot(0.0, y - 0.05, "o", color="white", mec=COLORS["mean"], ms=5)
        if pt["closed_form"] is not None:
            ax.plot(pt["closed_form"], y - 0.22, "s", color=COLORS["closed_form"], ms=6,
                    mec="k", mew=0.5, label=label("closed_form", ctx.cf_label))
        if pt["truth"] is not None:
            ax.plot(pt["truth"], y, "*", color=COLORS["truth"], ms=10, mec="k", mew=0.5,
                    label=label("truth", "truth"))
    lin = max(lin, 1e-3) * 1.2
    ax.set_xscale("symlog", linthresh=lin)
    lo, hi = ax.get_xlim()
    ticks = [0.0] + [sg * float(f"{lin:.1g}") for sg in (-1, 1)]
    ticks += [sg * 10.0**e for e in range(-3, 4) for sg in (-1, 1) if 10.0**e > 3 * lin]
    ax.set_xticks(sorted(t for t in ticks if lo <= t <= hi))
    ax.xaxis.set_major_formatter(_percent)
    ax.xaxis.set_minor_locator(NullLocator())
    ax.axvline(0.0, color="k", lw=0.7)
    ax.set_yticks(range(len(names)))
    labels = []
    for n in reversed(names):  # each value rounded to its uncertainty, as in the tables
        f = row_format(ref[n], ctx.sd(n))
        labels.append(f"{n} ({f.suffix}{display_unit(ctx.unit(n))})\n{f.value(ref[n])}")
    ax.set_yticklabels(labels)
    ax.set_ylim(-0.7, len(names) - 0.3)
    ax.set_xlabel(f"difference from the {ctx.best_label} (%, linear within ±{lin:.2g} %, "
                  "logarithmic beyond)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=4, frameon=False)
    ax.set_title(f"Every parameter relative to its {ctx.best_label} (value under each name)")
    return png(fig)
