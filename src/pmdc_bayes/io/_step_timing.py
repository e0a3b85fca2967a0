"""A trace whose speed starts to move a thousand times later than its voltage schedule
steps: the schedule written in seconds beside a time column in milliseconds (or a
time column in milliseconds read as seconds), which a fit would take for a dead time
of nearly the whole wait."""

from __future__ import annotations

import numpy as np

from .robust import departure, difference_sd
from .session import Schedule
from .toml_tables import Table as _Table
from .units import unit_factor

__all__ = ["check_step_timing"]

RATIO = (950.0, 1300.0)  # the motor's start over the schedule's step: a unit's 1000
CLEAR = 10.0  # a departure this many noise sds from rest (and 5 % of the swing) is clear


def _start(time: np.ndarray, speed: np.ndarray) -> float | None:
    """When ``speed`` leaves its first level: :data:`~pmdc_bayes.io.robust.CONSECUTIVE`
    samples in a row beyond :data:`CLEAR` sds of its reading noise and 5 % of its
    largest swing."""
    w = np.asarray(speed, float)
    ok = np.isfinite(w)
    time, w = np.asarray(time, float)[ok], w[ok]
    if w.size < 10:
        return None
    k = departure(w, difference_sd(w), CLEAR)
    return None if k is None else float(time[k])


def check_step_timing(t: _Table, time: np.ndarray, speed, voltage: Schedule,
                      load: Schedule, unit: str) -> None:
    """Refuse a trace started at rest under its voltage schedule when its speed starts
    to move a thousand times (:data:`RATIO`) after the schedule's first clear step (a
    quarter of its largest change or more), well after it and with no input changing
    in between: the schedule and the time column are in different units (``time``,
    ``voltage`` and ``load`` in SI, ``unit`` the trace's unit of time, for the
    message)."""
    changes = voltage.change_times()
    if speed is None or changes.size == 0:
        return
    sizes = np.abs(np.diff(np.asarray(voltage.values, float)))
    sizes = sizes[sizes > 0]
    step = float(changes[np.argmax(sizes >= 0.25 * sizes.max())])
    moved = _start(time, speed)
    if step <= 0 or moved is None or not RATIO[0] <= moved / step <= RATIO[1]:
        return
    between = np.concatenate([changes, load.change_times()])
    if moved - step < 10 * float(np.median(np.diff(time))) or np.any(
            (between > step) & (between < moved)):
        return
    per = unit_factor("time", unit)
    at, first = moved / per, step / per
    fix = (f"is the time column in ms? Then set units.time = \"ms\" and write the "
           f"schedule's times in ms ({first * 1000:g} for {first:g} s)" if unit == "s" else
           f"is the schedule written in seconds? Its times are in the trace's unit of time "
           f"({unit}, units.time); write {first * 1000:g} for {first:g} s")
    t.fail("voltage", f"the speed starts to move at {at:.4g} {unit}, a thousand times "
           f"the time the schedule's voltage first changes ({first:g} {unit}): {fix}")
