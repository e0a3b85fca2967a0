"""A diagnosis rule on what a driver does at a zero command.

At a zero command the model's driver holds the armature's terminals together (a
bridge braking in slow decay): the back-emf drives a current that brakes the rotor
on the motor's own electrical time scale, as fast as it rose.  Many cheap drivers
instead open the armature there (an L298N with its enable low, PWM in coast or fast
decay): the current dies at once and the rotor coasts on its friction alone, for
``J/B`` rather than ``J·Ra/(K² + Ra·B)``.  The data then fall toward rest after
each switch to zero far more slowly than they rise after a switch on, which no fit
of the braking model shows (it compromises between the two time scales).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .onset import crossing_time, smoothed
from .proposals import Proposal, said

__all__ = ["coast_rules", "time_constants", "TimeConstants", "COAST_RATIO", "CLEAR"]

COAST_RATIO = 3.0  # a decay at a zero command this many times slower than every rise
EDGE = 3  # samples averaged for the level at a switch
CLEAR = 0.2  # a rise or a fall read only where it covers this share of the speed's range


class TimeConstants(NamedTuple):
    """A trace's 63.2 % times (s): of its rises toward a nonzero command's level, and of
    its falls toward rest after a switch to zero."""

    rises: list[float]
    falls: list[float]


def _fall(t, ys, t0, start, rest) -> float | None:
    """The 63.2 % time of a fall from ``start`` toward ``rest``: where ``ys`` gets there,
    else read off the share of the way left at its end (``-T / ln(share)``, an
    exponential's); None where it set off away from rest or moved no measurable way."""
    tau = crossing_time(t, ys, t0, start, rest)
    if tau is not None:
        return tau
    share = (float(np.mean(ys[-EDGE:])) - rest) / (start - rest)
    if not 0.0 < share < 1.0:
        return None
    return float(np.mean(t[-EDGE:]) - t0) / -np.log(share)


def _rise(t, ys, t0, start) -> float | None:
    """The 63.2 % time of a rise from ``start``: read at the crossing where the segment
    has settled (crossed in its first third), else from three equally spaced points,
    an exponential's ``-h / ln((y3 - y2) / (y2 - y1))`` (cut short before it settles,
    the crossing of its end level comes early); None where it is no such rise."""
    end = float(np.mean(ys[-EDGE:]))
    span = float(np.mean(t[-EDGE:]) - t0)
    tau = crossing_time(t, ys, t0, start, end)
    if tau is not None and tau < span / 3.0:
        return tau
    mid = float(np.interp(t0 + span / 2.0, t, ys))
    if mid == start:
        return None
    ratio = (end - mid) / (mid - start)
    return span / 2.0 / -np.log(ratio) if 0.0 < ratio < 1.0 else None


def _rest(tr, t, y, times, values) -> float:
    """The speed the sensor reads at rest: its mean before the first nonzero command
    of a trace that starts at rest and at zero (a sensor's offset), else zero."""
    if tr.initial != "rest" or values[0] != 0 or values.size < 2:
        return 0.0
    before = y[t < times[1]]
    return float(np.mean(before)) if before.size >= EDGE else 0.0


def time_constants(tr) -> TimeConstants:
    """The data's 63.2 % times (of the speed smoothed to quiet its noise): of each rise
    toward a nonzero command's level (from rest at the first sample too), and of each
    fall toward the speed read at rest after a switch to zero (read off the share of its
    way left at the segment's end where it never gets there); a rise or fall that
    covers less than :data:`CLEAR` of the speed's range is not read."""
    values = np.asarray(tr.voltage.values, float)
    runs = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])  # a logged column's
    times = np.append(np.asarray(tr.voltage.times, float)[runs], np.inf)  # levels
    values = values[runs]
    t, y = np.asarray(tr.time, float), np.asarray(tr.speed, float)
    keep = np.isfinite(y)
    t, y = t[keep], y[keep]
    out = TimeConstants([], [])
    if y.size < 4 * EDGE:
        return out
    clear = CLEAR * float(np.max(y) - np.min(y))
    rest = _rest(tr, t, y, times, values)
    for k in range(values.size):
        on = (t > times[k]) & (t < times[k + 1])
        before = np.flatnonzero(t <= times[k])[-EDGE:]
        if on.sum() < 4 * EDGE:
            continue
        if before.size:
            start = float(np.mean(y[before]))
        elif k == 0 and tr.initial == "rest":
            start = rest
        else:
            continue
        tt, ys = t[on], smoothed(y[on])
        if values[k] == 0 and np.any(values[:k] != 0):
            tau = _fall(tt, ys, times[k], start, rest) if abs(start - rest) > clear else None
            if tau is not None:
                out.falls.append(tau)
        elif values[k] != 0 and abs(float(np.mean(ys[-EDGE:])) - start) > clear:
            tau = _rise(tt, ys, times[k], start)
            if tau is not None:
                out.rises.append(tau)
    return out


def coast_rules(model, tr) -> list:
    """A sentence when the logged speed of ``tr`` falls toward rest after every switch
    to zero more than :data:`COAST_RATIO` times as slowly as it rises after every
    change to a nonzero command (model-free: a motor whose terminals the driver holds
    together brakes on the time scale it rises on), proposing ``open_at_zero``."""
    if "open_at_zero" in model.session.nuisances or tr.speed is None:
        return []
    rises, falls = time_constants(tr)
    if not rises or not falls or min(falls) < COAST_RATIO * max(rises):
        return []
    return [said(f"{tr.name}: after each switch to a zero command the speed takes "
                 f"{min(falls) / max(rises):.2g} times as long to fall as it takes to rise "
                 "after a step up, where a motor its driver brakes falls as fast as it "
                 "rises: the driver opens the armature at zero (an L298N or another "
                 "H-bridge with its enable low, PWM in coast or fast decay), and the rotor "
                 "coasts on its friction: --add open-at-zero, or open_at_zero = true "
                 "under [model]", Proposal("open_at_zero"))]
