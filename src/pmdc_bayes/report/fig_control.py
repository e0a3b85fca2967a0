"""Controller-design figure: the speed's step response and the Bode plot of ω/Va at
the estimate, with the 94 % band over posterior draws, the closed form's and (for a
simulated session) the truth's."""

from __future__ import annotations

import numpy as np

from ..physics.response import frequency_response, poles, step_response
from ._plot import COLORS, LABELS, png, styled, subplots
from ._render import Drawing

__all__ = ["response_curves", "response_figure", "N_RESPONSE_DRAWS"]

N_RESPONSE_DRAWS = 400  # posterior draws the bands are computed from
_MOTOR = ("Ra", "La", "K", "B", "J")


def _curves(values: dict, t, w) -> dict:
    args = [np.asarray(values[n], dtype=float) for n in _MOTOR]
    h = frequency_response(*args, w)
    return {"step": step_response(*args, t), "gain_db": 20 * np.log10(np.abs(h)),
            "phase_deg": np.degrees(np.unwrap(np.angle(h), axis=-1))}


def response_curves(ctx) -> dict:
    """Times (s), frequencies (rad/s) and, per parameter set (``"estimate"``,
    ``"closed_form"``, ``"truth"``, when known), the step response (rad/s per V), gain
    (dB) and phase (deg); ``"band"`` holds the 3 % and 97 % points of each over
    posterior draws (absent without a posterior)."""
    best = ctx.best
    slow, fast = (abs(p) for p in poles(*(best[n] for n in _MOTOR)))
    t = np.linspace(0.0, 5.0 / slow, 400)
    w = np.logspace(np.log10(slow) - 1.5, np.log10(fast) + 1.5, 300)
    out = {"time": t, "frequency": w, "estimate": _curves(best, t, w)}
    if "closed_form" in ctx.values:
        out["closed_form"] = _curves(ctx.values["closed_form"], t, w)
    if ctx.truth and all(ctx.truth.get(n) is not None for n in _MOTOR):
        out["truth"] = _curves(ctx.truth, t, w)
    if ctx.draws is not None:
        pick = np.linspace(0, len(ctx.draws) - 1, min(N_RESPONSE_DRAWS, len(ctx.draws)))
        sub = ctx.draws[pick.astype(int)]
        many = _curves({n: sub[:, ctx.names.index(n)] for n in _MOTOR}, t, w)
        out["band"] = {k: np.percentile(v, [3, 97], axis=0) for k, v in many.items()}
    return out


@styled
def response_figure(ctx) -> Drawing:
    c = response_curves(ctx)
    fig, (ax_s, ax_g, ax_p) = subplots(1, 3, figsize=(11.0, 3.2))
    x = {"step": (ax_s, c["time"]), "gain_db": (ax_g, c["frequency"]),
         "phase_deg": (ax_p, c["frequency"])}
    if "band" in c:
        for key, (ax, xs) in x.items():
            lo, hi = c["band"][key]
            ax.fill_between(xs, lo, hi, color=COLORS["mean"], alpha=0.3, lw=0,
                            label="posterior 94 % band")
    styles = {"estimate": (COLORS["mean" if ctx.has_posterior else "map"], "-",
                           ctx.best_label),
              "closed_form": (COLORS["closed_form"], "--", ctx.cf_label),
              "truth": (COLORS["truth"], ":", LABELS["truth"])}
    for name, (color, ls, label) in styles.items():
        if name in c:
            for key, (ax, xs) in x.items():
                ax.plot(xs, c[name][key], color=color, ls=ls, lw=1.2, label=label)
    ax_s.set(xlabel="time after a 1 V step (s)", ylabel="speed (rad/s per V)",
             title="Step response")
    ax_g.set(xscale="log", xlabel="frequency (rad/s)", ylabel="|ω/Va| (dB, rad/s per V)",
             title="Bode gain")
    ax_p.set(xscale="log", xlabel="frequency (rad/s)", ylabel="phase (deg)",
             title="Bode phase")
    ax_s.legend(loc="lower right")
    return png(fig)
