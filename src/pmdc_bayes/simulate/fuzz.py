"""Random sessions over the whole session format, drawn by the independent bench simulator.

:func:`fuzz_plan` draws a motor over four decades of size and a plan for it: one to
three traces of the kinds real benches log (a step from rest or from a steady speed,
an up-down, a staircase of many levels of both signs, a load change at constant voltage
with several load steps, a coast-down; on request a sweep or a random sequence,
:mod:`._fuzz_shapes`), sample rates of 0.2–20 kHz, short and long
records, speed noise of 0.1–5 % of the trace's span (sometimes quantised, in rad/s or
rpm, or counted by an encoder at the samples or at its edges), current channels or
not, a steady table (with or without currents), an operating point, a step reading.
The plan always has a ``[rig]``, so every reading comes from
:mod:`pmdc_bayes.simulate.bench` (LSODA on its own motor, not the fitted model).  With
``misspecified`` (a key of :data:`NON_IDEALITIES`, or several) the rig carries that
non-ideality (each of them), sized so that it matters.

:func:`fuzz_session` renders the plan with :func:`~.session.render_session` (the writer
of ``pmdc-bayes simulate``), adds what plans cannot say (a voltage logged as a column,
a step reading: :mod:`._fuzz_extra`; half the logged columns read by an ADC with noise
of 0.1–2 % of the trace's largest voltage) and writes the directory the loader reads.  The
same seed gives the same bytes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._clock import stamp_coarse_clock
from ._fuzz_extra import (
    NON_IDEALITIES,
    add_step_reading,
    column_reading,
    draw_sensors,
    log_uniform,
    log_voltage_column,
    rig_table,
    stop_before_end,
)
from ._fuzz_shapes import EXCITATION_SHAPES, excitation
from ._write import write_session_files
from .bench import BenchMotor, steady_point
from .plan import check_plan
from .session import render_session

__all__ = ["NON_IDEALITIES", "TRACE_SHAPES", "EXCITATION_SHAPES", "FuzzedSession",
           "fuzz_motor", "fuzz_plan", "column_reading", "fuzz_files", "fuzz_session"]

TRACE_SHAPES = ("step from rest", "step from steady", "up-down", "staircase",
                "load change", "coast-down")

MAX_SAMPLES = 12_000  # per trace: keeps a fit of a fuzzed session to seconds


@dataclass(frozen=True)
class FuzzedSession:
    """A fuzzed session: where it was written, its truth and what it is made of."""

    seed: int
    misspecified: str | tuple[str, ...] | None
    path: Path | None
    truth: dict
    shapes: tuple[str, ...]  # one label per item: trace shapes, tables, points ...
    features: frozenset  # "speed only", "quantised", "encoder position", ...


def fuzz_motor(rng: np.random.Generator, coulomb: bool) -> tuple[dict, float]:
    """True parameters over four decades of size, and the motor's nominal voltage.

    Nominal voltage 3–200 V, stall current 0.5–500 A (about 2 W to 100 kW), no-load
    speed 50–2000 rad/s, La/Ra 0.1–5 ms, mechanical time constant 5 ms–1 s, viscous
    friction 2–30 % of the damping; Coulomb friction 5–30 % of the no-load torque."""
    v = log_uniform(rng, 3.0, 200.0)
    ra = v / log_uniform(rng, 0.5, 500.0)
    k = v / log_uniform(rng, 50.0, 2000.0)
    la = ra * log_uniform(rng, 1e-4, 5e-3)
    damping = float(rng.uniform(0.02, 0.3))
    b = damping * k * k / ra / (1 - damping)
    j = log_uniform(rng, 5e-3, 1.0) * (k * k + ra * b) / ra
    tc = 0.0
    if coulomb:
        tc = float(rng.uniform(0.05, 0.3)) * b * k * v / (ra * b + k * k)
    return dict(Ra=ra, La=la, K=k, B=b, J=j, Tc=tc), v


def _rate_and_duration(rng, tau_m: float, holds: float) -> tuple[float, float]:
    """A sample rate (Hz) of 0.2–20 kHz and a record of ``holds`` mechanical time
    constants, the rate lowered (or raised) to keep 60–MAX_SAMPLES samples."""
    duration = holds * tau_m
    rate = log_uniform(rng, 200.0, 20_000.0)
    rate = min(max(rate, 60.0 / duration), MAX_SAMPLES / duration)
    return float(f"{rate:.6g}"), float(f"{duration:.6g}")


def _trace(rng, shape: str, name: str, truth: dict, v: float, tau_m: float,
           motor: BenchMotor, column: bool, between: bool = False) -> dict:
    """A plan ``[[trace]]`` of ``shape``; switching times on the sample grid when the
    voltage will be logged as a column (a zero-order hold exact), unless ``between``."""
    sign = 1.0 if rng.uniform() < 0.7 else -1.0
    top = sign * v * float(rng.uniform(0.4, 1.0))
    t = {"name": name, "kind": "step", "initial": "rest"}
    if shape == "staircase":
        n = int(rng.integers(4, 11))
        levels = v * rng.uniform(0.2, 1.0, n) * rng.choice([-1.0, 1.0], n)
        holds = rng.uniform(1.5, 4.0, n)
        rate, duration = _rate_and_duration(rng, tau_m, float(holds.sum()) + 0.5)
        starts = (0.5 + np.concatenate([[0.0], np.cumsum(holds)[:-1]])) * tau_m
        t.update(kind="free-form", voltage=[[0.0, 0.0]] + [[float(a), float(b)] for a, b in
                                                           zip(starts, levels, strict=True)])
    elif shape == "up-down":
        rate, duration = _rate_and_duration(rng, tau_m, float(rng.uniform(4.0, 12.0)))
        t1, t2 = 0.1 * duration, float(rng.uniform(0.45, 0.6)) * duration
        back = -top if rng.uniform() < 0.5 else 0.0
        t.update(kind="free-form", voltage=[[0.0, 0.0], [t1, top], [t2, back]])
    elif shape == "load change":
        rate, duration = _rate_and_duration(rng, tau_m, float(rng.uniform(4.0, 15.0)))
        n = int(rng.integers(1, 4))
        room = truth["K"] * abs(top) / truth["Ra"] - truth["Tc"]
        loads = np.sort(rng.uniform(0.05, 0.5, n)) * room * np.sign(top)
        times = duration * (np.arange(1, n + 1) / (n + 1))
        t.update(kind="load_change", initial="steady", voltage=[[0.0, top]],
                 load_torque=[[0.0, 0.0]] + [[float(a), float(b)] for a, b in
                                             zip(times, loads, strict=True)])
    elif shape in EXCITATION_SHAPES:
        rate, duration = _rate_and_duration(rng, tau_m, float(rng.uniform(6.0, 15.0)))
        t.update(kind="free-form",
                 voltage=excitation(rng, shape, top, v, tau_m, duration, rate))
    elif shape == "coast-down":
        rate, duration = _rate_and_duration(rng, tau_m, float(rng.uniform(1.0, 4.0)))
        w0 = steady_point(motor, abs(top))[1]
        return {"name": name, "kind": "coast-down", "duration": duration, "rate": rate,
                "initial": {"speed": float(f"{w0:.6g}")},
                "speed_noise": float(f"{log_uniform(rng, 1e-3, 5e-2) * w0:.4g}")}
    else:
        rate, duration = _rate_and_duration(rng, tau_m, float(rng.uniform(1.5, 12.0)))
        t0 = float(rng.uniform(0.02, 0.2)) * duration
        if shape == "step from steady":
            t.update(initial="steady", voltage=[[0.0, top * float(rng.uniform(0.2, 0.7))],
                                                [t0, top]])
        else:
            t.update(voltage=[[0.0, 0.0], [t0, top]])
    for key in ("voltage", "load_torque"):  # a column's switch exactly at a sample k/rate
        if key in t:
            t[key] = [[round(a * rate) / rate if column and not between
                       else float(f"{a:.9g}"),
                       float(f"{b:.6g}")] for a, b in t[key]]
    t["voltage"][0][0] = 0.0
    if "load_torque" in t:
        t["load_torque"][0][0] = 0.0
    t.update(duration=duration, rate=rate)
    return t


def fuzz_plan(seed: int, *, misspecified: str | tuple[str, ...] | None = None, shapes=None,
              trace_current: bool | None = None, steady: str | None = None,
              between_samples: bool = False, stopped: bool = False) -> tuple[dict, dict]:
    """A random plan and what it holds.

    Parameters
    ----------
    seed : the draw (``numpy.random.default_rng(seed)``) and the plan's noise seed.
    misspecified : a key of :data:`NON_IDEALITIES`, a tuple of them (a rig carrying
        each), or None for an in-class session.
    shapes : the trace shapes to draw from (default :data:`TRACE_SHAPES`; also
        :data:`EXCITATION_SHAPES`).
    trace_current : force (True) or forbid (False) the driven traces' current channels.
    steady : ``"table"``, ``"table without current"`` or ``"point"`` to force that
        steady reading (and no other); default a random mix.
    between_samples : a column's voltage switches between samples (a rig the logger's
        clock does not time), shown at the first sample after; all else the same.
    stopped : every trace driven by a schedule that ends driven commanded to zero
        halfway through its last level (as the rig of ``"open at zero"`` is).

    Returns
    -------
    (plan, extras)
        The plan dict for :func:`~.plan.check_plan`; ``extras`` says which trace logs
        its voltage as a column and whether to add a step reading.
    """
    keys = (misspecified,) if isinstance(misspecified, str) else tuple(misspecified or ())
    keys = tuple(dict.fromkeys(keys))
    for key in keys:
        if key not in NON_IDEALITIES:
            raise ValueError(f"unknown non-ideality {key!r}; use one of {NON_IDEALITIES}")
    rng = np.random.default_rng(seed)
    coulomb = rng.uniform() < 0.3
    truth, v = fuzz_motor(rng, coulomb)
    motor = BenchMotor(**truth)
    tau_m = truth["J"] * truth["Ra"] / (truth["K"] ** 2 + truth["Ra"] * truth["B"])
    features: set = set()
    pool = tuple(shapes or TRACE_SHAPES)
    for shape in pool:
        if shape not in TRACE_SHAPES + EXCITATION_SHAPES:
            raise ValueError(f"unknown trace shape {shape!r}; use one of "
                             f"{TRACE_SHAPES + EXCITATION_SHAPES}")
    kinds = [str(rng.choice(pool)) for _ in range(int(rng.integers(1, 4)))]
    if all(k == "coast-down" for k in kinds):
        kinds[0] = "step from rest"
    traces, columns = [], []
    for n, shape in enumerate(kinds):
        column = shape != "coast-down" and rng.uniform() < 0.3
        t = _trace(rng, shape, f"tr{n}_{shape.replace(' ', '_').replace('-', '_')}", truth,
                   v, tau_m, motor, column, between_samples)
        if shape != "coast-down":
            draw_sensors(rng, t, motor, v, features)
            if trace_current is not None:
                t["record_current"] = trace_current
                t.setdefault("current_noise", 0.01 * v / truth["Ra"])
            edges = t.get("encoder", {}).get("output") == "edges"
            if column and not edges:
                columns.append(t["name"])
        traces.append(t)
    plan = {"seed": int(seed), "motor": {"name": f"fuzzed motor {seed}",
                                         "friction": "coulomb" if coulomb else "viscous"},
            "truth": truth, "bench": {"Ra": {"sd": float(f"{0.03 * truth['Ra']:.4g}"),
                                             "unit": "ohm"}},
            "trace": traces}
    if rng.uniform() < 0.7:
        plan["bench"]["La"] = {"sd": float(f"{0.1 * truth['La']:.4g}"), "unit": "H"}
    w_top = steady_point(motor, v)[1]
    i_level = (truth["B"] * w_top + truth["Tc"]) / truth["K"]
    draw = rng.uniform(size=3)
    want_table = draw[0] < 0.6 if steady is None else steady.startswith("table")
    if want_table:
        volts = np.sort(v * rng.uniform(0.25, 1.0, int(rng.integers(3, 9))))
        tab = {"name": "steady", "voltages": [float(f"{x:.5g}") for x in volts],
               "speed_sd": float(f"{log_uniform(rng, 1e-3, 5e-2) * w_top:.4g}")}
        if (draw[1] < 0.5 if steady is None else steady == "table"):
            tab["current_sd"] = float(f"{log_uniform(rng, 1e-3, 5e-2) * i_level:.4g}")
        plan["steady_table"] = [tab]
    if (draw[2] < 0.4 if steady is None else steady == "point"):
        plan["operating_point"] = [{
            "name": "point", "supply_voltage": float(f"{1.25 * v:.5g}"),
            "duty": float(f"{rng.uniform(0.3, 0.8):.3g}"),
            "speed_sd": float(f"{log_uniform(rng, 1e-3, 5e-2) * w_top:.4g}"),
            "current_sd": float(f"{log_uniform(rng, 1e-3, 5e-2) * i_level:.4g}")}]
    step = steady is None and rng.uniform() < 0.15
    plan["rig"] = {}
    for key in keys:
        plan["rig"].update(rig_table(rng, key, truth, v, tau_m,
                                     [t["name"] for t in traces if t["kind"] != "coast-down"],
                                     traces))
    if stopped:
        stop_before_end(traces)
    return plan, {"columns": tuple(columns), "step_reading": bool(step),
                  "shapes": tuple(kinds), "features": frozenset(features)}


def fuzz_files(seed: int, *, coarse_clock: bool = False,
               **kw) -> tuple[dict[str, str], dict, dict]:
    """The files of a fuzzed session (name -> text), its plan and extras; with
    ``coarse_clock``, every trace stamped as a microcontroller logs it (see
    :func:`~._clock.stamp_coarse_clock`)."""
    plan, extras = fuzz_plan(seed, **kw)
    spec = check_plan(plan)
    files = render_session(spec, int(seed))
    for name in extras["columns"]:
        files = log_voltage_column(files, spec, name, **column_reading(seed, name, plan))
    if extras["step_reading"]:
        files = add_step_reading(files, spec, seed)
    if coarse_clock:
        for t in plan["trace"]:
            files = stamp_coarse_clock(files, t["name"])
    return files, plan, extras


def fuzz_session(seed: int, *, misspecified: str | tuple[str, ...] | None = None, out=None,
                 shapes=None, trace_current: bool | None = None, steady: str | None = None,
                 between_samples: bool = False, coarse_clock: bool = False,
                 stopped: bool = False) -> FuzzedSession:
    """Draw the session of ``seed`` (see :func:`fuzz_plan`) and, given ``out``, write it
    there (replacing an earlier fuzzed session) for :func:`~pmdc_bayes.io.loader.load_session`."""
    files, plan, extras = fuzz_files(seed, misspecified=misspecified, shapes=shapes,
                                     trace_current=trace_current, steady=steady,
                                     between_samples=between_samples, stopped=stopped,
                                     coarse_clock=coarse_clock)
    path = None
    if out is not None:
        path = Path(out)
        write_session_files(files, path, force=True)
    features = set(extras["features"])
    traces = [t for t in plan["trace"] if t["kind"] != "coast-down"]
    if not any(t.get("record_current") for t in traces):
        features.add("no trace current")
    if extras["columns"]:
        features.add("voltage column")
    if coarse_clock:
        features.add("coarse clock")
    if stopped:
        features.add("stopped")
    if any(column_reading(seed, name, plan) for name in extras["columns"]):
        features.add("noisy voltage column")
    labels = list(extras["shapes"]) + [k.replace("_", " ") for k in
                                       ("steady_table", "operating_point") if k in plan]
    if extras["step_reading"]:
        labels.append("step reading")
    return FuzzedSession(int(seed), misspecified, path, json.loads(files["truth.json"]),
                         tuple(labels), frozenset(features))
