"""A plan's coast-down traces: the rotor running down with the armature open.

On an ideal plan the speed is the exact run-down of the package's equation
(:func:`~pmdc_bayes.physics.motor.coast_down`).  On a rig it is integrated by LSODA
(``J·dω/dt = −(B + b)·ω − (Tc + c)·sign ω``, with ``(c, b)`` the rig's unknown load on
the trace), the stop located as an event and held, independently of the package's
model, and read through the rig's speed sensor (its lag, settled at the first sample
as after a steady run, then its gain and offset).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from ..physics import motor

__all__ = ["ideal_coast_down", "rig_coast_down"]

_RTOL = 1e-10


def ideal_coast_down(truth: dict, spec) -> dict[str, np.ndarray]:
    """Noise-free ``time``, ``speed`` (SI) of a coast-down of the ideal motor; a sample
    at ``t`` reads the speed at ``max(t − delay, 0)``."""
    t = spec.time
    seen = np.maximum(t - spec.delay, 0.0)
    w = motor.coast_down(truth["B"], truth["J"], spec.initial[1], seen, truth["Tc"])
    return {"time": t, "speed": np.asarray(w, dtype=float), "current": None}


def _run_down(b: float, j: float, tc: float, w0: float, lag: float,
              t: np.ndarray) -> np.ndarray:
    """What a sensor of first-order ``lag`` (s; 0: none) reads of ω at the times ``t``
    (≥ 0, increasing) of a run-down from ``w0``, the sensor settled at ``w0``; the rotor
    stops and stays where Coulomb friction holds it (located as an event), after which
    the reading decays as ``e^(−t/lag)``."""
    if w0 == 0.0:
        return np.zeros_like(t)

    def rhs(_, x):
        dw = (-b * x[0] - tc * np.sign(x[0])) / j
        return [dw, (x[0] - x[1]) / lag if lag > 0 else dw]

    def stop(_, x):
        return x[0]

    stop.terminal, stop.direction = True, -np.sign(w0)
    sol = solve_ivp(rhs, (0.0, float(t[-1])), [w0, w0], method="LSODA", rtol=_RTOL,
                    atol=1e-9 * abs(w0), events=stop, dense_output=True)
    if not sol.success:
        raise RuntimeError(f"coast-down integration failed: {sol.message}")
    if sol.status != 1:  # still turning at the end
        return sol.sol(t)[1]
    t_stop = float(sol.t_events[0][0])
    y_stop = float(sol.y_events[0][0][1]) if lag > 0 else 0.0
    after = y_stop * np.exp(-(t - t_stop) / lag) if lag > 0 else np.zeros_like(t)
    return np.where(t < t_stop, sol.sol(np.minimum(t, t_stop))[1], after)


def rig_coast_down(truth: dict, rig, spec) -> dict[str, np.ndarray]:
    """Noise-free ``time``, ``speed`` (SI) of a coast-down on the rig, as its speed
    sensor reads it (the plan's delay too)."""
    t = spec.time
    extra = {n: (c, v) for n, c, v in rig.unknown_load}.get(spec.name, (0.0, 0.0))
    speed = _run_down(truth["B"] + extra[1], truth["J"], truth["Tc"] + extra[0],
                      spec.initial[1], rig.speed_lag, np.maximum(t - spec.delay, 0.0))
    return {"time": t, "speed": rig.speed_gain * speed + rig.speed_offset, "current": None}
