"""Published simulation numbers of the reference paper, for the ``paper`` session only.

The paper's simulated speeds are not data (they are the paper's model output, so the
session leaves them out and the fit never sees them); the report shows them beside
the fitted lines so that their disagreement with Table I is visible.  Source:
Tun & Naing, *PMDC Motor Modeling and Parameter Identification for Control Purpose*,
Table II and Figure 6.
"""

from __future__ import annotations

import numpy as np

from ..paper.closed_form import gain

__all__ = ["PAPER_SESSION", "TABLE2_SIMULATED", "FIGURE6_SIMULATED", "published_findings"]

PAPER_SESSION = "paper"
RPM = 2.0 * np.pi / 60.0
# Table II, "simulated" column: armature voltage (V) -> simulated steady speed (rad/s).
TABLE2_SIMULATED = {"voltage": (6.49, 7.78, 9.08, 10.38, 11.67, 12.97),
                    "speed": (86.0, 103.0, 120.0, 137.5, 154.58, 172.5)}
# Figure 6 (simulation, load change at 12.97 V): 1610 / 1200 / 780 rpm at TL = 0 / 0.01 /
# 0.02 N·m, read off the figure.
FIGURE6_SIMULATED = {"voltage": 12.97, "load_torque": (0.0, 0.01, 0.02),
                     "speed": tuple(r * RPM for r in (1610.0, 1200.0, 780.0))}


def published_findings(ctx) -> list[str] | None:
    """Sentences with numbers on the paper's Table I against its own speeds, or None
    for any session but the paper's."""
    if ctx.summary["session"]["name"] != PAPER_SESSION:
        return None
    cf = ctx.cf
    g_table1 = gain(cf.Ra, cf.K, cf.B)
    v, w = np.asarray(TABLE2_SIMULATED["voltage"]), np.asarray(TABLE2_SIMULATED["speed"])
    sim_slope, sim_off = np.polyfit(v, w, 1)
    cons = ctx.summary.get("consistency", {})
    meas_slope = cons.get("steady_slope")
    best, label = ctx.best, ctx.best_label
    g_best = gain(best["Ra"], best["K"], best["B"])
    out = [f"Table I does not reproduce the published speeds: its parameters give a gain "
           f"G = K/(B·Ra + K²) = {g_table1:.3g} rad/s per V (equation (10)), "
           f"{g_table1 * 12.97:.4g} rad/s at 12.97 V, while Table II's simulated column "
           f"rises at {sim_slope:.3g} rad/s per V (offset {sim_off:+.2g} rad/s), so it was not "
           f"computed from Table I; Table II's experimental column rises at {meas_slope:.3g} "
           f"rad/s per V."]
    s_meas = cons.get("load_sensitivity_measured")
    s_cf = cons.get("load_sensitivity_closed_form")
    if s_meas and s_cf:
        fw = np.asarray(FIGURE6_SIMULATED["speed"])
        s_fig6 = -np.polyfit(FIGURE6_SIMULATED["load_torque"], fw, 1)[0]
        out.append(f"The load-change speeds of Figure 7 fall {s_meas * 0.01:.3g} rad/s per "
                   f"0.01 N·m; Table I predicts Ra/(B·Ra + K²) × 0.01 N·m = {s_cf * 0.01:.3g} "
                   f"rad/s, so the measured torque sensitivity is {s_meas / s_cf:.2g} times "
                   f"what Table I predicts (the paper's own simulation, Figure 6, falls "
                   f"{s_fig6 * 0.01:.3g} rad/s per 0.01 N·m, {s_fig6 / s_cf:.2g} times).")
    line = (f"Fitted jointly to all of the paper's numbers, the {label} gives "
            f"G = {g_best:.3g} rad/s per V and a torque sensitivity of "
            f"{best['Ra'] / (best['B'] * best['Ra'] + best['K'] ** 2) * 0.01:.3g} rad/s per "
            f"0.01 N·m.")
    if s_meas and meas_slope:
        k_need = cf.Ra * meas_slope / s_meas
        b_need = (k_need / meas_slope - k_need**2) / cf.Ra
        op = next((p for p in ctx.session.operating_points if p.current is not None), None)
        line += (f" Meeting both the measured slope and the measured load sensitivity with "
                 f"the viscous model would need K = Ra·G/S = {k_need:.3g} V·s/rad and "
                 f"B = (K/G − K²)/Ra = {b_need:.3g} N·m·s/rad")
        if op is not None:
            ia = (b_need * op.voltage) / (b_need * cf.Ra + k_need**2)
            line += (f", which contradict the chopper point: equation (20) there gives "
                     f"K = {cf.K:.3g} V·s/rad, and these values would draw {ia:.3g} A at "
                     f"{op.voltage:.4g} V instead of the measured {op.current:.3g} A")
        line += "."
    out.append(line)
    return out
