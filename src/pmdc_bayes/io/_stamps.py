"""A logger's time stamps in a CSV time column (``12:00:01.250``, ``10:15:03.120 PM``,
a date and a zone around it allowed, ``26-Nov-2026 14:03:07.251`` as MATLAB writes a
datetime): read as seconds since midnight, then as the time since the first row, a
day's turn found from the clock going back; or durations with their unit (``0.001
sec``), read as written, in the column's unit of time."""

from __future__ import annotations

import re

import numpy as np

from .units import unit_factor, unit_named

__all__ = ["STAMP", "DURATION", "stamp_seconds", "duration_seconds", "elapsed"]

# A logger's time stamp: a clock time h:mm:ss[.f] (on a 12-hour clock with AM or PM; a
# date, its month a number or a name, and a zone around it allowed, both passed over) or
# m:ss.f; the day's turn is found from the clock going back.
STAMP = re.compile(r"(?:\d{1,4}[-/. ](?:\d{1,2}|[A-Za-z]{3,9})[-/. ]\d{1,4}(?:T|\s+))?"
                   r"(?:(\d{1,2}):)?(\d{1,2}):"
                    r"(\d{2}(?:[.,]\d*)?)\s*(?:([AP])\.?M\.?)?\s*(?:Z|UTC|[+-]\d{2}:?\d{2})?",
                    re.IGNORECASE)
DAY = 86400.0
# A duration with its unit of time, as MATLAB writes a timetable's (``0.001 sec``) or a
# logger its elapsed time (``12.5s``, ``250 ms``).
DURATION = re.compile(r"([+-]?\d+(?:[.,]\d*)?(?:e[+-]?\d+)?)\s*([a-zµμ]+)", re.IGNORECASE)


def duration_seconds(text: str) -> float | None:
    """The seconds of a duration with its unit (:data:`DURATION`, a unit of time as
    :func:`~.units.unit_named` reads it), or None when ``text`` is none."""
    d = DURATION.fullmatch(text.strip().replace("\u2212", "-"))
    unit = None if d is None else unit_named("time", d.group(2))
    return None if unit is None else float(d.group(1).replace(",", ".")) * unit_factor(
        "time", unit)


def stamp_seconds(text: str) -> float | None:
    """The seconds since midnight of a logger's time stamp (:data:`STAMP`), or of a
    duration (:data:`DURATION`), or None when ``text`` is neither (a stamp m:ss needs
    a fraction of a second, as ``12:00`` could be hours or minutes)."""
    d = duration_seconds(text)
    if d is not None:
        return d
    m = STAMP.fullmatch(text.strip())
    if m is None:
        return None
    hours, minutes, seconds = m.group(1), m.group(2), m.group(3).replace(",", ".")
    if hours is None and "." not in seconds:
        return None
    h = int(hours or 0)
    if m.group(4) is not None:  # a 12-hour clock: 12:00 AM is midnight, 12:00 PM noon
        if hours is None or not 1 <= h <= 12:
            return None
        h = h % 12 + (12 if m.group(4).upper() == "P" else 0)
    return 3600.0 * h + 60.0 * int(minutes) + float(seconds)


def elapsed(stamps: np.ndarray, seconds_per_unit: float) -> np.ndarray:
    """Time stamps (seconds since midnight) as the time since the first, in the
    column's unit: a stamp earlier than the one before by more than half a day is on
    the next day."""
    turn = np.concatenate([[0.0], np.cumsum(np.diff(stamps) < -0.5 * DAY)])
    return (stamps + DAY * turn - stamps[0]) / seconds_per_unit
