"""A first-order response read from a driven trace whatever its input: a chirp, a sine, a
random sequence, a schedule of many small levels none of which is held long enough to
read a time constant from its own response.

Near its mechanical time constant the motor follows ``τ·dω/dt + ω = G·V + c`` (the
electrical lag is short beside it; ``c`` takes a constant load or Coulomb friction of
one sign).  Integrated from the trace's start, ``ω(t) = ω₀ + (G/τ)·∫V − (1/τ)·∫ω +
(c/τ)·t`` is linear in its four coefficients, and its regressors are integrals, so a
speed's noise enters them averaged, not differenced: least squares over the samples
gives τ and G (the integral form of the equation-error method).  A seed, not an
estimate: the fit starts from it and its priors are wide.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid

__all__ = ["integral_fit", "first_order"]

MIN_LEVELS = 2  # distinct input values a trace must hold to read τ from their mixture
MIN_SAMPLES = 20


def _input_integral(schedule, t: np.ndarray) -> np.ndarray:
    """``∫ V`` from ``t[0]`` to each of ``t``, exact for the held schedule."""
    bt = np.asarray(schedule.times, float)
    v = np.asarray(schedule.values, float)
    at_breaks = np.concatenate([[0.0], np.cumsum(v[:-1] * np.diff(bt))])
    idx = np.clip(np.searchsorted(bt, t, side="right") - 1, 0, v.size - 1)
    whole = at_breaks[idx] + v[idx] * (t - bt[idx])
    return whole - whole[0]


def integral_fit(time: np.ndarray, speed: np.ndarray, voltage) -> tuple[float, float] | None:
    """``(τ, G)`` of the integral form (module docstring) fitted to a speed logged at
    ``time`` under the schedule ``voltage``; None when the fit gives no decay (τ not
    positive, or outside two samples to ten times the record) or no motor's gain (a
    speed that does not follow its voltage's sign)."""
    ok = np.isfinite(speed)
    t, w = np.asarray(time, float)[ok], np.asarray(speed, float)[ok]
    if t.size < MIN_SAMPLES:
        return None
    int_w = cumulative_trapezoid(w, t, initial=0.0)
    basis = np.column_stack([np.ones_like(t), _input_integral(voltage, t), int_w, t - t[0]])
    scale = np.max(np.abs(basis), axis=0)
    scale[scale == 0.0] = 1.0
    coef, *_ = np.linalg.lstsq(basis / scale, w, rcond=None)
    coef = coef / scale
    if not (np.all(np.isfinite(coef)) and coef[2] < 0.0):
        return None
    tau, gain = -1.0 / coef[2], -coef[1] / coef[2]
    span = t[-1] - t[0]
    if not (2.0 * float(np.median(np.diff(t))) < tau < 10.0 * span) or not gain > 0.0:
        return None
    return float(tau), float(gain)


def _readable(tr) -> bool:
    """A driven trace with a logged speed, a constant load and an input holding at least
    :data:`MIN_LEVELS` distinct values over its record."""
    if tr.kind == "coast-down" or not tr.speed_logged:
        return False
    seen = tr.voltage.at(tr.time)
    return (np.unique(seen).size >= MIN_LEVELS
            and np.unique(tr.load_torque.at(tr.time)).size == 1)


def first_order(session) -> tuple[float, float, str, object] | None:
    """``(G, τ, where, trace)`` from the driven trace with the most samples that
    :func:`integral_fit` reads, G in rad/s per V; None without one."""
    for tr in sorted(filter(_readable, session.traces), key=lambda tr: -tr.n):
        got = integral_fit(tr.time, tr.speed, tr.voltage)
        if got is not None:
            tau, gain = got
            return (gain, tau, f"a first-order model fitted to trace {tr.name!r} in "
                    "integral form (no response to its input settles before the input next "
                    "changes)", tr)
    return None
