"""A logger's clock: a rendered session's traces stamped as a microcontroller logs them,
in whole milliseconds (``millis()``) where a steady rate leaves two or more between
samples, else in microseconds on a 4 µs tick (``micros()`` of a 16 MHz board; encoder
edges are always stamped so).  The motor and every reading are the session's as before;
only the stamps round, and the trace's schedules are written in the stamps' unit."""

from __future__ import annotations

import tomllib

import numpy as np

from ._text import pairs, trace_block

__all__ = ["MICROS_TICK", "stamp_coarse_clock"]

MICROS_TICK = 4e-6  # s, the resolution of micros() on a 16 MHz board
_PER_SECOND = {"ms": 1e3, "us": 1e6}
_SCHEDULES = ("voltage", "load_torque")  # a trace's [[time, value], ...] tables


def _stamps(t: np.ndarray) -> tuple[str, np.ndarray]:
    """The unit and the integer stamps of sample times ``t`` (s) on the logger's clock."""
    steps = np.diff(t)
    steady = steps.size > 0 and float(np.max(steps)) < 1.5 * float(np.min(steps))
    if steady and float(np.median(steps)) >= 2e-3:
        return "ms", np.rint(t * 1e3).astype(np.int64)
    tick = round(MICROS_TICK * 1e6)
    return "us", tick * np.rint(t * 1e6 / tick).astype(np.int64)


def stamp_coarse_clock(files: dict[str, str], name: str) -> dict[str, str]:
    """``files`` with trace ``name``'s time column (``t``, in s) written as the logger's
    integer stamps, and its ``units.time`` and schedules in ``session.toml`` to match."""
    rows = files[f"{name}.csv"].rstrip("\n").split("\n")
    k = rows[0].split(",").index("t")
    cells = [r.split(",") for r in rows[1:]]
    unit, stamps = _stamps(np.array([float(c[k]) for c in cells]))
    for c, s in zip(cells, stamps, strict=True):
        c[k] = str(int(s))
    out = dict(files)
    out[f"{name}.csv"] = "\n".join([rows[0], *(",".join(c) for c in cells)]) + "\n"
    lines = files["session.toml"].split("\n")
    for j in trace_block(lines, name):
        if lines[j].startswith('units = { time = "s"'):
            lines[j] = lines[j].replace('time = "s"', f'time = "{unit}"', 1)
        key = lines[j].split(" = ", 1)[0]
        if key in _SCHEDULES:
            scale = _PER_SECOND[unit]
            table = tomllib.loads(lines[j])[key]
            lines[j] = f"{key} = {pairs([(a * scale, b) for a, b in table])}"
    out["session.toml"] = "\n".join(lines)
    return out
