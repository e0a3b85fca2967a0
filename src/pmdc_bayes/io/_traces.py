"""The ``[[trace]]`` entries of ``session.toml``: a trace's CSV, its input schedules
and initial state, read, checked and converted to SI (part of the session loader)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._errors import SessionError
from . import _sensors as sensors
from ._csv import read_columns
from ._inputs import (
    DUTY_UNITS,
    duty_scale,
    duty_to_volts,
    schedule,
    signed_current,
    signed_speed,
    signed_voltage,
)
from ._missing import MISSABLE, without_missing, without_repeats
from ._steady_clock import steady_times
from ._step_timing import check_step_timing
from ._time_order import check_date_serial, check_increasing, check_slow_time
from ._units_row import check_column_units, check_unstated, unit_stated
from .drag import check_curve_reach, read_drag
from .held_levels import held_levels
from .position import (
    angle_si,
    check_motion_columns,
    differenced_angle,
    direction_signs,
    edge_angles,
    edges_flag,
    speed_estimate,
    unwrap_position,
    unwrap_time,
)
from .run_down import check_run_down_start
from .session import COAST_DOWN, Schedule, Trace
from .toml_tables import Table as _Table
from .toml_tables import describe as _describe
from .units import to_si, unit_factor

__all__ = ["read_traces"]

_TRACE_KINDS = {"time": "time", "speed": "speed", "current": "current", "voltage": "voltage",
                "load_torque": "torque", "position": "angle"}
_UNIT_KINDS = dict(_TRACE_KINDS, supply_voltage="voltage", sample_rate="frequency",
                   **sensors.UNIT_KINDS)  # the keys of a trace's units
_COLUMNS = dict(_TRACE_KINDS, direction="")  # the roles a column may have


def _initial(t: _Table, u: dict):
    value = t.data.get("initial", "rest")
    if isinstance(value, str) and value in ("rest", "steady"):
        return value
    if isinstance(value, dict):
        sub = _Table(t.file, value, t.path("initial"))
        sub.check_keys(("current", "speed"))
        return (sub.number("current", "current", u["current"]),
                sub.number("speed", "speed", u["speed"]))
    t.fail("initial", f'expected "rest", "steady" or {{ current = ..., speed = ... }}, got '
           f"{_describe(value)}; use one of those")


def _columns(t: _Table, kinds: dict, required=()) -> dict:
    """The trace's columns: a time column, or rows at a stated ``sample_rate``."""
    cols = t.columns(kinds, required)
    if "sample_rate" in t.data and "time" in cols:
        t.fail("sample_rate", "is given with a time column; give one of them (a time column "
               "for samples at their own times, sample_rate for rows at a steady rate)")
    for key in ("time_wrap", "edges"):
        if "sample_rate" in t.data and t.data.get(key, False) is not False:
            t.fail(key, "reads a time column, which a trace at a sample_rate has not; add "
                   "the time column and remove sample_rate, or remove " + key)
    if "sample_rate" not in t.data and "time" not in cols:
        t.fail("columns.time", 'no time column; add columns.time = "<header name>", or '
               "sample_rate = <Hz> when the rows are samples at a steady rate")
    return cols


class _TraceFile(NamedTuple):
    """A trace's CSV file read: its path, the raw columns (role -> values in the file's
    units), the raw and SI time axes, the file lines of the rows left out and the raw
    time of the first row (before any is left out), and each sample's line."""

    path: Path
    raw: dict
    t_raw: np.ndarray
    time: np.ndarray
    left_out: tuple
    start: float
    lines: list


def _read_trace_file(t: _Table, root: Path, cols: dict, u: dict, *,
                     edges: bool = False) -> _TraceFile:
    """A trace's CSV file (at least 3 samples, strictly increasing in time; rows left
    out for a missing reading); its time in s, a coarse clock's stamps of a steady rate
    read at the rate's times (:func:`.steady_times`; an encoder's edges as stamped)."""
    path = root / t.string("file")
    second = unit_factor("time", u["time"])
    read = read_columns(path, cols, asked_by=f"session.toml {t.path('columns')}",
                        stamps=("time", second), missing=MISSABLE)
    check_column_units(path, cols, read, u, _TRACE_KINDS, t.where)
    raw, lines = read.values, read.lines
    if "time" in cols:
        t_raw = unwrap_time(t, path, raw["time"])
    else:  # rows at a stated rate, in the trace's unit of time from the first row
        rate = t.number("sample_rate", "frequency", u["sample_rate"], positive=True)
        t_raw = np.arange(len(lines)) / rate / second
    start = float(t_raw[0]) if t_raw.size else 0.0  # before any row is left out
    twice = ()
    if "time" in cols:
        raw, t_raw, lines, twice = without_repeats(raw, t_raw, lines)
    raw, t_raw, lines, left_out = without_missing(path, raw, t_raw, lines, cols)
    left_out = tuple(sorted((*left_out, *read.skipped, *twice)))
    if t_raw.size < 3:
        raise SessionError(path, f"only {t_raw.size} samples; a trace needs at least 3 "
                           "samples (log a longer record)")
    check_increasing(path, cols.get("time"), raw, t_raw, lines, t_raw.size + len(left_out),
                     second, wrap_given="time_wrap" in t.data)
    if "time" in cols:
        check_date_serial(path, cols["time"], t_raw, second)
        if read.plain_stamps and not unit_stated("time", t.data.get("units"), cols["time"],
                                                 read.units):
            check_slow_time(path, cols["time"], t_raw, t.where, whole=read.whole_stamps)
    check_unstated(path, cols, raw, t.data.get("units"), read.units, t.where)
    for role in ("speed", "position"):
        y = raw.get(role)
        if y is not None and np.all(y == y[0]):
            raise SessionError(path, f"the {role} column {cols[role]!r} is {y[0]:g} in every "
                               f"row: the motor did not turn, or the column is not the {role}; "
                               "remove the trace or log one in which the motor turns")
    y = raw.get("current")
    if y is not None and np.isfinite(y).sum() > 2 and np.ptp(y[np.isfinite(y)]) == 0:
        c = y[np.isfinite(y)][0]
        raise SessionError(path, f"the current column {cols['current']!r} is {c:g} in every "
                           "row while the motor turns: a dead or unplugged channel, a sensor "
                           "too coarse to see the current, or a setpoint rather than a "
                           "reading; leave current out of columns (the speed alone then "
                           "carries the fit) or log the current itself")
    clock = t_raw
    if "time" in cols and not edges:
        rows = np.searchsorted(np.sort(np.union1d(lines, left_out)), lines)  # data rows
        clock = steady_times(t_raw, rows)
    return _TraceFile(path, raw, t_raw, to_si(clock, "time", u["time"]), left_out, start, lines)


def _motion(t: _Table, path: Path, raw: dict, u: dict, time: np.ndarray, edges: bool,
            inputs: dict, initial, left_out: tuple) -> dict:
    """The trace's time, speed (a magnitude signed: :func:`._inputs.signed_speed`) and
    angle (SI), the angle of one count.  An edge trace at rest first gets an unread
    sample at its voltage's start; a speed differenced from encoder counts (no position)
    is the counted angle, which rows ``left_out`` between first and last break."""
    if not edges:
        out = {"time": time, "position": None, "encoder_step": 0.0, "differenced": False}
        if "position" in raw:
            counts = unwrap_position(t, path, raw["position"], u["position"])
            out["position"], out["encoder_step"] = angle_si(t, counts, u["position"])
        out["speed"] = raw.get("speed")
        if out["speed"] is not None:
            out["speed"] = signed_speed(sensors.speed_si(t, out["speed"], u), time, inputs)
            if "counts_per_rev" in t.data and "position" not in raw:
                out["position"], out["encoder_step"] = differenced_angle(
                    t, time, out["speed"], left_out, (raw.get("time"), u["time"]))
                out["speed"], out["differenced"] = speed_estimate(time, out["position"]), True
        else:
            out["speed"] = speed_estimate(time, out["position"])
        return out
    angle, q = edge_angles(t, time.size, raw.get("direction"))
    if initial == "rest":
        if not inputs["voltage"].times[0] < time[0]:
            t.fail("voltage", "an encoder-edge trace starting at rest starts at its voltage "
                   "schedule's first time, which must come before the first edge; begin the "
                   "schedule at the time the motor was still at rest")
        moves = inputs["voltage"].change_times()
        span = float(time[-1] - time[0])
        if moves.size and float(time[0] - moves[0]) > 10.0 * max(span, 1e-12):
            t.fail("voltage", f"the voltage first changes {float(time[0] - moves[0]):.6g} s "
                   f"before the first edge, yet the edges span only {span:.3g} s: the "
                   "schedule is not on the time column's clock; give its times in the same "
                   "unit and from the same origin as the edges (a wrapping timer's too)")
        time = np.concatenate([inputs["voltage"].times[:1], time])
        angle = np.concatenate([[np.nan], angle])
    return {"time": time, "position": angle, "encoder_step": q,
            "speed": speed_estimate(time, angle), "differenced": False}


def _trace(t: _Table, root: Path) -> Trace:
    t.check_keys(("name", "kind", "file", "columns", "units", "voltage", "load_torque",
                  "initial", "counts_per_rev", "time_wrap", "edges", "drag",
                  "supply_voltage", "pwm_full_scale", "position_wrap", "sample_rate",
                  *sensors.KEYS))
    # an angle in counts is 2π/counts_per_rev each, known per trace (position.angle_si)
    name, kind = t.string("name"), t.string("kind")
    u = t.units(_UNIT_KINDS, extra={"position": ("counts",), "voltage": (*DUTY_UNITS, "pwm"),
                                    "speed": sensors.VOLTS, "current": sensors.VOLTS})
    duty = duty_scale(t, u)
    cols = _columns(t, _COLUMNS)
    sensors.check_unused(t, u, cols)
    edges = edges_flag(t)
    check_motion_columns(t, cols, edges)
    for inp in ("voltage", "load_torque"):
        if inp in cols and inp in t.data:
            t.fail(inp, f"{inp} is given both as a column (columns.{inp}) and as a schedule; "
                   "remove one of them")
    if "voltage" not in cols and "voltage" not in t.data:
        t.fail("voltage", "no armature voltage given; add a column (columns.voltage = "
               "\"<header name>\") or a schedule (voltage = [[t0, V0], [t1, V1], ...])")
    path, raw, t_raw, time, left_out, start, lines = _read_trace_file(t, root, cols, u,
                                                                      edges=edges)
    if "direction" in raw:  # a decoder's or a driver's direction bit, row by row
        raw["direction"] = direction_signs(path, raw["direction"], lines)
    si = {role: to_si(raw[role], _TRACE_KINDS[role], u[role]) for role in raw
          if role == "load_torque" or (role == "voltage" and duty is None)}
    if "current" in raw:
        si["current"] = sensors.current_si(t, raw["current"], u)
    if "voltage" in raw and duty is not None:
        si["voltage"] = duty_to_volts(t, "columns.voltage", raw["voltage"], duty)
    if "direction" in raw and not edges:  # a driver's PWM and direction pins
        si["voltage"] = signed_voltage(path, si["voltage"], raw["direction"], lines)
    inputs = {}
    for inp in ("voltage", "load_torque"):
        if inp in si:  # a duty is the command itself, exact however it moves
            exact = inp == "voltage" and duty is not None
            inputs[inp] = (Schedule(time, si[inp]) if exact
                           else held_levels(time, si[inp], switching=inp == "voltage"))
        elif inp in t.data:
            inputs[inp] = schedule(t, inp, u, _TRACE_KINDS[inp], t_raw, start,
                                    duty if inp == "voltage" else None)
        else:
            inputs[inp] = Schedule(time[:1].copy(), np.zeros(1))
    if "direction" in raw and not edges and "current" in si:  # ... and its current sense
        si["current"] = signed_current(si["current"], raw["direction"], inputs["voltage"].at(time))
    initial = _initial(t, sensors.physical(u))
    drag = read_drag(t, sensors.physical(u))
    inside = tuple(n for n in left_out if lines[0] < n < lines[-1])
    m = _motion(t, path, raw, u, time, edges, inputs, initial, inside)
    check_curve_reach(t, drag, m["speed"], sensors.physical(u))
    if initial == "rest" and "voltage" not in cols:  # a schedule, in the trace's unit
        check_step_timing(t, m["time"], m["speed"], inputs["voltage"], inputs["load_torque"],
                          u["time"])
    return Trace(name=name, kind=kind, file=path, time=m["time"], speed=m["speed"],
                 current=si.get("current"), voltage=inputs["voltage"],
                 load_torque=inputs["load_torque"], voltage_logged="voltage" in si,
                 load_logged="load_torque" in si, initial=initial,
                 position=m["position"], speed_logged="speed" in raw and not m["differenced"],
                 encoder_step=m["encoder_step"], drag=drag, rows_left_out=left_out,
                 time_unit=u["time"])


def _coast_down(t: _Table, root: Path) -> Trace:
    """A trace of kind ``"coast-down"``: time and speed only, the armature open."""
    t.check_keys(("name", "kind", "file", "columns", "units", "tacho_constant",
                  "sample_rate", "opened"))
    name = t.string("name")
    kinds = {"time": "time", "speed": "speed"}
    u = t.units(dict(kinds, tacho_constant="motor_constant", sample_rate="frequency"),
                extra={"speed": sensors.VOLTS})
    cols = _columns(t, kinds, ("speed",))
    sensors.check_unused(t, u, cols)
    f = _read_trace_file(t, root, cols, u)
    time, speed, left_out = f.time, sensors.speed_si(t, f.raw["speed"], u), f.left_out
    per_unit = unit_factor("time", u["time"])
    if "opened" in t.data:  # in the trace's unit of time, as its time column
        opened = t.number("opened") * per_unit
        step = float(np.median(np.diff(time)))
        if not time[0] - step <= opened <= time[-3]:
            t.fail("opened", f"{t.data['opened']!r} {u['time']} lies outside the record "
                   f"({time[0] / per_unit:.6g} to {time[-3] / per_unit:.6g} {u['time']}, "
                   "3 samples before its end); give the time the armature was opened, in "
                   "the trace's time unit")
        kept = time >= opened - 1e-9 * step
        first_line = f.lines[int(np.argmax(kept))]
        time, speed = time[kept], speed[kept]
        left_out = tuple(n for n in left_out if n > first_line)
    else:
        check_run_down_start(t, time, speed, u["time"], per_unit)
    none = Schedule(time[:1].copy(), np.zeros(1))
    return Trace(name=name, kind=COAST_DOWN, file=f.path, time=time, speed=speed,
                 current=None, voltage=none, load_torque=none, rows_left_out=left_out,
                 time_unit=u["time"])


def read_traces(top: _Table, root: Path) -> tuple[tuple, tuple]:
    """The ``[[trace]]`` entries of ``session.toml``: the driven traces and the
    coast-downs."""
    driven, coast = [], []
    for t in top.tables("trace"):
        if t.data.get("kind") == COAST_DOWN:
            coast.append(_coast_down(t, root))
        else:
            driven.append(_trace(t, root))
    return tuple(driven), tuple(coast)
