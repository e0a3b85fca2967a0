"""A session whose speed turns against its voltage (its leads or a sensor wired the other
way round), found from its steady levels, or whose current swings against its voltage's
changes (a current sensor wired the other way round): what
:func:`.contradictions.refuse_contradictions` refuses."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from ...io.robust import resolution
from ...paper.changes import AT_REST, responses
from .levels import unloaded_levels

__all__ = ["Reversal", "reversed_speed", "reversed_current", "CLEAR_SWING"]


class Reversal(NamedTuple):
    """Where a session's readings contradict its inputs (a sensor wired the other way
    round, a voltage late against the motor): ``file`` and ``where`` name the place to
    mend (``where`` None for a whole file), ``why`` says so and how."""

    file: Path
    where: str | None
    why: str


def reversed_speed(session) -> Reversal | None:
    """Where the speed turns against the voltage at every held, unloaded level that
    moves the motor (above :data:`AT_REST` of the session's largest level): every speed
    (the motor's leads, or every sensor, wired against the voltage's sign), one trace's
    (its sensor reversed) or the steady readings' (their speeds written with the other
    sign), where the rest of the session turns with its voltage.  None when the speeds
    follow their voltages, or too few levels move to tell."""
    rows, names = unloaded_levels(session, held=True)
    if rows.shape[0] == 0:
        return None
    v, w = rows[:, 0], rows[:, 1]
    moving = (np.abs(w) > AT_REST * np.max(np.abs(w))) & (v != 0)
    against = moving & (np.sign(w) == -np.sign(v))
    groups = {}
    for k, name in enumerate(names):
        if moving[k]:
            groups.setdefault(name, []).append(bool(against[k]))
    reversed_ = {g for g, flags in groups.items() if all(flags)}
    toml = session.root / "session.toml"
    if not reversed_:
        return None
    if reversed_ == set(groups):
        return Reversal(toml, None, (
            "the speed turns against the voltage at every steady level (a positive "
            "voltage, a negative speed): the motor's leads, or its speed sensor, are wired "
            "the other way round; negate the speeds (or the voltages) and fit again"
            + _magnitude_hint(session.traces)))
    name = next((g for g in names if g in reversed_ and g is not None), None)
    if name is not None:
        tr = next(t for t in session.traces if t.name == name)
        return Reversal(tr.file, None, (
            f"the speed of trace {name!r} turns against its voltage at every level it "
            "holds, where the rest of the session turns with it: its speed sensor is "
            "wired the other way round; negate this file's speed column and fit again"
            + _magnitude_hint([tr])))
    tables = [t for t in session.steady_tables if np.any(t.load_torque == 0)]
    points = [p for p in session.operating_points if p.load_torque == 0]
    one_table = len(tables) == 1 and not points
    return Reversal(tables[0].file if one_table else toml,
                    None if one_table else "steady readings", (
        "the steady readings' speeds turn against their voltages, where the traces turn "
        "with theirs: the steady speeds are written with the other sign; negate "
        f"{'its speed column' if one_table else 'the steady speeds'} and fit again"))


def _magnitude_hint(traces) -> str:
    """Where a trace's logged voltage never goes negative: it may be a magnitude whose
    sign a driver's direction pin gives, logged in a column of its own."""
    if any(tr.voltage_logged and np.all(np.asarray(tr.voltage.values) >= 0)
           for tr in traces):
        return ("; or, where the voltage column is a magnitude (a PWM duty) and a driver's "
                "direction pin gives its sign in another column, name that column "
                "columns.direction")
    return ""


CLEAR_SWING = 10.0  # a current's swing this many of its noise's sds above it is clear


def reversed_current(session) -> Reversal | None:
    """The first trace whose current swings against every change of its inputs that
    moves the current clearly: a step up of the voltage drives the armature's current
    up (``di/dt = ΔV/La`` at the change; a limit, a lag or a dead time delays it, none
    turns it round), and so does a step up of the load torque (its steady current
    ``ΔTL/(K + B·Ra/K)`` higher, where its speed falls as a load's does), so a trace
    whose current falls on every step up reads it through a sensor wired the other way
    round.  None when every trace's current
    follows its inputs, or none swings clearly (by :data:`CLEAR_SWING` times its
    :func:`~pmdc_bayes.io.robust.resolution`: its noise's sd, or a quantised reading's
    step)."""
    for tr in session.traces:
        if tr.current is None or tr.n < 8:
            continue
        current = np.asarray(tr.current, float)
        clear = CLEAR_SWING * resolution(current)
        against = []
        for which in ("voltage", "load_torque"):
            for r in responses(tr, which):
                t, i = tr.time[r.start:r.stop], current[r.start:r.stop]
                before, after = i[t < r.time], i[t >= r.time]
                if after.size < 3 or r.after == r.before or (
                        which == "load_torque" and not _slows(tr, r)):
                    continue
                # from rest, the current at the change: none flows through La yet
                base = np.nanmean(before) if np.isfinite(before).any() else after[0]
                swing = np.nan_to_num(after - base)
                swing = float(swing[np.argmax(np.abs(swing))])
                if abs(swing) > clear:
                    against.append(np.sign(swing) == -np.sign(r.after - r.before))
        if against and all(against):
            return Reversal(tr.file, None, (
                f"the current of trace {tr.name!r} swings against its inputs at every "
                "change (it falls where the voltage or the load steps up): its current "
                "sensor is wired the other way round; negate this file's current column "
                "and fit again"))
    return None


def _slows(tr, r) -> bool:
    """Whether the speed settles lower after a load change ``r`` that raises the load
    (higher after one that lowers it), as a load given with its sign does; a load
    written with the other sign is no evidence about the current's."""
    w = np.asarray(tr.speed[r.start:r.stop], float)
    t = tr.time[r.start:r.stop]
    before, after = w[t < r.time], w[t >= r.time]
    if not (np.isfinite(before).any() and np.isfinite(after).any()):
        return False
    settled = np.nanmean(after[-max(3, after.size // 10):]) - np.nanmean(before)
    return bool(np.sign(settled) == -np.sign(r.after - r.before))
