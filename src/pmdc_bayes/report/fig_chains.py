"""The sampler's chains: every walker against step with the marginal density, and rank
plots of the walkers pooled into sets, drawn directly (one artist per panel and set)."""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection

from ._plot import COLORS, png, scale_of, styled, subplots
from ._render import Drawing

__all__ = ["chains_figure", "ranks_figure", "pooled_ranks"]

_MAX_STEPS = 500  # steps per walker drawn (thinned evenly)
_BINS = 20  # rank bins
_SET_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def _draws(ctx, name: str) -> np.ndarray:
    """``(walkers, steps)`` draws of ``name`` (SI), thinned to at most
    :data:`_MAX_STEPS` steps per walker."""
    x = ctx.chains[name]
    return x[:, :: max(1, -(-x.shape[1] // _MAX_STEPS))]


@styled
def chains_figure(ctx) -> Drawing:
    """PNG: per parameter the marginal density of every walker's draws pooled, and each
    walker against step (thinned), in a power-of-ten unit so that the ticks stay short."""
    n = len(ctx.names)
    fig, axes = subplots(n, 2, figsize=(9, 1.6 * n + 0.5), squeeze=False,
                         gridspec_kw={"width_ratios": [1, 1.4]})
    for row, name in zip(axes, ctx.names, strict=True):
        x = _draws(ctx, name)
        f, label = scale_of(name, float(np.mean(x)), ctx.unit(name))
        x = x * f
        dens, edges = np.histogram(x, bins=60, density=True)
        row[0].stairs(dens, edges, color=COLORS["map"], lw=1.0)
        row[0].set_yticks([])
        row[0].set_title(f"{label}: marginal, all walkers", fontsize=9)
        steps = np.arange(x.shape[1])
        lines = np.stack([np.broadcast_to(steps, x.shape), x], axis=-1)
        row[1].add_collection(LineCollection(lines, colors=COLORS["map"], alpha=0.25,
                                             linewidths=0.4))
        row[1].set_xlim(0, max(1, steps[-1]))
        lo, hi = float(x.min()), float(x.max())
        pad = 0.05 * (hi - lo) or 0.05 * abs(hi) or 1.0
        row[1].set_ylim(lo - pad, hi + pad)
        row[1].set_title(f"{label} against step (thinned), one line per walker", fontsize=9)
        for ax in row:
            ax.tick_params(labelsize=7)
            ax.ticklabel_format(axis="both", useOffset=False)
        row[0].locator_params(axis="x", nbins=6)
        row[1].locator_params(axis="y", nbins=4)
    axes[-1][1].set_xlabel("draw index after burn-in (thinned)")
    axes[-1][0].set_xlabel("parameter value (unit in the title)")
    return png(fig)


def pooled_ranks(x: np.ndarray, groups: int, bins: int = _BINS) -> np.ndarray:
    """Rank histograms of ``x`` ``(walkers, steps)`` with the walkers pooled into
    ``groups`` sets of consecutive walkers: ``(groups, bins)``, each bin's count over
    its count were the sets' draws exchangeable (1 = uniform)."""
    g = min(groups, x.shape[0])
    x = x[: (x.shape[0] // g) * g]
    ranks = np.empty(x.size)
    ranks[np.argsort(x, axis=None, kind="stable")] = np.arange(x.size)
    ranks = ranks.reshape(g, -1)
    counts = np.stack([np.histogram(r, bins=bins, range=(0, x.size))[0] for r in ranks])
    return counts / (ranks.shape[1] / bins)


@styled
def ranks_figure(ctx, groups: int = 4) -> Drawing:
    """PNG: rank plots, the walkers pooled into ``groups`` sets; bars near uniform (the
    dashed line) mean the sets sample the same distribution."""
    n = len(ctx.names)
    cols = 3
    rows = -(-n // cols)
    fig, axes = subplots(rows, cols, figsize=(9, 2.2 * rows + 0.5), squeeze=False)
    walkers = ctx.chains[ctx.names[0]].shape[0]
    for ax, name in zip(axes.ravel(), ctx.names, strict=False):
        x = _draws(ctx, name)
        hist = pooled_ranks(x, groups)
        edges = np.linspace(0, x.size, hist.shape[1] + 1)
        for k, h in enumerate(hist):
            ax.stairs(k + 0.5 * h, edges, baseline=k, fill=True, alpha=0.85,
                      color=_SET_COLORS[k % len(_SET_COLORS)])
            ax.axhline(k + 0.5, color="k", ls="--", lw=1.0)
        ax.set_title(f"{name}", fontsize=9)
        ax.set_xlabel("rank of the draw (all draws)", fontsize=8)
        ax.set_ylabel(f"walker set ({walkers // len(hist)} walkers each)", fontsize=8)
        ax.set_yticks(np.arange(len(hist)))
        ax.tick_params(labelsize=7)
    for ax in axes.ravel()[n:]:
        ax.set_axis_off()
    fig.suptitle("Rank plots of the chains", x=0.02, ha="left")
    return png(fig)
