"""A logged input column read as the levels its driver held.

A column logged by an analogue channel (the driver's output read by an ADC, a torque
sensor) carries the channel's noise on every sample.  Held sample by sample, each reading
would start a new constant segment of the input: the noise fed to the motor as if the
driver had applied it, and a segment per sample for every solution whose cost grows with
the segments (a current limit, a voltage drop, Coulomb friction).  Where the column is
noisy, the input is read instead as the levels it held: the column cut where the means
on either side differ by more than its noise allows, each level the mean of its
readings, starting at the first sample that shows it (as a held column's change does).
A change the readings show beyond their noise (a step, a driver's overshoot, a supply
that sags under load, in levels that each hold within their error) is kept; a column
without noise (a logged command) is read as written, and so is a duty (the trace reader
does not send it here: it is the command itself, however it moves).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .robust import difference_sd
from .session import Schedule

__all__ = ["held_levels", "FALSE_SPLIT"]

FALSE_SPLIT = 0.01  # the chance that a column of constant level is split anywhere
MAD_EFFICIENCY = 0.37  # a MAD's σ is as good as a sample sd from this share of its readings


def held_levels(time: np.ndarray, values: np.ndarray) -> Schedule:
    """The levels a noisy column held (module docstring), each with its standard error;
    the column itself where it has no noise.  The levels are found by binary
    segmentation: a stretch of the column is cut where the standardised difference of
    the means on either side (its CUSUM statistic, N(0, 1) at any one cut of a constant
    level with Gaussian readings of sd σ) is largest, when it exceeds ``c``, such that a
    constant level is cut anywhere with probability :data:`FALSE_SPLIT` at most (a
    union bound over the column's cuts; Student's t for σ's own error, with the degrees
    of freedom of :data:`MAD_EFFICIENCY` of the differences); then each side in turn.
    A step is cut at the first sample that shows it, and a drift (a sagging supply) into
    levels that each hold within their readings' error."""
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    sigma = difference_sd(values)
    if sigma == 0.0 or values.size < 3:
        return Schedule(time, values)
    dof = max(1.0, MAD_EFFICIENCY * (values.size - 1))  # σ's own error, as Student's t
    c = float(stats.t.isf(FALSE_SPLIT / (2.0 * values.size), dof))
    bounds = np.array([0, *_cuts(values, sigma, c), values.size])
    levels = np.array([values[a:b].mean() for a, b in zip(bounds[:-1], bounds[1:],
                                                          strict=True)])
    return Schedule(time[bounds[:-1]], levels, sigma / np.sqrt(np.diff(bounds)))


def _cuts(x: np.ndarray, sigma: float, c: float) -> list[int]:
    """The first samples of every level after the first (:func:`held_levels`)."""
    cuts, stack = [], [(0, x.size)]
    while stack:
        a, b = stack.pop()
        m = b - a
        if m < 2:
            continue
        part = x[a:b]
        k = np.arange(1, m)
        cusum = np.abs(np.cumsum(part - part.mean())[:-1])
        t = cusum / (sigma * np.sqrt(k * (m - k) / m))
        j = int(np.argmax(t))
        if t[j] > c:
            cuts.append(a + j + 1)
            stack += [(a, a + j + 1), (a + j + 1, b)]
    return sorted(cuts)
