"""Where a session's published or measured numbers disagree with each other.

Checks that need no fitting: the closed-form gain (10) against the slope of the
steady speed–voltage points, the zero-voltage offset that viscous friction cannot
produce, the load sensitivity dω/dTL (from the steady state with load) against the
closed form's ``Ra/(B·Ra + K²)``, and step readings against steady points at the same
voltage.  Each finding is a sentence with the numbers.
"""

from __future__ import annotations

import numpy as np

from ..io.session import Session
from .closed_form import ClosedForm

__all__ = ["consistency_checks"]


def _steady_points(session: Session):
    v, tl, w, src = [], [], [], []
    for tab in session.steady_tables:
        v.extend(tab.voltage)
        tl.extend(tab.load_torque)
        w.extend(tab.speed)
        src.extend([tab.name] * tab.voltage.size)
    for op in session.operating_points:
        v.append(op.voltage), tl.append(op.load_torque), w.append(op.speed), src.append(op.name)
    return np.array(v, float), np.array(tl, float), np.array(w, float), src


def consistency_checks(session: Session, cf: ClosedForm) -> dict:
    """Numbers and findings (JSON-ready) on how the session's data agree."""
    v, tl, w, _ = _steady_points(session)
    out: dict = {"closed_form_gain": cf.G, "findings": []}
    F = out["findings"]
    noload = tl == 0.0
    if np.unique(v[noload]).size >= 2:
        tables = [t for t in session.steady_tables if np.all(t.load_torque == 0)
                  and np.unique(t.voltage).size >= 2]
        sel = noload
        label = "the no-load steady points"
        if tables:
            tab = max(tables, key=lambda t: t.voltage.size)
            sel_v, sel_w = tab.voltage, tab.speed
            label = f"the rows of table {tab.name!r}"
        else:
            sel_v, sel_w = v[sel], w[sel]
        slope, offset = np.polyfit(sel_v, sel_w, 1)
        out.update(steady_slope=float(slope), steady_offset=float(offset))
        F.append(f"The closed-form parameters give a gain G = {cf.G:.3g} rad/s per V (10); "
                 f"{label} rise at {slope:.3g} rad/s per V ({100 * (cf.G / slope - 1):+.0f} %).")
        if offset < 0 and abs(offset) > 0.05 * np.abs(sel_w).max():
            F.append(f"{label[0].upper()}{label[1:]} lie on ω ≈ {slope:.4g}·Va "
                     f"{offset:+.3g} rad/s: an offset at zero voltage that purely viscous "
                     "friction cannot produce (a Coulomb friction torque or a brush voltage "
                     "drop can).")
        pred = cf.G * sel_v
        rel = (pred - sel_w) / sel_w
        out["closed_form_steady_error"] = [float(x) for x in rel]
        F.append(f"The closed-form parameters put the speeds of {label} {100 * rel.min():+.1f} % "
                 f"to {100 * rel.max():+.1f} % from the measured ones.")
    for volt in np.unique(v):
        at = (v == volt) & (np.abs(v - volt) < 1e-9)
        if np.unique(tl[at]).size >= 2:
            s_meas = -np.polyfit(tl[at], w[at], 1)[0]
            s_cf = cf.Ra / (cf.B * cf.Ra + cf.K**2)
            out.update(load_sensitivity_measured=float(s_meas),
                       load_sensitivity_closed_form=float(s_cf))
            F.append(f"At {volt:.4g} V the speed falls {s_meas * 0.01:.3g} rad/s per 0.01 N·m of "
                     f"load; the closed form predicts {s_cf * 0.01:.3g} rad/s (Ra/(B·Ra + K²)): "
                     f"the measured torque sensitivity is {s_meas / s_cf:.2g} times the "
                     f"predicted one.")
    for sr in session.step_readings:
        at = noload & (np.abs(v - sr.voltage) < 1e-9)
        if at.any():
            others = w[at]
            F.append(f"Step reading {sr.name!r} settles at {sr.final_speed:.4g} rad/s at "
                     f"{sr.voltage:.4g} V; steady points at that voltage read "
                     f"{', '.join(f'{x:.4g}' for x in others)} rad/s "
                     f"({100 * (others.mean() / sr.final_speed - 1):+.1f} %).")
        F.append(f"With the closed-form parameters the steady speed at {sr.voltage:.4g} V is "
                 f"{cf.G * sr.voltage:.4g} rad/s, not the {sr.final_speed:.4g} rad/s read from "
                 f"the step ({100 * (cf.G * sr.voltage / sr.final_speed - 1):+.1f} %).")
    return out
