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

A column sampled from a switching driver's output (an H-bridge's PWM read by an ADC
far slower than it switches) holds no level at all: each reading is a rail or zero, and
the motor, whose inductance and inertia average the switching, sees the duty.  Such a
column (:func:`switched_swing`) is read as the levels of its duty the same way, its
noise the switching's (at most half its swing, then the largest spread of the levels
so found), each level's error from its own
readings' spread (and at least what n readings leave of a duty: a level its readings
never left is known to about 1/n of the swing).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .robust import difference_sd
from .session import Schedule

__all__ = ["held_levels", "switched_swing", "FALSE_SPLIT"]

FALSE_SPLIT = 0.01  # the chance that a column of constant level is split anywhere
MAD_EFFICIENCY = 0.37  # a MAD's σ is as good as a sample sd from this share of its readings
SWITCH_TOLERANCE = 0.1  # a switched column's readings lie this share of its swing from a rail
MIN_SWITCHES = 5  # ... or zero, and it flips for one or two samples this often at least


def held_levels(time: np.ndarray, values: np.ndarray, switching: bool = False) -> Schedule:
    """The levels a noisy column held (module docstring), each with its standard error;
    the column itself where it has no noise.  The levels are found by binary
    segmentation: a stretch of the column is cut where the standardised difference of
    the means on either side (its CUSUM statistic, N(0, 1) at any one cut of a constant
    level with Gaussian readings of sd σ) is largest, when it exceeds ``c``, such that a
    constant level is cut anywhere with probability :data:`FALSE_SPLIT` at most (a
    union bound over the column's cuts; Student's t for σ's own error, with the degrees
    of freedom of :data:`MAD_EFFICIENCY` of the differences); then each side in turn.
    A step is cut at the first sample that shows it, and a drift (a sagging supply) into
    levels that each hold within their readings' error.  With ``switching`` (a voltage
    column), one sampled from a switching driver's output (:func:`switched_swing`) is
    read as the levels of its duty."""
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    switched = switched_swing(values) / 2.0 if switching else 0.0
    sigma = switched or difference_sd(values)
    if sigma == 0.0 or values.size < 3:
        return Schedule(time, values)
    dof = max(1.0, MAD_EFFICIENCY * (values.size - 1))  # σ's own error, as Student's t
    c = float(stats.t.isf(FALSE_SPLIT / (2.0 * values.size), dof))
    bounds = np.array([0, *_cuts(values, sigma, c), values.size])
    parts = [values[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    if switched:  # cut again at the switching's largest spread within a level
        sigma = min(sigma, max(float(x.std(ddof=1)) if x.size > 1 else 0.0 for x in parts))
        sigma = sigma or switched
        bounds = np.array([0, *_cuts(values, sigma, c), values.size])
        parts = [values[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    levels = np.array([x.mean() for x in parts])
    n = np.diff(bounds)
    if switched:  # each level's own spread, and a duty's error from n readings at least
        spread = np.array([x.var(ddof=1) if x.size > 1 else sigma**2 for x in parts])
        se = np.sqrt((spread + sigma**2 / n) / n)
    else:
        se = sigma / np.sqrt(n)
    return Schedule(time[bounds[:-1]], levels, se, sigma, bool(switched))


def switched_swing(values) -> float:
    """The swing of a column sampled from a switching driver's output, 0 for any other:
    every reading within :data:`SWITCH_TOLERANCE` of the swing of zero or of a rail (the
    column's largest reading above zero, its smallest below, each one beyond that share
    of the swing from zero), and the column flipping between zero and a rail, or between
    the rails, for one or two samples at least :data:`MIN_SWITCHES` times (a logged
    command or a driver's held output flips only at its steps, and a noisy level never
    reaches zero)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 3:
        return 0.0
    hi, lo = max(float(v.max()), 0.0), min(float(v.min()), 0.0)
    swing = hi - lo
    tol = SWITCH_TOLERANCE * swing
    levels = np.array([0.0] + [x for x in (lo, hi) if abs(x) > tol])
    if levels.size < 2:
        return 0.0
    gap = np.abs(v[:, None] - levels[None, :])
    if not np.all(gap.min(axis=1) <= tol):
        return 0.0
    state = gap.argmin(axis=1)
    flips = np.flatnonzero(np.diff(state)) + 1
    runs = np.diff(np.concatenate([[0], flips, [state.size]]))[1:-1]
    return swing if int(np.sum(runs <= 2)) >= MIN_SWITCHES else 0.0


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
