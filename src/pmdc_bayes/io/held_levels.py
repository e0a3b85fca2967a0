"""A logged input column read as the levels its driver held.

A column logged by an analogue channel (the driver's output read by an ADC, a torque
sensor) carries the channel's noise on every sample.  Held sample by sample, each reading
would start a new constant segment of the input: the noise fed to the motor as if the
driver had applied it, and a segment per sample for every solution whose cost grows with
the segments (a current limit, a voltage drop, Coulomb friction).  Where the column is
noisy, the input is read instead as the levels it held: a new level where two
consecutive readings leave the current level's mean by more than the column's noise
allows, each level the mean of its readings, starting at the first sample that shows it
(as a held column's change does).  A change larger than the noise (a step, a supply that
sags under load, a slow ramp in steps of a few noise widths) is kept; a column without
noise (a logged command, a duty) is read as written.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .session import Schedule

__all__ = ["held_levels", "column_noise", "FALSE_SPLIT"]

FALSE_SPLIT = 0.01  # the chance that a column of constant level is split anywhere
_MAD_SD = 1.482602218505602  # sd of a normal variable per median absolute deviation


def column_noise(values: np.ndarray) -> float:
    """The sd of a column's reading noise, from the median absolute deviation of its
    first differences (robust to the column's steps, which are few); 0 for a column that
    holds its value from one sample to the next more often than not (a command written as
it was set, or a reading whose noise seldom moves it by a quantum: read as written)."""
    d = np.diff(np.asarray(values, dtype=float))
    if d.size < 2:
        return 0.0
    return float(_MAD_SD * np.median(np.abs(d - np.median(d))) / np.sqrt(2.0))


def held_levels(time: np.ndarray, values: np.ndarray) -> Schedule:
    """The levels a noisy column held (module docstring), each with its standard error;
    the column itself where it has no noise.  A level ends where two consecutive readings lie
    more than ``c·σ·√(1 + 1/m)`` from the running mean of its ``m`` readings, ``c`` such
    that even one Gaussian reading of sd σ would leave a constant level with probability
    :data:`FALSE_SPLIT` at most over the column's length (two in a row, far less often:
    room for the error of σ, estimated from the same readings)."""
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    sigma = column_noise(values)
    if sigma == 0.0 or values.size < 3:
        return Schedule(time, values)
    c = float(stats.norm.isf(FALSE_SPLIT / (2.0 * values.size)))
    limit = c * sigma
    starts, total, count = [0], values[0], 1
    k, n = 1, values.size
    while k < n:
        mean = total / count
        off = limit * np.sqrt(1.0 + 1.0 / count)  # a reading's spread about the mean
        if k + 1 < n and abs(values[k] - mean) > off and abs(values[k + 1] - mean) > off:
            starts.append(k)
            total, count = values[k], 1
        else:
            total, count = total + values[k], count + 1
        k += 1
    bounds = np.append(starts, n)
    levels = np.array([values[a:b].mean() for a, b in zip(bounds[:-1], bounds[1:],
                                                          strict=True)])
    return Schedule(time[np.asarray(starts)], levels, sigma / np.sqrt(np.diff(bounds)))
