"""A time column written by a clock coarse against its sampling: a steady rate's times
read back from its rounded stamps.

A logger that samples at a steady rate and stamps each row with a coarse clock (an
Arduino's ``millis()`` at a few hundred hertz, seconds written to the millisecond at
a kilohertz) writes each sample's time rounded to the clock's resolution ``q``: an
error uniform over ``±q/2`` that the model would read as the motor's, at the fast
changes (an electrical transient, a switch) above all.  Where every stamp lies within
:data:`WITHIN` of ``q`` of one straight line through the row numbers, the rows are that
steady rate rounded, and the line gives their times; a sampling whose interval itself
varies (a loop timed by the same clock, stamps 2 or 3 ms apart as it happens) strays
further, and its stamps are kept.
"""

from __future__ import annotations

import numpy as np

__all__ = ["COARSE", "WITHIN", "stamp_resolution", "steady_times"]

COARSE = 0.1  # a clock resolution this share of the sample interval or more is coarse
WITHIN = 0.6  # stamps within this share of the resolution of a line are a steady rate


def stamp_resolution(t_raw: np.ndarray) -> float:
    """The largest power of ten (10⁻⁹ … 10³ of the column's unit) every stamp is a whole
    number of: the resolution the times were written to; 0 when none is, or none can be
    told from the stamps' own rounding as numbers (a clock's seconds since 1970 written
    to the microsecond)."""
    t = np.asarray(t_raw, dtype=float)
    if not t.size:
        return 0.0
    own = 8.0 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(t))))
    for k in range(3, -10, -1):
        q = 10.0**k
        if own > 1e-2 * q:  # a resolution this fine is lost in the stamps' own rounding
            break
        if np.all(np.abs(t - q * np.round(t / q)) <= max(1e-6 * q, own)):
            return q
    return 0.0


def steady_times(t_raw: np.ndarray, rows) -> np.ndarray:
    """``t_raw`` (strictly increasing stamps, in the column's unit) at the steady rate
    through ``rows`` (each sample's row number in its file) that they round, when their
    resolution is coarse (:data:`COARSE`) and every stamp lies within :data:`WITHIN`
    of it of the straight line fitted to them; ``t_raw`` itself otherwise (and where it
    lies on that line already).  ``rows`` number the file's samples (its rows of
    readings, not its comments), so that a comment line leaves no gap in the rate."""
    t = np.asarray(t_raw, dtype=float)
    k = np.asarray(rows, dtype=float)
    if t.size < 8:
        return t
    q = stamp_resolution(t)
    step = float(np.median(np.diff(t)))
    if not (q > 0.0 and step > 0.0 and q >= COARSE * step):
        return t
    slope, origin = np.polyfit(k - k[0], t, 1)
    line = origin + slope * (k - k[0])
    off = float(np.max(np.abs(t - line)))
    if slope <= 0.0 or off > WITHIN * q or off <= 1e-6 * q:  # not a steady rate, or exact
        return t
    return line
