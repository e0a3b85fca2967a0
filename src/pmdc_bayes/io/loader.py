"""Read a session directory (``session.toml`` and its CSV files) into a :class:`Session`.

Everything is validated and converted to SI here, once; a problem raises a
:class:`~pmdc_bayes.SessionError` whose one-line message names the file, the key path
or line, what is wrong and how to fix it.  The format is described in
``docs/session-format.md``.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import numpy as np

from .._errors import SessionError
from . import gear
from ._csv import read_columns
from ._model_table import read_model_table
from ._traces import read_traces
from ._units_row import check_column_units, check_unstated
from .bundled import BUNDLED, session_path
from .session import (
    FRICTION_MODELS,
    LA_ASSUMED,
    LA_PRIOR_LOG_SD,
    LA_TIME_CONSTANT,
    Measurement,
    OperatingPoint,
    Session,
    SteadyTable,
    StepReading,
)
from .text import read_text
from .toml_tables import Table as _Table
from .toml_tables import describe as _describe
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
_TRUTH_KEYS = ("Ra", "La", "K", "B", "J", "Tc")



def _locate(path) -> Path:
    p = Path(path)
    if p.is_dir():
        toml = p / "session.toml"
        if not (toml.is_file() or toml.is_symlink()):
            raise SessionError(toml, "file not found; a session directory must hold "
                               "session.toml (see docs/session-format.md)")
        return toml if toml.is_symlink() else toml.resolve()
    if p.is_file() and p.suffix.lower() != ".toml":
        raise SessionError(p, "a file, not a session; pass the session directory (the folder "
                           "holding session.toml)")
    if p.is_file():
        return p.resolve()
    raise SessionError(p, "no such session directory or file; pass a directory holding "
                       "session.toml, or the name of a bundled session ("
                       + ", ".join(BUNDLED) + ")")


def _read_toml(toml: Path) -> dict:
    text = read_text(toml, "session.toml").lstrip("\ufeff")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = re.match(r"(.*) \(at line (\d+), column (\d+)\)$", str(exc))
        what, where = (m.group(1), f"line {m.group(2)}, column {m.group(3)}") if m else (
            str(exc), None)
        raise SessionError(toml, f"TOML syntax error: {what}; fix the syntax there (strings "
                           "need quotes, keys need '=')", where=where) from None


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
    read = read_columns(path, cols, asked_by=f"session.toml {t.path('columns')}")
    check_column_units(path, cols, read, u, _TABLE_KINDS, t.where)
    raw = read.values
    if raw["voltage"].size == 0:
        raise SessionError(path, "no data rows; add one row per steady operating point")
    check_unstated(path, cols, raw, t.data.get("units"), read.units, t.where, duty=False)
    si = {role: to_si(raw[role], _TABLE_KINDS[role], u[role]) for role in raw}
    load = si.get("load_torque", np.zeros_like(si["speed"]))
    return SteadyTable(name, path, si["voltage"], si["speed"], si.get("current"), load)


def _step_reading(t: _Table) -> StepReading:
    t.check_keys(("name", *_STEP_KINDS, "units"))
    name, u = t.string("name"), t.units(_STEP_KINDS)
    reading = StepReading(
        name=name,
        voltage=t.number("voltage", "voltage", u["voltage"]),
        final_speed=t.number("final_speed", "speed", u["final_speed"]),
        tau=t.number("tau", "time", u["tau"], positive=True),
        initial_speed=t.number("initial_speed", "speed", u["initial_speed"], default=0.0),
    )
    if reading.final_speed == reading.initial_speed:
        t.fail("final_speed", "equals the initial speed: there was no step to read a time "
               "constant from; check the values or remove the reading")
    if reading.voltage == 0 and reading.final_speed != 0:
        t.fail("voltage", "is 0 but the speed settles away from 0; give the voltage the "
               "step went to")
    return reading


def _truth(path: Path) -> dict | None:
    if not path.is_file():
        return None
    text = read_text(path, "truth.json")
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise SessionError(path, f"not valid JSON ({exc}); fix or delete the file") from None
    if not isinstance(data, dict):
        raise SessionError(path, "expected a JSON object of SI parameter values; fix or "
                           "delete the file")
    truth = {}
    for key in _TRUTH_KEYS:
        if key in data:
            v = data[key]
            if isinstance(v, bool) or not isinstance(v, int | float) or not abs(v) < 1e300:
                raise SessionError(path, f"{key} is {str(v)[:20]!r}, not a finite number; "
                                   "write the SI value", where=key)
            truth[key] = float(v)
    for key, v in data.items():  # the rig's truths (Vdrop, dead_time, ...): numbers only
        if key not in truth and isinstance(v, int | float) and not isinstance(v, bool) \
                and abs(v) < 1e300:
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
        A session directory holding ``session.toml``, or the ``session.toml`` itself,
        or the name of a bundled session (``"demo"``, ``"paper"``, ``"bench"``) when
        nothing of that name here holds a session.toml (``./demo`` names a local one).

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
    toml = _locate(session_path(path))
    root = toml.parent
    top = _Table(toml, _read_toml(toml), "")
    top.check_keys(_TOP_KEYS)
    motor = top.table("motor")
    motor.check_keys(("name", "friction", "gear_ratio"))
    friction = motor.string("friction", default="viscous")
    ratio = motor.number("gear_ratio", default=1.0, positive=True)
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
    mt = top.table("model", required=False)
    traces, coast_downs = read_traces(top, root)
    _unique(traces + coast_downs, "trace", toml)
    traces = tuple(gear.motor_shaft_trace(t, ratio) for t in traces)
    coast_downs = tuple(gear.motor_shaft_trace(t, ratio) for t in coast_downs)
    model = read_model_table(mt, traces, coast_downs)
    session = Session(
        name=root.name,
        nuisances=model.nuisances,
        loaded_traces=model.loaded_traces,
        load_kinds=model.load_kinds,
        shared_dead_time=model.shared_dead_time,
        coloured_traces=model.coloured_traces,
        current_limit_setting=model.current_limit_setting,
        bench={k: m for k, m in measured.items() if k not in ("Ra", "La")},
        root=root,
        motor=motor.string("name"),
        Ra=measured["Ra"],
        La=measured["La"],
        friction=friction,
        operating_points=_unique([gear.motor_shaft_point(_operating_point(t), ratio)
                                  for t in top.tables("operating_point")],
                                 "operating_point", toml),
        steady_tables=_unique([gear.motor_shaft_table(_steady_table(t, root), ratio)
                               for t in top.tables("steady_table")], "steady_table", toml),
        step_readings=_unique([gear.motor_shaft_reading(_step_reading(t), ratio)
                               for t in top.tables("step_reading")], "step_reading", toml),
        gear_ratio=ratio,
        traces=traces,
        coast_downs=coast_downs,
        closed_form_options=options,
        truth=_truth(root / "truth.json"),
    )
    inert = session.inert_nuisance()
    if inert is not None:
        mt.fail(inert[0], f"{inert[1]}: there is nothing for it to fit; remove it")
    return session
