"""Read and check a simulation plan: the true motor, the bench and the experiments.

A plan is a TOML file read by :func:`load_plan` into a plain dict; :func:`check_plan`
validates it once and returns a frozen :class:`Plan` whose numbers are SI (except
the bench uncertainties, kept in the unit the bench value is written in).  Every
problem raises a one-line :class:`~pmdc_bayes.SessionError` naming the plan file,
the key and the fix.  ``data/demo/plan.toml`` is a complete, commented example.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from .._errors import SessionError
from ..io.drag import read_drag
from ..io.session import FRICTION_MODELS
from ..io.text import read_text
from ..io.toml_tables import REQUIRED, Table
from ..io.units import unit_factor
from .rig import check_encoder, check_rig
from .specs import BenchSpec, Plan, PointSpec, TableSpec, TraceSpec

__all__ = ["Plan", "BenchSpec", "PointSpec", "TableSpec", "TraceSpec", "load_plan",
           "check_plan"]

TRUTH_KEYS = ("Ra", "La", "K", "B", "J", "Tc")
TRACE_KINDS = ("step", "load_change", "free-form", "coast-down")
COAST_DOWN = "coast-down"
MAX_SAMPLES = 1_000_000
_BENCH = {"Ra": "resistance", "La": "inductance"}
_SI_DRAG = {"speed": "rad/s", "load_torque": "N*m"}  # a plan's known load is SI
_SAFE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")


def load_plan(path) -> dict:
    """Read a plan TOML file into a dict (checked later by :func:`check_plan`)."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(path, "plan file not found; pass the path of a plan TOML file "
                           "(see data/demo/plan.toml)")
    text = read_text(path, "plan").lstrip("\ufeff")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SessionError(path, f"TOML syntax error: {exc}; fix the syntax there") from None


def _named_tables(t: Table, key: str) -> list[Table]:
    """The array of tables ``[[key]]``, each with a name fit for a file name."""
    out = t.tables(key)
    for item in out:
        name = item.string("name")
        if not _SAFE_NAME.fullmatch(name):
            item.fail("name", f"{name!r} cannot be a file name; use letters, digits, _ . -")
    return out


def _schedule(t: Table, key: str, required: bool):
    """A piecewise-constant schedule ``[[time s, value], ...]`` (None when optional and
    absent)."""
    value = t.value(key, default=REQUIRED if required else None, what="[[time s, value], ...]")
    if value is None:
        return None
    example = f"write e.g. {key} = [[0.0, 0.0], [0.5, 12.0]]"
    if not isinstance(value, list) or not value or not all(
            isinstance(p, list) and len(p) == 2 for p in value):
        t.fail(key, f"expected a list of [time s, value] pairs; {example}")
    pairs = tuple((Table(t.file, {"time": p[0]}, t.path(key)).number("time"),
                   Table(t.file, {"value": p[1]}, t.path(key)).number("value")) for p in value)
    times = [p[0] for p in pairs]
    if times[0] > 0.0 or any(b <= a for a, b in zip(times, times[1:], strict=False)):
        t.fail(key, f"times must start at or before 0 and increase strictly; {example}")
    return pairs


def _coast_down(t: Table) -> TraceSpec:
    """A coast-down: the armature open from the first sample, the rotor running down
    from ``initial = { speed = rad/s }``; a speed channel only."""
    t.check_keys(("name", "kind", "duration", "rate", "initial", "speed_unit", "speed_noise",
                  "speed_quantum", "delay", "speed_noise_correlation"))
    initial = t.value("initial", what="{ speed = rad/s }")
    if not isinstance(initial, dict):
        t.fail("initial", "a coast-down starts from its speed when the armature opens; write "
               "initial = { speed = 200.0 } (rad/s)")
    sub = Table(t.file, initial, t.path("initial"))
    sub.check_keys(("speed",))
    w0 = sub.number("speed")
    speed_unit = t.string("speed_unit", default="rad/s")
    try:
        unit_factor("speed", speed_unit)
    except ValueError as exc:
        t.fail("speed_unit", str(exc))
    return TraceSpec(name=t.string("name"), kind=COAST_DOWN,
                     duration=t.number("duration", positive=True),
                     rate=t.number("rate", positive=True), voltage=((0.0, 0.0),),
                     load_torque=None, initial=(0.0, w0), speed_unit=speed_unit,
                     record_current=False,
                     speed_noise=t.number("speed_noise", default=0.0, low=0.0),
                     speed_quantum=t.number("speed_quantum", default=0.0, low=0.0),
                     current_noise=0.0, current_quantum=0.0,
                     delay=t.number("delay", default=0.0, low=0.0),
                     speed_noise_correlation=_correlation(t))


def _correlation(t: Table) -> float:
    """``speed_noise_correlation``: the speed noise's lag-1 correlation, in [0, 1)."""
    rho = t.number("speed_noise_correlation", default=0.0, low=0.0)
    if not rho < 1.0:
        t.fail("speed_noise_correlation", f"expected a correlation below 1, got {rho}; "
               "write e.g. speed_noise_correlation = 0.9")
    return rho


def _trace(t: Table) -> TraceSpec:
    spec = _coast_down(t) if t.string("kind", choices=TRACE_KINDS) == COAST_DOWN else None
    if spec is None:
        spec = _driven(t)
    if spec.delay >= spec.duration:
        t.fail("delay", f"delay {spec.delay} s is not shorter than the trace "
               f"({spec.duration} s); give the sensor delay in seconds")
    n = spec.time.size
    if not 3 <= n <= MAX_SAMPLES:
        t.fail("duration", f"duration x rate gives {n} samples; choose them so a trace has "
               f"3 to {MAX_SAMPLES} samples")
    return spec


def _driven(t: Table) -> TraceSpec:
    """A trace driven by a voltage schedule (any kind but a coast-down)."""
    t.check_keys(("name", "kind", "duration", "rate", "voltage", "load_torque", "initial",
            "speed_unit", "record_current", "speed_noise", "speed_quantum", "current_noise",
            "current_quantum", "delay", "encoder", "drag", "speed_noise_correlation"))
    initial = t.value("initial", default="rest")
    if isinstance(initial, dict):
        sub = Table(t.file, initial, t.path("initial"))
        sub.check_keys(("current", "speed"))
        initial = (sub.number("current"), sub.number("speed"))
    elif initial not in ("rest", "steady"):
        t.fail("initial", f'expected "rest", "steady" or {{ current = A, speed = rad/s }}, '
               f"got {initial!r}")
    speed_unit = t.string("speed_unit", default="rad/s")
    try:
        unit_factor("speed", speed_unit)
    except ValueError as exc:
        t.fail("speed_unit", str(exc))
    record_current = t.value("record_current", default=True)
    if not isinstance(record_current, bool):
        t.fail("record_current", f"expected true or false, got {record_current!r}")
    spec = TraceSpec(
        name=t.string("name"), kind=t.string("kind", choices=TRACE_KINDS),
        duration=t.number("duration", positive=True), rate=t.number("rate", positive=True),
        voltage=_schedule(t, "voltage", True), load_torque=_schedule(t, "load_torque", False),
        initial=initial, speed_unit=speed_unit, record_current=record_current,
        **{k: t.number(k, default=0.0, low=0.0) for k in ("speed_noise", "speed_quantum",
                                                  "current_noise", "current_quantum",
                                                  "delay")},
        encoder=check_encoder(t), drag=read_drag(t, _SI_DRAG),
        speed_noise_correlation=_correlation(t),
    )
    if spec.encoder is not None and spec.encoder[1] == "edges" and spec.initial != "rest":
        t.fail("encoder", 'an "edges" encoder trace starts at rest; set initial = "rest" or '
               'output = "position"')
    return spec


def check_plan(data: dict, source=None) -> Plan:
    """Validate a plan dict (from :func:`load_plan`) and return it as a :class:`Plan`.

    Raises
    ------
    SessionError
        One line naming ``source`` (the plan file), the key, the problem and the fix.
    """
    source = None if source is None else Path(source)
    top = Table(source, data, "")
    top.check_keys(("seed", "motor", "truth", "bench", "operating_point", "steady_table", "trace",
                    "rig"))
    seed = top.value("seed", default=None)
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        top.fail("seed", f"expected a whole number >= 0, got {seed!r}; write e.g. seed = 1")
    motor = top.table("motor")
    motor.check_keys(("name", "friction"))
    friction = motor.string("friction", default="viscous", choices=FRICTION_MODELS)
    tt = top.table("truth")
    tt.check_keys(TRUTH_KEYS)
    truth = {k: tt.number(k, default=0.0 if k == "Tc" else REQUIRED, low=0.0,
                       positive=k != "Tc")
             for k in TRUTH_KEYS}
    if friction == "viscous" and truth["Tc"] > 0:
        tt.fail("Tc", 'friction "viscous" has no Coulomb torque; set Tc = 0 or set '
                'motor.friction = "coulomb"')
    bt = top.table("bench")
    bt.check_keys(tuple(_BENCH))
    bench = []
    for key, kind in _BENCH.items():
        if key == "La" and key not in bt.data:  # an unmeasured La: the session omits it
            continue
        b = bt.table(key)
        b.check_keys(("sd", "unit"))
        unit = b.string("unit")
        try:
            unit_factor(kind, unit)
        except ValueError as exc:
            b.fail("unit", str(exc))
        bench.append(BenchSpec(key, b.number("sd", positive=True), unit))
    points = []
    for t in _named_tables(top, "operating_point"):
        t.check_keys(("name", "supply_voltage", "duty", "load_torque", "speed_sd", "current_sd"))
        duty = t.number("duty", positive=True)
        if duty > 1.0:
            t.fail("duty", f"duty {duty} is above 1; give the duty cycle as a fraction, e.g. 0.7")
        points.append(PointSpec(t.string("name"), t.number("supply_voltage", positive=True),
                                duty, t.number("load_torque", default=0.0),
                                t.number("speed_sd", default=0.0, low=0.0),
                                t.number("current_sd", default=0.0, low=0.0)))
    tables = []
    for t in _named_tables(top, "steady_table"):
        t.check_keys(("name", "voltages", "load_torques", "speed_sd", "current_sd"))
        volts, loads = t.numbers("voltages"), t.numbers("load_torques", required=False)
        if loads and len(loads) != len(volts):
            t.fail("load_torques", f"has {len(loads)} values for {len(volts)} voltages; give "
                   "one load torque per voltage")
        cur = t.value("current_sd", default=None)
        tables.append(TableSpec(t.string("name"), volts, loads or None,
                                t.number("speed_sd", default=0.0, low=0.0),
                                None if cur is None else t.number("current_sd", low=0.0)))
    traces = tuple(_trace(t) for t in _named_tables(top, "trace"))
    names = [s.name for s in (*points, *tables, *traces)]
    for name in names:
        if names.count(name) > 1:
            top.fail("name", f"the name {name!r} is used twice; give every operating point, "
                     "steady table and trace its own name")
    rt = top.table("rig", required=False)
    rig = None if rt is None else check_rig(rt, {s.name for s in traces})
    for tr in traces:
        if tr.encoder is not None and rig is None:
            top.fail("trace", f"trace {tr.name!r} has an encoder, which the rig simulator "
                     "draws: add a [rig] table (it may be empty)")
    return Plan(source, seed, motor.string("name"), friction, truth, tuple(bench),
                tuple(points), tuple(tables), traces, rig)
