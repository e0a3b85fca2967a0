"""Readings a logger missed: the rows of a trace's CSV with an empty or ``NaN`` cell in a
channel (:data:`._cells.MISSING`) are left out, the others kept at their own times, as long
as they are a few; the trace records the file lines it left out."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._errors import SessionError

__all__ = ["MISSABLE", "MISSING_SHARE", "without_missing", "without_repeats"]

MISSABLE = frozenset({"speed", "current", "voltage", "load_torque", "position"})
MISSING_SHARE = 0.1  # at most this share of a trace's rows may be left out


def without_missing(path: Path, raw: dict, t_raw: np.ndarray, lines: list, cols: dict):
    """``raw``, ``t_raw`` and ``lines`` without the rows where a channel's reading is
    missing (NaN), and the file lines of those rows; the rows after the last that holds
    any of the trace's readings (a trace that ended before the time column its file
    shares with a longer one) dropped, not counted as missed.  More than :data:`MISSING_SHARE` of
    the rows missing is an error naming the column that misses most (a channel logged at
    a lower rate than the trace, whose gaps would take the other channels' readings
    with them)."""
    gaps = {role: ~np.isfinite(raw[role]) for role in MISSABLE & raw.keys()}
    ended = np.logical_and.reduce(list(gaps.values())) if gaps else np.zeros(t_raw.size, bool)
    end = t_raw.size - int(np.argmin(ended[::-1])) if not ended.all() else t_raw.size
    if end < t_raw.size:  # the trace ended before the time column its file shares
        raw = {role: v[:end] for role, v in raw.items()}
        t_raw, lines = t_raw[:end], lines[:end]
        gaps = {role: g[:end] for role, g in gaps.items()}
    bad = np.zeros(t_raw.size, bool)
    for g in gaps.values():
        bad |= g
    if not bad.any():
        return raw, t_raw, lines, ()
    if bad.sum() > MISSING_SHARE * bad.size:
        role = max(gaps, key=lambda r: int(gaps[r].sum()))
        raise SessionError(path, f"column {cols[role]!r} has no reading in "
                           f"{int(gaps[role].sum())} of {bad.size} rows (at most "
                           f"{MISSING_SHARE:.0%} of a trace's rows may miss one, and are "
                           "left out); log it at the trace's rate, fill in the readings, "
                           "or give it a trace (CSV) of its own",
                           where=f"line {lines[int(np.argmax(gaps[role]))]}")
    keep = ~bad
    out = {role: v[keep] for role, v in raw.items()}
    dropped = tuple(int(x) for x, b in zip(lines, bad, strict=True) if b)
    return out, t_raw[keep], [x for x, k in zip(lines, keep, strict=True) if k], dropped


def without_repeats(raw: dict, t_raw: np.ndarray, lines: list):
    """``raw``, ``t_raw`` and ``lines`` without the rows that repeat the row before them
    in every column, the time included, where the readings move (a row a logger wrote
    twice: read once), and the file lines of those rows.  Where the readings stand still
    (a motor at rest) a repeated row may as well be a sample whose time is wrong, and is
    left to the check of the time."""
    same = np.zeros(t_raw.size, bool)
    moved = np.zeros(t_raw.size, bool)  # a row's readings differ from the row before
    if t_raw.size > 2:
        same[1:] = t_raw[1:] == t_raw[:-1]
        for role, v in raw.items():
            same[1:] &= (v[1:] == v[:-1]) | (np.isnan(v[1:]) & np.isnan(v[:-1]))
            if role != "time":
                moved[1:] |= v[1:] != v[:-1]
        first = np.maximum.accumulate(np.where(same, 0, np.arange(t_raw.size)))
        same &= moved[first]  # the row repeated had moved on from the one before it
    if not same.any():
        return raw, t_raw, lines, ()
    keep = ~same
    return ({role: v[keep] for role, v in raw.items()}, t_raw[keep],
            [x for x, k in zip(lines, keep, strict=True) if k],
            tuple(int(x) for x, b in zip(lines, same, strict=True) if b))
