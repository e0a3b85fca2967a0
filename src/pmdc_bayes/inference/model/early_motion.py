"""A trace started at rest whose motor moves before its voltage is switched on.

No motor at rest turns, or draws current, before its voltage comes on: a dead time, a
driver's or a sensor's lag all come after the switch-on.  Where the speed or the
current of a trace stands clear of its rest reading for the last samples before the
voltage the trace was given switches on, the voltage is late against the motor's own
readings: a supply's read-back logged a sample period or more after the fact, a logger
that writes the command after applying it, a schedule on another clock.  A fit would
read the motion before the switch-on as noise, or the current's fall after it as a
sensor wired the other way round; the session is refused instead, with the time the
readings stand clear before the switch-on: a lower bound on the voltage's delay.
"""

from __future__ import annotations

import numpy as np

from ...io.robust import MAD_SD, resolution
from ...paper.changes import AT_REST
from .reversal import CLEAR_SWING, Reversal

__all__ = ["EARLY_RUN", "moves_early"]

EARLY_RUN = 5  # samples in a row before the switch-on, each clear of the rest reading


def _switch_on(tr) -> tuple[int, float] | None:
    """The index and time of the voltage's first level away from rest (above
    :data:`AT_REST` of its largest), where the trace holds some samples before it."""
    values = np.asarray(tr.voltage.values, dtype=float)
    top = float(np.max(np.abs(values))) if values.size else 0.0
    away = np.nonzero(np.abs(values) > AT_REST * top)[0]
    if top == 0.0 or not away.size or away[0] == 0:
        return None
    return int(away[0]), float(tr.voltage.times[away[0]])


def _lead(tr, y: np.ndarray, on: int, t_on: float) -> float | None:
    """How long before ``t_on`` the reading ``y`` stood clear of its rest reading (the
    median of the quietest third of the samples before the switch-on: a record may
    open on a run-down from a previous run) in every sample, on the side its largest
    swing after the switch-on takes: beyond :data:`~.reversal.CLEAR_SWING` sds of its
    noise (the largest of its sample-to-sample noise, its quantum and its scatter in
    that third, a slow noise's) and beyond what the levels held before the switch-on
    would drive, pro rata to that swing.  None where fewer than :data:`EARLY_RUN`
    samples before the switch-on do so."""
    y = np.asarray(y, dtype=float)
    before = np.nonzero(tr.time < t_on)[0]
    after = y[tr.time >= t_on]
    if before.size < 3 * EARLY_RUN or not np.isfinite(after).any():
        return None
    thirds = [y[k] for k in np.array_split(before, 3) if np.isfinite(y[k]).any()]
    if not thirds:
        return None
    spread = [float(np.nanmedian(np.abs(r - np.nanmedian(r)))) for r in thirds]
    rest = thirds[int(np.argmin(spread))]
    base = float(np.nanmedian(rest))
    swing = after[np.nanargmax(np.abs(after - base))] - base
    values = np.asarray(tr.voltage.values, dtype=float)
    held = float(np.max(np.abs(values[:on]))) / abs(float(values[on]))
    noise = max(resolution(y), MAD_SD * min(spread))
    allowed = CLEAR_SWING * noise + 2.0 * held * abs(float(swing))
    clear = (y[before] - base) * np.sign(swing) > allowed
    if clear.all():  # no rest reading to move from
        return None
    run = int(np.argmin(clear[::-1]))  # the samples clear in a row up to the switch-on
    return t_on - float(tr.time[before[before.size - run]]) if run >= EARLY_RUN else None


def moves_early(session) -> Reversal | None:
    """The first trace started at rest whose speed or current moves (module docstring)
    before its voltage switches on, unless a load changes before then (a load may turn
    a motor at rest) or the voltage comes from a switching driver's samples (whose
    changes are placed only to several samples: :mod:`pmdc_bayes.io.held_levels`)."""
    for tr in session.traces:
        found = _switch_on(tr) if tr.initial == "rest" else None
        if found is None or tr.voltage.switched or np.any(
                (tr.load_torque.change_times() > tr.time[0])
                & (tr.load_torque.change_times() < found[1])):
            continue
        for channel, y in (("speed", tr.speed if tr.speed_logged else None),
                           ("current", tr.current)):
            lead = None if y is None else _lead(tr, y, *found)
            if lead is not None:
                return _refusal(session, tr, channel, lead)
    return None


def _refusal(session, tr, channel: str, lead: float) -> Reversal:
    """The place to mend (the trace's file for a logged voltage, its schedule in
    session.toml for a written one) and why."""
    said = (f"the {channel} of trace {tr.name!r} moves at least {lead:.2g} s before its "
            f"{'logged' if tr.voltage_logged else 'scheduled'} voltage switches on from "
            "rest: the voltage is late against the motor's readings")
    more = "(or more: the readings stand clear of their noise only after the motor starts)"
    if tr.voltage_logged:
        return Reversal(tr.file, None, (
            f"{said} (a supply's read-back, a logger that writes the command after "
            "applying it); log the command itself, or move the voltage's switch-on that "
            f"much earlier {more}, and fit again"))
    return Reversal(session.root / "session.toml", f"trace[{tr.name!r}].voltage", (
        f"{said} (a schedule on another clock, or a switch-on time misread); move the "
        f"schedule's switch-on that much earlier {more}, and fit again"))
