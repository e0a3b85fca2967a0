"""Read a session directory (``session.toml`` and its CSV files) into a :class:`Session`.

Everything is validated and converted to SI here, once; a problem raises a
:class:`~pmdc_bayes.SessionError` whose one-line message names the file, the key path
or line, what is wrong and how to fix it.  The format is described in
``docs/session-format.md``.
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from pathlib import Path

import numpy as np

from .._errors import SessionError
from ._csv import read_columns
from ._toml import Table as _Table
from ._toml import describe as _describe
from .session import (
    COAST_DOWN,
    FRICTION_MODELS,
    LA_ASSUMED,
    LA_PRIOR_LOG_SD,
    LA_TIME_CONSTANT,
    NUISANCES,
    Measurement,
    OperatingPoint,
    Schedule,
    Session,
    SteadyTable,
    StepReading,
    Trace,
)
from .units import to_si

__all__ = ["load_session"]

_TOP_KEYS = ("motor", "bench", "closed_form", "model", "operating_point", "steady_table",
             "step_reading", "trace")
_BENCH_KINDS = {"Ra": "resistance", "La": "inductance", "J": "inertia", "K": "motor_constant",
                "B": "damping"}
_OP_KINDS = {"supply_voltage": "voltage", "duty": "duty", "current": "current",
             "speed": "speed", "load_torque": "torque"}
_TABLE_KINDS = {"voltage": "voltage", "speed": "speed", "current": "current",
                "load_torque": "torque"}
_STEP_KINDS = {"voltage": "voltage", "final_speed": "speed", "tau": "time",
               "initial_speed": "speed"}
_TRACE_KINDS = {"time": "time", "speed": "speed", "current": "current", "voltage": "voltage",
                "load_torque": "torque"}
_TRUTH_KEYS = ("Ra", "La", "K", "B", "J", "Tc")



def _locate(path) -> Path:
    p = Path(path)
    if p.is_dir():
        toml = p / "session.toml"
        if not toml.is_file():
            raise SessionError(toml, "file not found; a session directory must hold "
                               "session.toml (see docs/session-format.md)")
        return toml.resolve()
    if p.is_file():
        return p.resolve()
    raise SessionError(p, "no such session directory or file; pass a directory holding "
                       "session.toml, or 'paper' for the bundled paper session")


def _read_toml(toml: Path) -> dict:
    try:
        with toml.open("rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        m = re.match(r"(.*) \(at line (\d+), column (\d+)\)$", str(exc))
        what, where = (m.group(1), f"line {m.group(2)}, column {m.group(3)}") if m else (
            str(exc), None)
        raise SessionError(toml, f"TOML syntax error: {what}; fix the syntax there (strings "
                           "need quotes, keys need '=')", where=where) from None
    except UnicodeDecodeError:
        raise SessionError(toml, "not UTF-8 text; save the file as UTF-8") from None


def _measurement(t: _Table, kind: str) -> Measurement:
    t.check_keys(("value", "unit", "sd", "source"))
    unit = t.unit("unit", kind)
    value = t.number("value", kind, unit, positive=True)
    sd = t.number("sd", kind, unit, positive=True)
    return Measurement(value, sd, unit, t.string("source", default=""))


def _operating_point(t: _Table) -> OperatingPoint:
    t.check_keys(("name", *_OP_KINDS, "units"))
    name, u = t.string("name"), t.units(_OP_KINDS)
    duty = t.number("duty", "duty", u["duty"])
    if not 0.0 < duty <= 1.0:
        t.fail("duty", f"duty {t.data['duty']} is outside (0, 1]; give the duty cycle as a "
               "fraction, e.g. 0.7 (or set units.duty = \"%\")")
    return OperatingPoint(
        name=name,
        supply_voltage=t.number("supply_voltage", "voltage", u["supply_voltage"], positive=True),
        duty=duty,
        current=t.number("current", "current", u["current"], default=None),
        speed=t.number("speed", "speed", u["speed"], positive=True),
        load_torque=t.number("load_torque", "torque", u["load_torque"], default=0.0),
    )


def _steady_table(t: _Table, root: Path) -> SteadyTable:
    t.check_keys(("name", "file", "columns", "units"))
    name, u = t.string("name"), t.units(_TABLE_KINDS)
    cols = t.columns(_TABLE_KINDS, ("voltage", "speed"))
    path = root / t.string("file")
    raw, _ = read_columns(path, cols, asked_by=f"session.toml {t.path('columns')}")
    if raw["voltage"].size == 0:
        raise SessionError(path, "no data rows; add one row per steady operating point")
    si = {role: to_si(raw[role], _TABLE_KINDS[role], u[role]) for role in raw}
    load = si.get("load_torque", np.zeros_like(si["speed"]))
    return SteadyTable(name, path, si["voltage"], si["speed"], si.get("current"), load)


def _step_reading(t: _Table) -> StepReading:
    t.check_keys(("name", *_STEP_KINDS, "units"))
    name, u = t.string("name"), t.units(_STEP_KINDS)
    return StepReading(
        name=name,
        voltage=t.number("voltage", "voltage", u["voltage"]),
        final_speed=t.number("final_speed", "speed", u["final_speed"]),
        tau=t.number("tau", "time", u["tau"], positive=True),
        initial_speed=t.number("initial_speed", "speed", u["initial_speed"], default=0.0),
    )


def _schedule(t: _Table, key: str, u: dict, kind: str, t_raw: np.ndarray) -> Schedule:
    """A ``[[time, value], ...]`` schedule in the trace's units, checked against the samples."""
    pairs = t.data[key]
    example = f"{key} = [[0.0, 0.0], [1.0, 12.0]]"
    if not isinstance(pairs, list) or not pairs:
        t.fail(key, f"expected a list of [time, value] pairs, got {_describe(pairs)}; "
               f"write e.g. {example}")
    times, values = [], []
    for i, pair in enumerate(pairs):
        if not isinstance(pair, list) or len(pair) != 2:
            t.fail(f"{key}[{i}]", f"expected a [time, value] pair, got {_describe(pair)}; "
                   f"write e.g. {example}")
        pt = _Table(t.file, {"time": pair[0], "value": pair[1]}, t.path(f"{key}[{i}]"))
        times.append(pt.number("time"))
        values.append(pt.number("value"))
        if i and times[i] <= times[i - 1]:
            t.fail(f"{key}[{i}]", f"schedule time {times[i]:g} does not follow "
                   f"{times[i - 1]:g}; list the pairs with strictly increasing times")
    tu = u["time"]
    if times[0] > t_raw[-1]:
        t.fail(key, f"trace and schedule don't overlap: the schedule starts at {times[0]:g} "
               f"{tu}, after the last sample at {t_raw[-1]:g} {tu}; check the times (both "
               "are in the trace's time unit)")
    if times[0] > t_raw[0]:
        t.fail(key, f"the schedule starts at {times[0]:g} {tu}, after the first sample at "
               f"{t_raw[0]:g} {tu}; add a pair at the first sample time, "
               f"[{t_raw[0]:g}, <value>]")
    return Schedule(to_si(np.array(times), "time", tu), to_si(np.array(values), kind, u[key]))


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


def _read_trace_file(t: _Table, root: Path, cols: dict, u: dict):
    """A trace's CSV file: its path, the raw columns, the raw and SI time axes (at
    least 3 samples, strictly increasing)."""
    path = root / t.string("file")
    raw, lines = read_columns(path, cols, asked_by=f"session.toml {t.path('columns')}")
    t_raw = raw["time"]
    if t_raw.size < 3:
        raise SessionError(path, f"only {t_raw.size} samples; a trace needs at least 3 "
                           "samples (log a longer record)")
    bad = np.nonzero(np.diff(t_raw) <= 0)[0]
    if bad.size:
        k = int(bad[0]) + 1
        raise SessionError(path, f"time column {cols['time']!r} is not strictly increasing: "
                           f"{t_raw[k]:g} follows {t_raw[k - 1]:g} (line {lines[k - 1]}); sort "
                           "the rows by time and remove duplicate samples",
                           where=f"line {lines[k]}")
    time = to_si(t_raw, "time", u["time"])
    return path, raw, t_raw, time


def _trace(t: _Table, root: Path) -> Trace:
    t.check_keys(("name", "kind", "file", "columns", "units", "voltage", "load_torque",
                  "initial"))
    name, kind, u = t.string("name"), t.string("kind"), t.units(_TRACE_KINDS)
    cols = t.columns(_TRACE_KINDS, ("time", "speed"))
    for inp in ("voltage", "load_torque"):
        if inp in cols and inp in t.data:
            t.fail(inp, f"{inp} is given both as a column (columns.{inp}) and as a schedule; "
                   "remove one of them")
    if "voltage" not in cols and "voltage" not in t.data:
        t.fail("voltage", "no armature voltage given; add a column (columns.voltage = "
               "\"<header name>\") or a schedule (voltage = [[t0, V0], [t1, V1], ...])")
    path, raw, t_raw, time = _read_trace_file(t, root, cols, u)
    si = {role: to_si(raw[role], _TRACE_KINDS[role], u[role]) for role in raw}
    inputs = {}
    for inp in ("voltage", "load_torque"):
        if inp in si:
            inputs[inp] = Schedule(time, si[inp])
        elif inp in t.data:
            inputs[inp] = _schedule(t, inp, u, _TRACE_KINDS[inp], t_raw)
        else:
            inputs[inp] = Schedule(time[:1].copy(), np.zeros(1))
    return Trace(name=name, kind=kind, file=path, time=time, speed=si["speed"],
                 current=si.get("current"), voltage=inputs["voltage"],
                 load_torque=inputs["load_torque"], voltage_logged="voltage" in si,
                 load_logged="load_torque" in si, initial=_initial(t, u))


def _coast_down(t: _Table, root: Path) -> Trace:
    """A trace of kind ``"coast-down"``: time and speed only, the armature open."""
    t.check_keys(("name", "kind", "file", "columns", "units"))
    name = t.string("name")
    kinds = {"time": "time", "speed": "speed"}
    u = t.units(kinds)
    cols = t.columns(kinds, ("time", "speed"))
    path, raw, _, time = _read_trace_file(t, root, cols, u)
    none = Schedule(time[:1].copy(), np.zeros(1))
    return Trace(name=name, kind=COAST_DOWN, file=path, time=time,
                 speed=to_si(raw["speed"], "speed", u["speed"]), current=None, voltage=none,
                 load_torque=none)


def _traces(top: _Table, root: Path, toml: Path) -> tuple[tuple, tuple]:
    """The driven traces and the coast-downs, names unique across both."""
    driven, coast = [], []
    for t in top.tables("trace"):
        if t.data.get("kind") == COAST_DOWN:
            coast.append(_coast_down(t, root))
        else:
            driven.append(_trace(t, root))
    _unique(driven + coast, "trace", toml)
    return tuple(driven), tuple(coast)


def _truth(path: Path) -> dict | None:
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise SessionError(path, f"not valid JSON ({exc}); fix or delete the file") from None
    if not isinstance(data, dict):
        raise SessionError(path, "expected a JSON object of SI parameter values; fix or "
                           "delete the file")
    truth = {}
    for key in _TRUTH_KEYS:
        if key in data:
            v = data[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise SessionError(path, f"{key} is {v!r}, not a finite number; write the "
                                   "SI value", where=key)
            truth[key] = float(v)
    return truth


def _unique(items, what: str, file: Path):
    seen = set()
    for item in items:
        if item.name in seen:
            raise SessionError(file, f"two [[{what}]] entries are named {item.name!r}; give "
                               "each a different name", where=f"{what}[{item.name!r}]")
        seen.add(item.name)
    return tuple(items)


def load_session(path) -> Session:
    """Read and validate a session, converting every number to SI.

    Parameters
    ----------
    path : str or Path
        A session directory holding ``session.toml``, or the ``session.toml`` itself.

    Returns
    -------
    Session
        ``name`` is the directory name; ``truth`` holds ``truth.json`` beside
        ``session.toml`` when present.

    Raises
    ------
    SessionError
        With a one-line message naming the file, the key or line, the problem and the fix.
    """
    toml = _locate(path)
    root = toml.parent
    top = _Table(toml, _read_toml(toml), "")
    top.check_keys(_TOP_KEYS)
    motor = top.table("motor")
    motor.check_keys(("name", "friction"))
    friction = motor.string("friction", default="viscous")
    if friction not in FRICTION_MODELS:
        motor.fail("friction", f"unknown friction model {friction!r}; use one of: "
                   f"{', '.join(FRICTION_MODELS)}")
    bench = top.table("bench")
    bench.check_keys(_BENCH_KINDS)
    measured = {key: _measurement(bench.table(key), kind) for key, kind in _BENCH_KINDS.items()
                if key == "Ra" or key in bench.data}
    if "La" not in measured:  # no LCR meter: a wide prior on the electrical time constant
        ra = measured["Ra"].value
        measured["La"] = Measurement(ra * LA_TIME_CONSTANT, LA_PRIOR_LOG_SD, "H", LA_ASSUMED)
    options = {}
    cf = top.table("closed_form", required=False)
    if cf is not None:
        cf.check_keys(("K_decimals",))
        if "K_decimals" in cf.data:
            d = cf.data["K_decimals"]
            if isinstance(d, bool) or not isinstance(d, int) or d < 0:
                cf.fail("K_decimals", f"expected a whole number >= 0, got {_describe(d)}; "
                        "write e.g. K_decimals = 3")
            options["K_decimals"] = d
    nuisances = ()
    mt = top.table("model", required=False)
    if mt is not None:
        mt.check_keys(NUISANCES)
        for key in NUISANCES:
            flag = mt.data.get(key, False)
            if not isinstance(flag, bool):
                mt.fail(key, f"expected true or false, got {_describe(flag)}; write e.g. "
                        f"{key} = true")
        nuisances = tuple(k for k in NUISANCES if mt.data.get(k, False))
    traces, coast_downs = _traces(top, root, toml)
    return Session(
        name=root.name,
        nuisances=nuisances,
        bench={k: m for k, m in measured.items() if k not in ("Ra", "La")},
        root=root,
        motor=motor.string("name"),
        Ra=measured["Ra"],
        La=measured["La"],
        friction=friction,
        operating_points=_unique([_operating_point(t) for t in top.tables("operating_point")],
                                 "operating_point", toml),
        steady_tables=_unique([_steady_table(t, root) for t in top.tables("steady_table")],
                              "steady_table", toml),
        step_readings=_unique([_step_reading(t) for t in top.tables("step_reading")],
                              "step_reading", toml),
        traces=traces,
        coast_downs=coast_downs,
        closed_form_options=options,
        truth=_truth(root / "truth.json"),
    )
