"""Steady-state figure: speed against voltage (no load) and speed against load torque,
with the closed-form, MAP and posterior lines, the measured points and, for the
paper's session, the paper's own simulated speeds."""

from __future__ import annotations

import numpy as np

from ..physics.motor import steady_with_drop, time_constant
from ._plot import COLORS, png, styled, subplots
from ._render import Drawing
from ._view import BAND
from .published import FIGURE6_SIMULATED, PAPER_SESSION, TABLE2_SIMULATED

__all__ = ["steady_points", "steady_figure"]


def _settled_segments(session, tau: float):
    """Settled speeds at the end of each constant-input stretch of every trace that
    lasts at least five time constants: (V, TL, ω) arrays."""
    out = []
    for tr in session.traces:
        edges = np.unique(np.concatenate([tr.voltage.times, tr.load_torque.times,
                                          [tr.time[0]], [tr.time[-1]]]))
        edges = edges[(edges >= tr.time[0]) & (edges <= tr.time[-1])]
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            if b - a < 5 * tau:
                continue
            sel = (tr.time >= b - 0.1 * (b - a)) & (tr.time < b)
            if sel.sum() >= 3:
                mid = np.array([0.5 * (a + b)])
                out.append((float(tr.voltage.at(mid)[0]), float(tr.load_torque.at(mid)[0]),
                            float(tr.speed[sel].mean())))
    return np.array(out).reshape(-1, 3)


def steady_points(ctx) -> dict:
    """Measured steady points, each an ``(n, 3)`` array of (V, TL, ω), by source."""
    s = ctx.session
    pts = {}
    rows = [(v, tl, w) for tab in s.steady_tables
            for v, tl, w in zip(tab.voltage, tab.load_torque, tab.speed, strict=True)]
    rows += [(op.voltage, op.load_torque, op.speed) for op in s.operating_points]
    if rows:
        pts["steady tables and operating points"] = np.array(rows, dtype=float)
    if s.step_readings:
        pts["step readings (final speed)"] = np.array(
            [(r.voltage, 0.0, r.final_speed) for r in s.step_readings])
    b = ctx.best
    seg = _settled_segments(s, time_constant(b["Ra"], b["K"], b["B"], b["J"]))
    if seg.size:
        pts["settled stretches of the traces"] = seg
    return pts


def _predict(ctx, vals, v, tl, *, viscous=False):
    """Steady speed (rad/s) for parameter values (dict of SI scalars or arrays of draws),
    shape ``(draws, points)``.

    Notes
    -----
    :func:`pmdc_bayes.physics.motor.steady_with_drop` (equations (15)–(16), the drop
    opposing the current, with a Coulomb
    torque ``Tc·sign`` and the rotor stuck while ``|K·V/Ra − TL| ≤ Tc``) in NumPy,
    evaluated for many draws at once without JAX dispatch.
    """
    v, tl = np.broadcast_arrays(np.atleast_1d(np.asarray(v, float)),
                                np.atleast_1d(np.asarray(tl, float)))
    p = {n: np.asarray(vals.get(n, 0.0), dtype=float)[..., None]
         for n in ("Ra", "K", "B", "Tc", "Vdrop")}
    tc = None if viscous or not ctx.coulomb else p["Tc"]
    _, w = steady_with_drop(p["Ra"], p["K"], p["B"], v, tl, tc, p["Vdrop"])
    return np.atleast_2d(w)


def _lines(ax, ctx, x, v, tl):
    """Closed form, MAP and posterior band of the steady speed along ``x``."""
    cf = _predict(ctx, ctx.values["closed_form"], v, tl, viscous=True)[0]
    ax.plot(x, cf, "--", color=COLORS["closed_form"], lw=1.5, label=ctx.cf_label)
    ax.plot(x, _predict(ctx, ctx.values["map"], v, tl)[0], color=COLORS["map"], lw=1.2,
            label="MAP")
    if ctx.draws is not None:
        d = {n: ctx.draws[::max(1, ctx.draws.shape[0] // 400), k] for k, n in enumerate(ctx.names)}
        w = _predict(ctx, d, v, tl)
        ax.fill_between(x, *np.quantile(w, BAND, axis=0), color=COLORS["mean"], alpha=0.3, lw=0,
                        label="posterior 94 % band (parameters)")


def _residuals(rax, ctx, x, v, tl, w, marker, color):
    for key, style in (("closed_form", "s"), ("map", "P")):
        pred = _predict(ctx, ctx.values[key], v, tl, viscous=key == "closed_form")[0]
        rax.plot(x, w - pred, style, color=COLORS[key], ms=5, mec="k", mew=0.4, ls="")
    rax.axhline(0.0, color="k", lw=0.6)


_MARKERS = {"steady tables and operating points": "o", "step readings (final speed)": "D",
            "settled stretches of the traces": "^"}


@styled
def steady_figure(ctx) -> Drawing:
    """PNG: 2×2 panels, speed–voltage and speed–torque lines (top) and residuals of the
    measured points against the closed form and the MAP (bottom)."""
    pts = steady_points(ctx)
    allp = np.concatenate(list(pts.values())) if pts else np.zeros((0, 3))
    loaded = allp[allp[:, 1] != 0]
    v_load = float(loaded[0, 0]) if loaded.size else float(
        ctx.summary.get("derived", {}).get("voltage", allp[:, 0].max() if allp.size else 12.0))
    fig, axes = subplots(2, 2, figsize=(10, 6.6), sharex="col",
                             gridspec_kw={"height_ratios": [3, 1.3]})
    vmax = 1.1 * max(allp[:, 0].max() if allp.size else 12.0, v_load)
    v = np.linspace(0.0, vmax, 200)
    _lines(axes[0, 0], ctx, v, v, 0.0)
    tmax = max(0.03, 1.25 * (loaded[:, 1].max() if loaded.size else 0.0))
    t = np.linspace(0.0, tmax, 200)
    _lines(axes[0, 1], ctx, t, v_load, t)
    for label, p in pts.items():
        m = _MARKERS[label]
        nl = p[p[:, 1] == 0]
        at_v = p[np.isclose(p[:, 0], v_load)]
        for ax, rax, sel, x in ((axes[0, 0], axes[1, 0], nl, nl[:, 0]),
                                (axes[0, 1], axes[1, 1], at_v, at_v[:, 1])):
            if sel.size:
                ax.plot(x, sel[:, 2], m, color=COLORS["measured"], ms=6, ls="", mfc="white",
                        mew=1.3, label=f"measured: {label}")
                _residuals(rax, ctx, x, sel[:, 0], sel[:, 1], sel[:, 2], m, COLORS["measured"])
    if ctx.summary["session"]["name"] == PAPER_SESSION:
        axes[0, 0].plot(TABLE2_SIMULATED["voltage"], TABLE2_SIMULATED["speed"], "x",
                        color=COLORS["published"], ms=7, mew=1.5,
                        label="paper's Table II 'simulated' (published, not data)")
        if np.isclose(FIGURE6_SIMULATED["voltage"], v_load):
            axes[0, 1].plot(FIGURE6_SIMULATED["load_torque"], FIGURE6_SIMULATED["speed"], "x",
                            color=COLORS["published"], ms=7, mew=1.5,
                            label="paper's Figure 6 simulation (published, not data)")
    axes[0, 0].set_title("No-load steady speed against armature voltage")
    axes[0, 1].set_title(f"Steady speed against load torque at {v_load:.4g} V")
    axes[0, 0].set_ylabel("steady speed ω (rad/s)")
    axes[1, 0].set_ylabel("measured − model (rad/s)")
    axes[1, 0].set_xlabel("armature voltage Va (V)")
    axes[1, 1].set_xlabel("load torque TL (N·m)")
    for ax in axes[0]:
        ax.legend(loc="upper left" if ax is axes[0, 0] else "upper right", fontsize=7)
    axes[1, 1].plot([], [], "s", color=COLORS["closed_form"], mec="k", mew=0.4,
                    label=f"measured − {ctx.cf_label}")
    axes[1, 1].plot([], [], "P", color=COLORS["map"], mec="k", mew=0.4, label="measured − MAP")
    axes[1, 1].legend(loc="lower left", fontsize=7, ncol=1)
    return png(fig)
