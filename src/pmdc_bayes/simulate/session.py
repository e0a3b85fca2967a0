"""Simulate a bench session from a plan: the files a real rig would give, with known truth.

:func:`simulate_session` reads a plan (see ``data/demo/plan.toml`` and
:mod:`pmdc_bayes.simulate.plan`), draws the bench measurements, steady points and logged traces
of a motor with the plan's true parameters, and writes a session directory that
:func:`pmdc_bayes.io.loader.load_session` reads: ``session.toml``, one CSV per steady table
and trace, and ``truth.json``.  Traces come from the exact model
:func:`pmdc_bayes.physics.solution.simulate`, passed through simple sensor models.

Reproducibility: every item (bench value, operating point, table, trace) draws from
its own random stream, derived from the seed and the item's name, so adding,
removing or reordering items leaves the others' noise unchanged; numbers are written
with a fixed format and ``\\n`` line endings, so a seed gives byte-identical files.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import jax
import numpy as np
from scipy.signal import lfilter

from .._errors import SessionError
from .._x64 import x64
from ..inference.model.trace_states import initial_speed_name
from ..io.units import from_si, to_si
from ..physics import motor
from ..physics.experiment import stack_experiments, with_drags
from ..physics.load import drag_cuts
from ..physics.solution import Params, simulate
from ._text import csv_text, drag_entry, inline, number, pairs, stream, string
from ._write import HEADER, check_out, write_session_files
from .coast import ideal_coast_down, rig_coast_down
from .plan import COAST_DOWN, Plan, TraceSpec, check_plan, load_plan
from .rig import rig_steady, rig_trace, rig_truth

__all__ = ["simulate_session", "load_plan", "render_session", "true_steady", "true_trace",
           "sample_trace"]

_simulate = jax.jit(simulate, static_argnames="coulomb")  # compiled once per trace layout
_BENCH_KIND = {"Ra": "resistance", "La": "inductance"}


def _params(truth: dict) -> Params:
    return Params(**{k: float(v) for k, v in truth.items()})


def true_steady(truth: dict, va, tl=0.0):
    """Steady ``(ia, ω)`` (A, rad/s) of the true motor, with Coulomb friction.

    Notes
    -----
    While it turns (``|K·Va/Ra − TL| > Tc``), equations (15)–(16) with the load
    ``TL + Tc·sign``: ``ω = (K·Va − Ra·(TL+Tc))/(K² + Ra·B)``,
    ``ia = (B·Va + K·(TL+Tc))/(K² + Ra·B)``; otherwise the rotor is held,
    ``ω = 0`` and ``ia = Va/Ra``.
    """
    p = _params(truth)
    va, tl = np.asarray(va, dtype=float), np.asarray(tl, dtype=float)
    return motor.steady_state(p.Ra, p.K, p.B, va, tl, p.Tc)


@x64
def true_trace(truth: dict, spec: TraceSpec):
    """Noise-free ``(t, ia, ω)`` of a trace (s, A, rad/s), with the sensor delay.

    A sample at time ``t`` reports the state at ``max(t − delay, 0)``.
    """
    t = spec.time
    shifted, index = np.unique(np.maximum(t - spec.delay, t[0]), return_inverse=True)
    va_t, va_v = zip(*spec.voltage, strict=True)
    tl_t, tl_v = zip(*(spec.load_torque or ((0.0, 0.0),)), strict=True)
    # a curved drag's tangent taken again on a finer grid than the fit's
    cuts = (drag_cuts(spec.drag, shifted, np.concatenate([va_t, tl_t]), ratio=1.1,
                      longest=(shifted[-1] - shifted[0]) / 400)
            if spec.drag.curved else None)
    exp = with_drags(stack_experiments([(shifted, va_t, va_v, tl_t, tl_v, spec.initial,
                                         cuts)]), [spec.drag])
    ia, w = _simulate(_params(truth), exp, coulomb=truth["Tc"] > 0 or spec.drag[0] > 0)
    return t, np.asarray(ia)[index], np.asarray(w)[index]


def _quantise(x: np.ndarray, q: float) -> np.ndarray:
    """Round to the nearest multiple of ``q`` (no rounding when ``q`` is 0)."""
    return x if q == 0 else np.round(x / q) * q


def sample_trace(truth: dict, spec: TraceSpec, seed: int, rig=None) -> dict[str, np.ndarray]:
    """Sensor readings of a trace, SI: ``time``, ``speed`` and (if recorded) ``current``;
    on a ``rig`` (:class:`~.rig.RigSpec`) its readings there, with ``position`` for an
    encoder trace.

    Each analogue channel is the true signal plus Gaussian noise (the speed's AR(1)
    with the trace's ``speed_noise_correlation``, its sd ``speed_noise`` throughout),
    then rounded to its quantum; an encoder's counts are exact.
    """
    if spec.kind == COAST_DOWN:
        true = (ideal_coast_down(truth, spec) if rig is None
                else rig_coast_down(truth, rig, spec))
    elif rig is None:
        t, ia, w = true_trace(truth, spec)
        true = {"time": t, "speed": w, "current": ia}
    else:
        true = rig_trace(truth, rig, spec)
    t = true["time"]
    speed_rng, current_rng = stream(seed, "trace", spec.name, 2)
    out = {"time": t}
    if spec.encoder is not None:
        out.update({k: true[k] for k in ("speed", "position", "direction")
                    if true.get(k) is not None})
    else:
        noise = speed_rng.standard_normal(t.size)
        rho = spec.speed_noise_correlation
        if rho > 0:  # stationary AR(1) of unit variance
            noise[1:] *= np.sqrt(1.0 - rho * rho)
            noise = lfilter([1.0], [1.0, -rho], noise)
        out["speed"] = _quantise(true["speed"] + spec.speed_noise * noise, spec.speed_quantum)
    if spec.record_current and true["current"] is not None:
        out["current"] = _quantise(true["current"] + spec.current_noise
                                   * current_rng.standard_normal(t.size), spec.current_quantum)
    return out


def _steady(plan: Plan, va, tl):
    """True steady ``(ia, ω)``: the ideal motor's, or on the plan's rig."""
    if plan.rig is None:
        return true_steady(plan.truth, va, tl)
    return rig_steady(plan.truth, plan.rig, va, tl)


@x64
def render_session(plan: Plan, seed: int) -> dict[str, str]:
    """The generated files, name -> text: ``session.toml``, ``truth.json`` and the CSVs."""
    truth, files = plan.truth, {}
    origin = plan.source.name if plan.source is not None else "a plan given in Python"
    out = [f"{HEADER} from {origin} (seed {seed}).",
           "# SIMULATED data, not measurements; the true parameters are in truth.json.",
           "# Do not edit: change the plan and regenerate with --force.", "",
           "[motor]", f"name = {string(plan.motor)}", f"friction = {string(plan.friction)}"]
    for b in plan.bench:
        kind = _BENCH_KIND[b.key]
        (rng,) = stream(seed, "bench", b.key)
        value = truth[b.key] + to_si(b.sd, kind, b.unit) * rng.standard_normal()
        if value <= 0:
            raise SessionError(plan.source, f"the drawn bench value {value:g} is not positive; "
                               "reduce sd", where=f"bench.{b.key}.sd")
        out += ["", f"[bench.{b.key}]", f"value = {number(from_si(value, kind, b.unit))}",
                f"unit = {string(b.unit)}", f"sd = {number(b.sd)}",
                'source = "simulated: true value + N(0, sd)"']
    for op in plan.operating_points:
        ia, w = (float(np.squeeze(v)) for v in _steady(plan, op.duty * op.supply_voltage,
                                                        op.load_torque))
        if w <= 0:
            raise SessionError(plan.source, "the motor does not turn at this point; raise "
                               "the voltage or lower the load",
                               where=f"operating_point[{op.name!r}]")
        rng_w, rng_i = stream(seed, "operating_point", op.name, 2)
        units = {"supply_voltage": '"V"', "current": '"A"', "speed": '"rad/s"',
                 "load_torque": '"N*m"'}
        out += ["", "[[operating_point]]", f"name = {string(op.name)}",
                f"supply_voltage = {number(op.supply_voltage)}", f"duty = {number(op.duty)}",
                f"current = {number(ia + op.current_sd * rng_i.standard_normal())}",
                f"speed = {number(w + op.speed_sd * rng_w.standard_normal())}",
                f"load_torque = {number(op.load_torque)}", f"units = {inline(units)}"]
    for tab in plan.steady_tables:
        va = np.asarray(tab.voltages)
        tl = np.asarray(tab.load_torques) if tab.load_torques else np.zeros_like(va)
        ia, w = _steady(plan, va, tl)
        rng_w, rng_i = stream(seed, "steady_table", tab.name, 2)
        cols = {"Va": va, "w": w + tab.speed_sd * rng_w.standard_normal(va.size)}
        roles = {"voltage": '"Va"', "speed": '"w"'}
        units = {"voltage": '"V"', "speed": '"rad/s"'}
        if tab.current_sd is not None:
            cols["ia"] = ia + tab.current_sd * rng_i.standard_normal(va.size)
            roles["current"], units["current"] = '"ia"', '"A"'
        if tab.load_torques:
            cols["TL"] = tl
            roles["load_torque"], units["load_torque"] = '"TL"', '"N*m"'
        files[f"{tab.name}.csv"] = csv_text(cols)
        out += ["", "[[steady_table]]", f"name = {string(tab.name)}",
                f"file = {string(tab.name + '.csv')}", f"columns = {inline(roles)}",
                f"units = {inline(units)}"]
    for tr in plan.traces:
        data = sample_trace(truth, tr, seed, plan.rig)
        cols, roles, extra = _trace_columns(tr, data)
        units = {"time": '"s"', "speed": string(tr.speed_unit), "current": '"A"',
                 "voltage": '"V"', "load_torque": '"N*m"'}
        if "position" in data:
            units["position"] = '"counts"'
        currents = (f"current noise sd {tr.current_noise:g} A, quantum "
                    f"{tr.current_quantum:g} A")
        if tr.kind == COAST_DOWN:
            units = {k: units[k] for k in ("time", "speed")}
            currents = f"the armature opened at {number(tr.initial[1])} rad/s"
        files[f"{tr.name}.csv"] = csv_text(cols)
        out += ["", f"# {tr.rate:g} Hz for {tr.duration:g} s ({tr.time.size} samples); "
                f"speed noise sd {tr.speed_noise:g} rad/s"
                + (f" (AR(1), lag-1 correlation {tr.speed_noise_correlation:g})"
                   if tr.speed_noise_correlation else "")
                + f", quantum {tr.speed_quantum:g} rad/s; "
                f"{currents}; sensor delay {tr.delay:g} s.",
                "[[trace]]", f"name = {string(tr.name)}", f"kind = {string(tr.kind)}",
                f"file = {string(tr.name + '.csv')}", f"columns = {inline(roles)}",
                f"units = {inline(units)}", *extra]
        if tr.kind == COAST_DOWN:  # its table says no more: the armature is open
            continue
        out.append(f"voltage = {pairs(tr.voltage)}")
        if tr.drag.nonzero:
            out.append(f"drag = {drag_entry(tr)}")
        if tr.load_torque is not None:
            out.append(f"load_torque = {pairs(tr.load_torque)}")
        if isinstance(tr.initial, str):
            out.append(f"initial = {string(tr.initial)}")
        else:
            ia0, w0 = tr.initial[0], from_si(tr.initial[1], "speed", tr.speed_unit)
            out.append(f"initial = {{ current = {number(ia0)}, speed = {number(w0)} }}")
    if plan.rig is not None:
        out[1] = "# SIMULATED data on a rig (see [rig] of the plan); the true values of the " \
            "motor and the rig are in truth.json."
        truth = {**truth, **rig_truth(plan.rig, [tr.name for tr in plan.traces
                                                 if tr.kind != COAST_DOWN])}
    truth = {**truth, **{initial_speed_name(tr.name): tr.initial[1] for tr in plan.traces
                         if tr.kind == COAST_DOWN}}
    files["session.toml"] = "\n".join(out) + "\n"
    files["truth.json"] = json.dumps({k: float(v) for k, v in truth.items()}, indent=2,
                                     sort_keys=True) + "\n"
    return files


def _trace_columns(tr: TraceSpec, data: dict) -> tuple[dict, dict, list[str]]:
    """A trace's CSV columns, their roles and the lines an encoder adds to its table."""
    cols, roles, extra = {"t": data["time"]}, {"time": '"t"'}, []
    if "position" in data:
        counts = data["position"] * tr.encoder[0] / (2.0 * np.pi)
        if tr.encoder[1] == "edges":  # one row per edge: its time (and direction)
            cols = {"t": data["time"][1:]}
            if "direction" in data:
                cols["dir"], roles["direction"] = data["direction"][1:], '"dir"'
        else:
            cols["counts"], roles["position"] = np.rint(counts), '"counts"'
        extra.append(f"counts_per_rev = {tr.encoder[0]}")
        if tr.encoder[1] == "edges":
            extra.append("edges = true")
    else:
        cols["speed"] = from_si(data["speed"], "speed", tr.speed_unit)
        roles["speed"] = '"speed"'
    if "current" in data:
        cols["ia"], roles["current"] = data["current"], '"ia"'
    return cols, roles, extra


@x64
def simulate_session(plan, out_dir, *, seed: int | None = None, force: bool = False) -> Path:
    """Simulate the session a plan describes and write it to ``out_dir``.

    Parameters
    ----------
    plan : dict or path
        A plan dict from :func:`load_plan`, or the path of a plan TOML file (then
        errors and the generated header name that file).
    out_dir : str or Path
        The session directory to write (created if needed).
    seed : int, optional
        Overrides the plan's ``seed``.
    force : bool
        Replace the generated files of an existing session in ``out_dir``.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    SessionError
        For a bad plan (one line naming the key and the fix).
    UsageError
        If ``out_dir`` already holds a ``session.toml`` and ``force`` is False.
    """
    source = None
    if isinstance(plan, str | os.PathLike):
        source = Path(plan)
        plan = load_plan(source)
    spec = check_plan(plan, source)
    seed = spec.seed if seed is None else seed
    if seed is None or isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SessionError(source, f"no usable seed ({seed!r}); add seed = <whole number >= 0> "
                           "to the plan or pass seed= (--seed)", where="seed")
    out = Path(out_dir)
    check_out(out, force)  # before the work, not only after it
    write_session_files(render_session(spec, seed), out, force)
    return out
