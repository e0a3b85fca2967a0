"""Per-trace figures: measured speed and current against each parameter set's
simulation and the posterior predictive band, with residuals underneath."""

from __future__ import annotations

import numpy as np

from ._plot import COLORS, LABELS, png, styled, subplots
from ._render import Drawing
from ._view import TracePrediction

__all__ = ["trace_figure"]

_YLABEL = {"speed": "speed ω (rad/s)", "current": "current ia (A)", "position": "angle θ (rad)"}
_RLABEL = {"speed": "residual (rad/s)", "current": "residual (A)", "position": "residual (rad)"}


def _time_axis(t):
    """Times to plot and their label: from the first sample when the clock's origin is
    far before the trace (a free-running counter)."""
    t = np.asarray(t)
    span = t[-1] - t[0]
    since = ""
    if abs(t[0]) > 10 * span:
        t, since = t - t[0], " since the first sample"
    return (t * 1e3, f"time{since} (ms)") if span < 0.5 else (t, f"time{since} (s)")


def _channel(ax, rax, tp: TracePrediction, c: str, t, cf_label: str):
    y = tp.measured(c)
    s = tp.sims
    ax.plot(t, y, ".", ms=1.5, color=COLORS["measured"], alpha=0.5, label="measured",
            rasterized=True)
    if tp.band is not None:
        ax.fill_between(t, *tp.band[c], color=COLORS["mean"], alpha=0.25, lw=0,
                        label="posterior predictive 94 % band")
    ax.plot(t, s["closed_form"][c], "--", color=COLORS["closed_form"], lw=1.4,
            label=cf_label)
    ax.plot(t, s["map"][c], "-", color=COLORS["map"], lw=1.0, label=LABELS["map"])
    ax.set_ylabel(_YLABEL[c])
    ref = s["map"][c]
    if tp.band is not None:
        rax.fill_between(t, tp.band[c][0] - ref, tp.band[c][1] - ref, color=COLORS["mean"],
                         alpha=0.25, lw=0, label="94 % band − MAP")
    rax.plot(t, y - ref, ".", ms=1.2, color=COLORS["map"], alpha=0.5, rasterized=True,
             label="measured − MAP")
    rax.plot(t, s["closed_form"][c] - ref, "--", color=COLORS["closed_form"], lw=1.4,
             label=f"{cf_label} − MAP")
    rax.axhline(0.0, color="k", lw=0.6)
    rax.set_ylabel(_RLABEL[c])
    rms = tp.rms
    txt = (f"RMS: {cf_label} {rms['closed_form'][c]:.3g}, MAP {rms['map'][c]:.3g}"
           + (f", 94 % band covers {100 * tp.coverage[c]:.0f} %" if tp.coverage else ""))
    rax.set_title(txt, loc="right", fontsize=7.5, pad=2)


@styled
def trace_figure(tp: TracePrediction, cf_label: str = LABELS["closed_form"]) -> Drawing:
    """PNG: speed (and current) with the closed form (or the seed, named by ``cf_label``),
    MAP and predictive band, residuals."""
    chans = tp.channels
    ratios = [3, 1.4] * len(chans)
    fig, axes = subplots(2 * len(chans), 1, sharex=True, figsize=(8.5, 2.6 * len(chans) + 1.4),
                             gridspec_kw={"height_ratios": ratios})
    t, tlabel = _time_axis(tp.trace.time)
    for k, c in enumerate(chans):
        _channel(axes[2 * k], axes[2 * k + 1], tp, c, t, cf_label)
    axes[-1].set_xlabel(tlabel)
    held = " — held out of the fit" if tp.held_out else ""
    kind = tp.trace.kind.replace("_", " ")  # the session's kind name, in words
    fig.suptitle(f"Trace {tp.trace.name!r} ({kind}){held}", y=0.995)
    h1, l1 = axes[0].get_legend_handles_labels()
    h2, l2 = axes[1].get_legend_handles_labels()
    fig.legend(h1 + h2, l1 + l2, loc="upper center", ncol=3, bbox_to_anchor=(0.5, 0.975),
               frameon=False, markerscale=5)
    return png(fig, rect=(0, 0, 1, 0.93))
