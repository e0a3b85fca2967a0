"""Trace shapes for identifying a motor by its response to a rich input rather than to
steps: a sweep (a chirp from a fifth to five times the motor's mechanical bandwidth,
about a mean that may leave room for both signs) and a random sequence (two levels
switched at random holds of a fraction of the mechanical time constant, as a
pseudo-random binary sequence).  None of their levels is held long enough to read a
time constant from one response.  Each is written as a schedule of held levels, as a
driver updating its duty at a control rate puts it out.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["EXCITATION_SHAPES", "excitation"]

EXCITATION_SHAPES = ("sweep", "random sequence")
MAX_LEVELS = 400  # breakpoints of a sweep's schedule


def _sweep(rng, top: float, v: float, tau_m: float, duration: float, rate: float):
    f0 = 0.2 / (2 * math.pi * tau_m)
    f1 = min(5.0 / (2 * math.pi * tau_m), rate / 8.0)
    step = max(1.0 / (20.0 * f1), duration / MAX_LEVELS, 2.0 / rate)
    t = np.arange(0.0, duration, step)
    phase = 2 * math.pi * (f0 * t + 0.5 * (f1 - f0) * t**2 / duration)
    amp = abs(top) * float(rng.uniform(0.3, 0.6))
    mean = math.copysign(float(rng.uniform(0.0, 1.0)) * (v - amp), top)
    return t, mean + amp * np.sin(phase)


def _random_sequence(rng, top: float, tau_m: float, duration: float, rate: float):
    low = top * float(rng.uniform(-1.0, 0.5))
    holds = np.maximum(rng.exponential(float(rng.uniform(0.2, 0.6)) * tau_m, 400),
                       3.0 / rate)
    starts = np.concatenate([[0.0], np.cumsum(holds)])
    t = starts[starts < duration]
    return t, np.where(np.arange(t.size) % 2 == 0, top, low)


def excitation(rng, shape: str, top: float, v: float, tau_m: float, duration: float,
               rate: float) -> list[list[float]]:
    """The voltage schedule ``[[time, volts], ...]`` of a trace of ``shape`` (one of
    :data:`EXCITATION_SHAPES`) whose largest level is about ``top`` (the motor's
    nominal voltage ``v``, its mechanical time constant ``tau_m``, the record's
    ``duration`` and sample ``rate``)."""
    if shape == "sweep":
        t, volts = _sweep(rng, top, v, tau_m, duration, rate)
    else:
        t, volts = _random_sequence(rng, top, tau_m, duration, rate)
    return [[float(a), float(b)] for a, b in zip(t, volts, strict=True)]
