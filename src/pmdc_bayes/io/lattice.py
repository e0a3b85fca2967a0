"""Readings on a quantiser's lattice: an encoder's counts, a speed a logger rounds to
its resolution, a current an ADC rounds to its step.

A quantised channel's errors are handled by its quantisation (the inference's noise
bookkeeping, :mod:`pmdc_bayes.inference.model.noise`); an analogue channel's are Gaussian,
white or coloured (:mod:`pmdc_bayes.inference.model.coloured`).
"""

from __future__ import annotations

import numpy as np

from ._steady_clock import stamp_resolution
from .channel import ChannelId

__all__ = ["quantum", "analogue", "analogue_channels", "clock_tick"]


def quantum(y: np.ndarray) -> float:
    """The step of the lattice a quantised signal's readings lie on (its smallest
    change, when every change is a whole multiple of it to 1e-6), else 0."""
    y = np.asarray(y, dtype=float)
    d = np.abs(np.diff(y))
    d = d[d > 1e-12 * max(1.0, np.abs(y).max())]
    if d.size < 2:
        return 0.0
    q = float(d.min())
    return q if np.all(np.abs(d / q - np.rint(d / q)) < 1e-6) else 0.0


def clock_tick(time) -> float:
    """The tick (s) of the clock a trace's times were stamped by, where those stamps
    are all it knows of when each row was read: the resolution its times are written to
    (:func:`~._steady_clock.stamp_resolution`, a power of ten of a second) where its
    intervals are not whole multiples of one interval (a loop's own pace stamped by a
    coarse clock, 10 or 11 ms apart); 0 where they are (a steady rate, its times exact
    or read back from rounded stamps) or the times are written to no such resolution."""
    t = np.asarray(time, dtype=float)
    if t.size < 3 or quantum(t) > 0.0:
        return 0.0
    return stamp_resolution(t)


def analogue(y) -> bool:
    """Whether a channel's readings are analogue (not on a quantiser's lattice)."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    return y.size > 2 and quantum(y) == 0.0


def analogue_channels(session) -> dict[ChannelId, str]:
    """Every channel ``coloured_noise`` may give a correlation, to its trace: each driven
    trace's logged speed and current, each coast-down's speed, where analogue."""
    out = {}
    for tr in session.traces:
        for what, y in (("speed", tr.speed if tr.speed_logged else None),
                        ("current", tr.current)):
            if y is not None and analogue(y):
                out[ChannelId(tr.name, what)] = tr.name
    out.update({ChannelId(tr.name, "speed"): tr.name for tr in session.coast_downs
                if analogue(tr.speed)})
    return out
