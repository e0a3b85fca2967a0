"""The bench motor's equations (:class:`~.bench.BenchMotor`), integrated by
:func:`scipy.integrate.solve_ivp` (LSODA), independently of :mod:`pmdc_bayes.physics`:
the state ``(ia, ω, ω_sensor, θ_sensor, ia_sensor)`` with the rig's non-idealities
(brush drop, source resistance, a current-limited driver's current loop, a driver that
opens the armature at a zero command (its freewheel voltage a drop there), Coulomb
friction smoothed to a stick-slip blend, extra load (a curved one too: its torque at
the speed, :mod:`pmdc_bayes.physics.load`), sensor lags)."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from ..io.session import Drag
from ..physics.load import curve_arrays, curve_torque

__all__ = ["integrate"]

_RTOL = 1e-8
_LOOP = 1e-3  # time constant of the driver's current loop, in units of La/Ra


def _rhs(m, name: str, va: float, tl: float, w_eps: float, i_eps: float):
    """Right-hand side for state ``(ia, ω, ω_sensor, θ_sensor, ia_sensor)`` of trace
    ``name`` at constant ``va`` and load ``tl``."""
    extra = Drag(*m.extra_load.get(name, ()))
    tc, b = m.Tc + extra.constant, m.B + extra.viscous
    curve = curve_arrays([extra]) if extra.curved else None
    lim, gain = m.current_limit, m.Ra / (m.La * _LOOP)  # near the limit, dia/dt = gain·Δi
    lag, i_lag = m.speed_lag, m.current_lag

    def f(t, x):
        ia, w, ws, _, ias = x
        drop = m.freewheel_voltage if va == 0 and m.freewheel_voltage else m.voltage_drop
        v = va - drop * math.tanh(ia / i_eps) - m.source_resistance * ia
        if lim is not None:  # the driver's current loop: it can only lower |voltage|
            emf = m.Ra * ia + m.K * w
            v = min(max(v, emf + m.La * gain * (-lim - ia)), emf + m.La * gain * (lim - ia))
        dia = (v - m.Ra * ia - m.K * w) / m.La
        drive = m.K * ia - tl
        s = math.tanh(w / w_eps)
        friction = tc * s + min(max(drive, -tc), tc) * (1.0 - s * s)  # slip, or stick
        curved = 0.0 if curve is None else float(curve_torque(w, *(a[0] for a in curve)))
        dw = (drive - b * w - curved - friction) / m.J
        dws = (w - ws) / lag if lag > 0 else dw
        dias = (ia - ias) / i_lag if i_lag > 0 else dia
        return [dia, dw, dws, ws, dias]

    return f


def integrate(m, name: str, t: np.ndarray, segments, x0, w_eps: float,
              i_eps: float, max_step: float) -> np.ndarray:
    """States ``(ia, ω, ω_sensor, θ_sensor, ia_sensor)`` at the increasing times ``t``
    (5 × n) of trace ``name``, from ``x0`` at ``segments[0]``'s start.

    ``segments`` are ``(start, end, va, tl)`` with constant inputs, end to end; each is
    integrated on its own, so the solver never steps across a discontinuity.
    """
    atol = 1e-6 * np.array([i_eps, w_eps, w_eps, w_eps * max_step, i_eps])
    x0, out = np.asarray(x0, dtype=float), np.zeros((5, t.size))
    out[:, t <= segments[0][0]] = x0[:, None]
    for lo, hi, va, tl in segments:
        if hi <= lo:
            continue
        sel = (t > lo) & (t <= hi)
        t_eval = np.append(t[sel], hi) if not sel.any() or t[sel][-1] < hi else t[sel]
        sol = solve_ivp(_rhs(m, name, float(va), float(tl), w_eps, i_eps), (lo, hi), x0,
                        method="LSODA", t_eval=t_eval, rtol=_RTOL, atol=atol,
                        max_step=max_step)
        if not sol.success:
            raise RuntimeError(f"trace {name!r}: integration failed: {sol.message}")
        out[:, sel] = sol.y[:, :int(sel.sum())]
        x0 = sol.y[:, -1]
    return out
