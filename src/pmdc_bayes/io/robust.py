"""Robust statistics of a sampled signal, read before any model: the sd of its readings'
noise from the median absolute deviation of its differences (with a quantised signal's
rounding as a floor), and where it first leaves a level for good (a run of samples
beyond a threshold)."""

from __future__ import annotations

from math import comb, sqrt

import numpy as np

__all__ = ["MAD_SD", "CONSECUTIVE", "AT_REST", "difference_sd", "smooth", "smallest_step",
           "noise_floor", "resolution", "first_run", "departure"]

MAD_SD = 1.482602218505602  # sd of a normal variable per median absolute deviation
CONSECUTIVE = 3  # samples in a row beyond a threshold that count as having left a level
AT_REST = 0.02  # a level below this share of a signal's largest is its rest (0 V, no speed)


def difference_sd(values, order: int = 1) -> float:
    """The sd of a signal's white reading noise, from the median absolute deviation of
    its ``order``-th differences about their median (white noise of sd σ gives them an
    sd of σ·√C(2·order, order): √2 for the first, √6 for the second); the few samples
    where the signal itself steps or bends do not move a median.  0 for a signal that
    holds its value from one sample to the next more often than not.  Missing readings
    (NaN) are left out."""
    y = np.asarray(values, dtype=float)
    d = np.diff(y[np.isfinite(y)], order)
    if d.size < 2:
        return 0.0
    return float(MAD_SD * np.median(np.abs(d - np.median(d))) / sqrt(comb(2 * order, order)))


def smooth(values, correlated: float = 0.5, jump: float = 10.0) -> bool:
    """Whether a signal moves smoothly from sample to sample, with no reading noise: the
    lag-1 correlation of its first differences, each clipped to three robust sds about
    their median, above ``correlated`` (−½ for white reading noise about a level, a step
    or a ramp; −(1 − φ)/2 for AR(1) noise of lag-1 correlation φ; near 1 for a logged
    command's chirp), and no difference beyond ``jump`` robust sds of their median (a
    step, however a filter rounds it, stands out of noise that a filter has smoothed)."""
    y = np.asarray(values, dtype=float)
    d = np.diff(y[np.isfinite(y)])
    if d.size < 3:
        return False
    centre = np.median(d)
    spread = MAD_SD * np.median(np.abs(d - centre))
    if spread == 0.0 or float(np.max(np.abs(d - centre))) > jump * spread:
        return False
    c = np.clip(d - centre, -3.0 * spread, 3.0 * spread)
    c = c - c.mean()
    power = float(c @ c)
    return power > 0 and float(c[1:] @ c[:-1]) / power > correlated


def smallest_step(values) -> float:
    """The smallest change between successive readings (missing ones left out): a
    quantised signal's quantum, a tiny figure for an analogue one; 0 for a signal that
    never changes."""
    y = np.asarray(values, dtype=float)
    y = y[np.isfinite(y)]
    d = np.abs(np.diff(y))
    d = d[d > 1e-12 * max(1.0, float(np.abs(y).max()) if y.size else 0.0)]
    return float(d.min()) if d.size else 0.0


def noise_floor(values, order: int = 1) -> float:
    """The sd of a signal's reading noise, :func:`difference_sd`, and at least the
    rounding noise ``q/√12`` of its smallest step (a quantised signal whose readings
    mostly repeat has no differences to read its noise from)."""
    return max(difference_sd(values, order), smallest_step(values) / sqrt(12.0))


def resolution(values) -> float:
    """The smallest change a signal's readings resolve: the sd of its noise,
    :func:`difference_sd`, or its smallest step if larger (a quantised reading moves by
    whole steps, whatever its noise)."""
    return max(difference_sd(values), smallest_step(values))


def first_run(beyond: np.ndarray, n: int = CONSECUTIVE) -> int | None:
    """The index of the first of ``n`` samples in a row where ``beyond`` holds, or None."""
    beyond = np.asarray(beyond, dtype=int)
    if beyond.size < n:
        return None
    run = np.convolve(beyond, np.ones(n, int), mode="valid") == n
    k = np.flatnonzero(run)
    return int(k[0]) if k.size else None


def departure(values, sigma: float, clear: float, share: float = 0.05,
              falling: bool = False) -> int | None:
    """Where ``values`` leave their first level (the median of their first three) for
    good: the first of :data:`CONSECUTIVE` samples in a row beyond ``clear`` sds
    ``sigma`` of their noise and ``share`` of their largest departure; with ``falling``,
    only a fall below it counts.  None if they never do."""
    v = np.asarray(values, dtype=float)
    if v.size < CONSECUTIVE:
        return None
    level = float(np.median(v[:3]))
    away = level - v if falling else np.abs(v - level)
    return first_run(away > max(clear * sigma, share * float(away.max()), 1e-300))
