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
without noise (a logged command) is read as written, and so is one that moves smoothly
from sample to sample without a step (a logged chirp or sine: :func:`~.robust.smooth`),
and so is a duty (the trace reader does not send it here: it is the command itself,
however it moves).

A column sampled from a switching driver's output (an H-bridge's PWM read by an ADC
far slower than it switches) holds no level at all: each reading is a rail or zero, and
the motor, whose inductance and inertia average the switching, sees the duty.  Such a
column (:func:`switched_swing`) is read as the levels of its duty: each reading a draw
of the duty among the driver's states, the column cut where the readings' multinomial
likelihood says the duty changed (:func:`_duty_levels`), each level's error the duty's
own from its readings.  Where a change falls is known only to the samples its two
duties' draws take to differ; the fit's lead of each change carries that
(:func:`pmdc_bayes.inference.model.switch_lead.placement_sd`).

A level whose readings do not tell it from zero (its mean within the two-sided
:data:`ZERO_MISS` quantile of its standard errors) is read as zero, exactly, with no
error (:func:`_zeros`): the driver commanded zero (a stop, a coast, an unloaded rig),
which the readings of a level a hair off zero cannot be told from, and what the rig does
at a zero command (a driver that opens the armature there, a load that is none) acts
only on a zero.
"""

from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.special import xlogy

from .robust import difference_sd, smooth
from .session import Schedule

__all__ = ["held_levels", "switched_swing", "FALSE_SPLIT", "ZERO_MISS"]

FALSE_SPLIT = 0.01  # the chance that a column of constant level is split anywhere
ZERO_MISS = 0.01  # the chance that a level held at zero is not read as zero
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
    swing = switched_swing(values) if switching and np.all(np.isfinite(values)) else 0.0
    if swing:
        return _duty_levels(time, values, swing)
    sigma = difference_sd(values)
    if sigma == 0.0 or values.size < 3 or smooth(values):
        return Schedule(time, values)
    dof = max(1.0, MAD_EFFICIENCY * (values.size - 1))  # σ's own error, as Student's t
    c = float(stats.t.isf(FALSE_SPLIT / (2.0 * values.size), dof))
    bounds = np.array([0, *_cuts(values, _cusum(sigma), c), values.size])
    levels = np.array([values[a:b].mean() for a, b in zip(bounds[:-1], bounds[1:], strict=True)])
    return Schedule(time[bounds[:-1]], *_zeros(levels, sigma / np.sqrt(np.diff(bounds))), sigma)


def _zeros(levels: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``levels`` and their standard errors ``se`` with every level its readings do not
    tell from zero read as zero, known exactly (module docstring)."""
    zero = np.abs(levels) <= stats.norm.isf(ZERO_MISS / 2.0) * se
    return np.where(zero, 0.0, levels), np.where(zero, 0.0, se)


def _duty_levels(time: np.ndarray, values: np.ndarray, swing: float) -> Schedule:
    """The levels of the duty a switched column's readings held (module docstring).

    Each reading is one of the driver's states (zero and the rails it reaches: zero or
    a rail for a bridge that switches between its output and zero, one rail or the other
    for one that never rests), a categorical draw of the level's duty.  The column is
    cut by binary segmentation on the multinomial likelihood ratio of two duties against
    one (2·Δlog L, χ² with a degree of freedom per state beyond the first at any one cut
    of a constant duty), such that a constant duty is cut anywhere with probability
    :data:`FALSE_SPLIT` at most (a union bound over the column's cuts): a change of
    direction, a rest and a change of duty alike, each cut where the readings make it
    most likely.  Each level is the mean of its readings, its error the duty's
    multinomial error from its readings (with half a reading more in each state, so that
    a level its readings never left is known to about 1/n of the rail) and their scatter
    about the states they read."""
    tol = SWITCH_TOLERANCE * swing
    rails = [r for r in (float(values.min()), float(values.max())) if abs(r) > tol]
    states = np.array(sorted(set(rails) | ({0.0} if np.any(np.abs(values) <= tol) else set())))
    code = np.abs(values[:, None] - states[None, :]).argmin(axis=1)
    onehot = (code[:, None] == np.arange(states.size)[None, :]).astype(float)
    c2 = float(stats.chi2.isf(FALSE_SPLIT / values.size, max(states.size - 1, 1)))
    bounds = np.array([0, *_cuts(onehot, _multinomial_ratio, c2), values.size])
    levels, se = [], []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        n = b - a
        p = (onehot[a:b].sum(axis=0) + 0.5) / (n + 0.5 * states.size)
        spread = float(p @ states**2 - (p @ states) ** 2)
        scatter = float(np.mean((values[a:b] - states[code[a:b]]) ** 2))
        levels.append(float(values[a:b].mean()))
        se.append(float(np.sqrt((spread + scatter) / n)))
    return Schedule(time[bounds[:-1]], *_zeros(np.array(levels), np.array(se)), swing / 2.0, True)


def _loglik(k: np.ndarray) -> np.ndarray:
    """The multinomial log-likelihood of the counts ``k`` (last axis: the states) at
    their best shares."""
    n = k.sum(axis=-1, keepdims=True)
    return np.sum(xlogy(k, k / np.where(n > 0, n, 1.0)), axis=-1)


def _multinomial_ratio(onehot: np.ndarray) -> np.ndarray:
    """At each cut of a part whose readings are ``onehot`` (one column per state), the
    likelihood ratio ``2·Δlog L`` of two duties against one (:func:`_duty_levels`)."""
    left = np.cumsum(onehot, axis=0)[:-1]
    total = onehot.sum(axis=0)
    return 2.0 * (_loglik(left) + _loglik(total - left) - _loglik(total))


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


def _cusum(sigma: float):
    """At each cut of a part, the standardised difference of the means on either side
    for readings of noise sd ``sigma`` (:func:`held_levels`)."""
    def statistic(part: np.ndarray) -> np.ndarray:
        m = part.size
        k = np.arange(1, m)
        return np.abs(np.cumsum(part - part.mean())[:-1]) / (sigma * np.sqrt(k * (m - k) / m))
    return statistic


def _cuts(x: np.ndarray, statistic, c: float) -> list[int]:
    """The first samples of every level after the first: binary segmentation, each
    stretch cut where ``statistic`` (per cut of the stretch) is largest when it exceeds
    ``c``, then each side in turn."""
    cuts, stack = [], [(0, x.size)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        t = statistic(x[a:b])
        j = int(np.argmax(t))
        if t[j] > c:
            cuts.append(a + j + 1)
            stack += [(a, a + j + 1), (a + j + 1, b)]
    return sorted(cuts)
