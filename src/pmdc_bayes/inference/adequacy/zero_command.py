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

import numpy as np

from .proposals import Proposal, said

__all__ = ["coast_rules", "COAST_RATIO"]

COAST_RATIO = 3.0  # a decay at a zero command this many times slower than every rise
EDGE = 3  # samples averaged for the level at a switch


def _crossing(t, y, t0, start, target):
    """The time after ``t0`` at which ``y`` (samples after it) first gets from ``start``
    to ``target`` (63.2 % of the way), or None when it never does."""
    level = start + (1.0 - np.exp(-1.0)) * (target - start)
    sense = np.sign(target - start)
    past = np.flatnonzero(sense * (y - level) >= 0)
    return float(t[past[0]] - t0) if past.size else None


def _time_constants(tr):
    """The data's 63.2 % times: of each rise toward a nonzero command's settled level,
    and of each fall toward rest after a switch to zero (its segment's length where it
    never gets there: a lower bound)."""
    values = np.asarray(tr.voltage.values, float)
    runs = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])  # a logged column's
    times = np.append(np.asarray(tr.voltage.times, float)[runs], np.inf)  # levels
    values = values[runs]
    t, y = np.asarray(tr.time, float), np.asarray(tr.speed, float)
    rises, falls = [], []
    for k in range(1, values.size):
        on = (t > times[k]) & (t < times[k + 1])
        before = np.flatnonzero(t <= times[k])[-EDGE:]
        if on.sum() < 4 * EDGE or before.size == 0:
            continue
        start = float(np.mean(y[before]))
        tt, yy = t[on], y[on]
        if values[k] == 0 and np.any(values[:k] != 0):
            tau = _crossing(tt, yy, times[k], start, 0.0)
            falls.append(tau if tau is not None else float(tt[-1] - times[k]))
        elif values[k] != 0:
            end = float(np.mean(yy[-max(EDGE, yy.size // 10):]))
            tau = _crossing(tt, yy, times[k], start, end)
            if tau is not None and abs(end - start) > 0:
                rises.append(tau)
    return rises, falls


def coast_rules(model, tr) -> list:
    """A sentence when the logged speed of ``tr`` falls toward rest after every switch
    to zero more than :data:`COAST_RATIO` times as slowly as it rises after every
    change to a nonzero command (model-free: a motor whose terminals the driver holds
    together brakes on the time scale it rises on), proposing ``open_at_zero``."""
    if "open_at_zero" in model.session.nuisances or tr.speed is None:
        return []
    rises, falls = _time_constants(tr)
    if not rises or not falls or min(falls) < COAST_RATIO * max(rises):
        return []
    return [said(f"{tr.name}: after each switch to a zero command the speed takes "
                 f"{min(falls) / max(rises):.2g} times as long to fall as it takes to rise "
                 "after a step up, where a motor its driver brakes falls as fast as it "
                 "rises: the driver opens the armature at zero (an L298N or another "
                 "H-bridge with its enable low, PWM in coast or fast decay), and the rotor "
                 "coasts on its friction: --add open-at-zero, or open_at_zero = true "
                 "under [model]", Proposal("open_at_zero"))]
