"""A trace's time column that does not increase: what the rows that break it most likely
are (a timer that wraps, a row logged twice, a stray time stamp, a clock coarser than the
sampling), and the fix, in the one line the loader refuses it with."""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from .._errors import SessionError

__all__ = ["check_date_serial", "check_increasing", "STRAY_REPEATS"]

STRAY_REPEATS = 3  # a time repeated this often or less is a stray, not a coarse clock


def check_increasing(path: Path, column: str | None, raw: dict, t_raw: np.ndarray,
                     lines: list, rows: int, second: float, *, wrap_given: bool) -> None:
    """Raise :class:`~pmdc_bayes.SessionError` where the times ``t_raw`` (in the trace's
    unit, ``second`` of them to the second; ``raw`` the columns read, ``lines`` each
    sample's line in the file, ``rows`` the rows before any was left out) do not
    increase strictly, naming the first line that breaks them and what to do."""
    bad = np.nonzero(np.diff(t_raw) <= 0)[0]
    if not bad.size:
        return
    k = int(bad[0]) + 1
    repeated = np.flatnonzero(np.diff(t_raw) == 0) + 1
    going_on = bool(np.all(np.diff(t_raw) >= 0) and t_raw[-1] > t_raw[0])
    rate = (rows - 1) / float(t_raw[-1] - t_raw[0]) / second if going_on else None
    fix = "sort the rows by time and remove duplicate samples"
    wrap = _counter_wrap(t_raw[k - 1], t_raw[k])
    if wrap is not None and not wrap_given:
        fix = (f"the time jumps back near 2^{wrap.bit_length() - 1}: a timer that wraps; "
               f"add time_wrap = {wrap} to the trace (in its time unit)")
    elif _restarts(t_raw, k):
        fix = (f"the time starts again at line {lines[k]}, as when two records are joined in "
               "one file; give each record a trace (and a file) of its own, or remove the "
               "second")
    elif repeated.size == 1 and all(v[k] == v[k - 1] for v in raw.values()):
        fix = (f"line {lines[k]} repeats line {lines[k - 1]} in every column: a row logged "
               f"twice, or a sample whose time is wrong; remove line {lines[k]} or mend its "
               "time")
    elif t_raw[k] == t_raw[k - 1] and repeated.size <= STRAY_REPEATS:
        named = ", ".join(str(lines[i]) for i in repeated)
        fix = (f"the time repeats the line before at line{'s' * (repeated.size > 1)} {named} "
               "only: a row logged twice or a sample whose time is wrong (remove or mend "
               f"{'them' if repeated.size > 1 else 'it'}), unless the clock is coarser than "
               "the sampling (then remove columns.time and give sample_rate" + (
                   f" = {rate:.4g} Hz)" if rate else ")"))
    elif going_on:
        fix = ("the time repeats, never going back: a clock coarser than the sampling (a "
               "logger's millisecond stamps); if the rows are samples at a steady rate, "
               f"remove columns.time and give sample_rate = {rate:.4g} (Hz, the rows over "
               "the record's span), or log a finer time")
        each = _repeats_each(t_raw)
        if each:
            fix += (f"; but if the file holds one row per channel and time (a long format: "
                    f"every time is written {each} times over, a column naming the "
                    "channel), give each channel a column of its own, one row per time")
    raise SessionError(path, f"time column {column!r} is not strictly increasing: "
                       f"{t_raw[k]:.12g} follows {t_raw[k - 1]:.12g} (line {lines[k - 1]}); "
                       f"{fix}", where=f"line {lines[k]}")


def _repeats_each(t_raw: np.ndarray) -> int | None:
    """The number of rows each time is written on, where every time but the last is
    written on as many (2 or more); None where they differ."""
    starts = np.flatnonzero(np.concatenate([[True], np.diff(t_raw) != 0]))
    runs = np.diff(np.concatenate([starts, [t_raw.size]]))[:-1]
    return int(runs[0]) if runs.size >= 3 and runs[0] >= 2 and np.all(runs == runs[0]) else None


def _restarts(t_raw: np.ndarray, k: int) -> bool:
    """Whether the time starts again at sample ``k``: back by more than two of its steps
    to (or before) its first value, and on from there at its steps (a second record, not
    one sample's wrong time nor two rows swapped)."""
    if k < 5 or k + 3 > t_raw.size:
        return False
    step = float(np.median(np.diff(t_raw[:k])))
    after = np.diff(t_raw[k:k + 3])
    return bool(t_raw[k - 1] - t_raw[k] > 2.0 * step and t_raw[k] <= t_raw[0] + 0.5 * step
                and np.all((after > 0) & (after <= 2.0 * step)))


def _counter_wrap(before: float, after: float) -> int | None:
    """The modulus ``2^k`` (k = 8 ... 64) of a timer that wrapped between two readings,
    when ``before`` lies in the top tenth of that range and ``after`` in the bottom
    tenth, else None."""
    for bits in (8, 10, 12, 16, 24, 31, 32, 48, 63, 64):
        wrap = 2**bits
        if 0.9 * wrap <= before < wrap and 0 <= after < 0.1 * wrap:
            return wrap
    return None


def check_date_serial(path: Path, column: str, t_raw: np.ndarray, second: float) -> None:
    """Refuse a time column that reads as a spreadsheet's date serial (days since
    1899-12-30, a day's fraction the time: 45413.5 is noon on 2024-05-01): its first
    time a day of the years 1954–2119, and its sample interval a round period (1, 2 or 5
    × 10^k s, to 1 %) read as days but not read in the trace's unit (``second`` of it to
    the second)."""
    if t_raw.size < 3 or not 20000.0 <= float(t_raw[0]) <= 80000.0:
        return
    step = float(np.median(np.diff(t_raw)))
    mean = float(t_raw[-1] - t_raw[0]) / (t_raw.size - 1)
    step = mean if abs(mean - step) <= 0.05 * step else step  # each time rounded alike
    if not (_round_period(step * 86400.0) and not _round_period(step * second)):
        return
    day = datetime(1899, 12, 30) + timedelta(days=float(t_raw[0]))
    raise SessionError(path, f"the time column {column!r} reads as a spreadsheet's date "
                       f"serial (days since 1899-12-30: {t_raw[0]:.9g} is "
                       f"{day:%Y-%m-%d %H:%M:%S}), its samples {step * 86400.0:.3g} s apart "
                       f"as days, {step * second:.3g} s as written; write the time in "
                       "seconds ((date - first date) × 86400) or as clock times "
                       "(hh:mm:ss.fff)", where="header")


def _round_period(seconds: float) -> bool:
    """Whether a sample interval is 1, 2 or 5 × 10^k s, to 1 %."""
    if not seconds > 0.0:
        return False
    mantissa = seconds / 10.0 ** np.floor(np.log10(seconds))
    return any(abs(mantissa / m - 1.0) <= 0.01 for m in (1.0, 2.0, 5.0, 10.0))


SLOW_SAMPLES = 0.5  # s: samples this far apart log no motor's step


def check_slow_time(path: Path, column: str, t_raw: np.ndarray, where: str, *,
                     whole: bool = True) -> None:
    """Refuse a time column written as plain numbers with no unit given (none in
    session.toml, its header or a row of units: the caller's to judge) whose samples are
    :data:`SLOW_SAMPLES` or more apart: read as seconds they are that many seconds apart,
    as a motor's step is not logged, while a logger's millisecond or microsecond
    counter (an Arduino's ``millis()``, ``micros()``, ``whole``) or its milliseconds as
    decimals (``micros() / 1000.0``), or a sample count, write exactly that (``where``:
    the trace's table in session.toml)."""
    finite = t_raw[np.isfinite(t_raw)]
    if finite.size < 3:
        return
    step = float(np.median(np.diff(finite)))
    if step < SLOW_SAMPLES:
        return
    written = (f"holds whole numbers {step:g} apart" if whole else
               f"holds numbers {step:.3g} apart (the median)")
    raise SessionError(path, f"the time column {column!r} gives no unit and {written}: read "
                       f"as seconds, its samples are {step:.3g} s apart, as a logger's "
                       "millisecond or microsecond counter or a sample count would write "
                       f"them; set {where}.units.time = \"ms\" (or \"us\"; \"s\" if they "
                       "are seconds), or, for a sample count, give "
                       "sample_rate and leave time out of columns", where="header")
