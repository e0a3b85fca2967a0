"""The fuzzer's ``[rig]`` (one non-ideality, sized so that it matters) and what a plan
cannot say, added to a rendered session: a trace's voltage logged as a column instead of
a schedule (half the columns read with noise), and a step reading (a 63.2 % time and a
final speed read off a plot of the rig's step response)."""

from __future__ import annotations

import math
import re
import zlib

import numpy as np

from ._text import csv_text, inline, number, trace_block
from .bench import BenchMotor, steady_point
from .plan import Plan, TraceSpec
from .rig import rig_steady, rig_trace

__all__ = ["NON_IDEALITIES", "rig_table", "stop_before_end", "column_reading", "log_voltage_column",
           "add_step_reading", "STEP_READING_SD", "draw_sensors", "log_uniform"]

NON_IDEALITIES = ("dead time", "speed lag", "voltage drop", "source resistance",
                  "current limit", "unknown load", "encoder speed", "speed gain",
                  "speed offset", "dead zone", "coloured noise", "open at zero")

STEP_READING_SD = 0.01  # relative error of a time and a speed read off a plot


def rig_table(rng, key: str | None, truth: dict, v: float, tau_m: float, names, traces) -> dict:
    """``[rig]`` with the one non-ideality ``key`` (empty for an in-class session)."""
    if key is None:
        return {}
    if key == "dead time":
        return {"dead_time": float(f"{rng.uniform(0.05, 0.15) * tau_m:.4g}")}
    if key == "speed lag":
        return {"speed_lag": float(f"{rng.uniform(0.1, 0.3) * tau_m:.4g}")}
    if key == "voltage drop":
        return {"voltage_drop": float(f"{rng.uniform(0.08, 0.15) * v:.4g}")}
    if key == "source resistance":
        return {"source_resistance": float(f"{rng.uniform(0.4, 0.8) * truth['Ra']:.4g}")}
    if key == "current limit":
        return {"current_limit": float(f"{rng.uniform(0.2, 0.4) * v / truth['Ra']:.4g}")}
    if key == "unknown load":
        name = str(rng.choice(names))
        w = v * truth["K"] / (truth["Ra"] * truth["B"] + truth["K"] ** 2)
        return {"unknown_load": {name: {"viscous": float(f"{2.0 * truth['B']:.4g}"),
                                        "constant": float(f"{0.1 * truth['B'] * w:.4g}")}}}
    if key == "speed gain":
        return {"speed_gain": float(f"{rng.uniform(1.06, 1.15):.4g}")}
    if key == "speed offset":
        w = v * truth["K"] / (truth["Ra"] * truth["B"] + truth["K"] ** 2)
        return {"speed_offset": float(f"{rng.uniform(0.03, 0.06) * w:.4g}")}
    if key == "dead zone":  # wider in reverse: a driver's asymmetric dead zone
        return {"dead_zone_forward": float(f"{rng.uniform(0.04, 0.08) * v:.4g}"),
                "dead_zone_reverse": float(f"{rng.uniform(0.10, 0.15) * v:.4g}")}
    if key == "coloured noise":  # every analogue speed read through a filtering sensor
        w = v * truth["K"] / (truth["Ra"] * truth["B"] + truth["K"] ** 2)
        for t in traces:
            if "speed_noise" in t:
                t.pop("speed_quantum", None)
                sd = max(t["speed_noise"], rng.uniform(0.01, 0.03) * w)
                t["speed_noise"] = float(f"{sd:.4g}")
                t["speed_noise_correlation"] = float(f"{rng.uniform(0.8, 0.97):.3g}")
        return {}
    if key == "open at zero":  # every driven trace stopped before its end, the rotor coasting
        stop_before_end(traces)
        return {"freewheel_voltage": float(f"{rng.uniform(1.0, 1.5) * v:.4g}")}
    if key == "encoder speed":
        for t in traces:  # every driven trace's speed: encoder counts differenced
            if t["kind"] != "coast-down":
                t.pop("speed_noise", None), t.pop("speed_quantum", None)
                t["encoder"] = {"counts_per_rev": 64, "output": "speed"}
        return {}
    raise ValueError(f"unknown non-ideality {key!r}; use one of {NON_IDEALITIES}")


def stop_before_end(traces) -> None:
    """A zero command halfway through the last level of every trace driven by a
    voltage schedule that ends driven, on the sample grid (where a logged column is
    exact) strictly after the level's start and a sample or more before the record's
    end; a level too short for one is left as drawn, and so is a load change at
    constant voltage."""
    for t in traces:
        if t["kind"] in ("step", "free-form") and t["voltage"][-1][1] != 0.0:
            last, rate, end = t["voltage"][-1][0], t["rate"], t["duration"]
            stop = round((last + 0.5 * (end - last)) * rate) / rate
            if last < stop < end - 1.0 / rate:
                t["voltage"].append([stop, 0.0])
                t["kind"] = "free-form"


def _held(pairs, t: np.ndarray) -> np.ndarray:
    """A schedule's value at each sample time ``t`` (the last pair at or before it; a
    pair within a thousandth of a sample interval of a sample counts as at it: the times
    written to the CSV keep ten significant digits, so a sample late in a long trace
    reads up to 5e-9 s before the switch the rig made at it)."""
    times = np.array([a for a, _ in pairs])
    values = np.array([b for _, b in pairs])
    tol = 1e-3 * float(np.median(np.diff(t)))
    return values[np.searchsorted(times, t + tol, side="right") - 1]


def column_reading(seed: int, name: str, plan: dict) -> dict:
    """How trace ``name``'s logged voltage column is read: for half the columns, by an
    ADC whose readings carry noise of 0.1–2 % of the trace's largest voltage (drawn from
    a generator of their own, so that the rest of the session is the seed's as before)."""
    rng = np.random.default_rng([int(seed), zlib.crc32(name.encode())])
    if rng.uniform() < 0.5:
        return {}
    trace = next(t for t in plan["trace"] if t["name"] == name)
    top = max(abs(float(v)) for _, v in trace["voltage"])
    share = float(np.exp(rng.uniform(np.log(1e-3), np.log(2e-2))))
    return {"noise": float(f"{share * top:.3g}"),
            "seed": int(rng.integers(2**31))}


def log_voltage_column(files: dict[str, str], plan: Plan, name: str, *,
                       noise: float = 0.0, seed: int = 0,
                       supply: float = 0.0) -> dict[str, str]:
    """``files`` with trace ``name``'s voltage schedule written as a column ``va`` of its
    CSV (the value at each sample, held to the next: exact when the schedule switches
    on samples) and the schedule removed from ``session.toml``; with ``noise`` (V), the
    column is the driver's output read by an ADC whose readings carry Gaussian noise of
    that sd (drawn from ``seed``), rounded to a millivolt; with ``supply`` (V), the
    output of a driver switching that supply, sampled far slower than it switches: each
    reading the supply (of the voltage's sign) with the duty's probability, else 0."""
    spec = next(t for t in plan.traces if t.name == name)
    rows = files[f"{name}.csv"].rstrip("\n").split("\n")
    header = rows[0].split(",")
    data = np.array([[float(x) for x in r.split(",")] for r in rows[1:]])
    t = data[:, header.index("t")]
    cols = {h: data[:, k] for k, h in enumerate(header)}
    cols["va"] = _held(spec.voltage, t)
    rng = np.random.default_rng(seed)
    if supply > 0.0:
        duty = np.abs(cols["va"]) / supply
        if np.any(duty > 1.0):
            raise ValueError(f"trace {name!r} applies more than the supply of {supply:g} V")
        cols["va"] = np.where(rng.uniform(size=t.size) < duty, np.sign(cols["va"]) * supply, 0.0)
    if noise > 0.0:
        read = cols["va"] + rng.normal(0.0, noise, t.size)
        cols["va"] = np.round(read, 3)
    out = dict(files)
    out[f"{name}.csv"] = csv_text(cols)
    lines = files["session.toml"].split("\n")
    for k in trace_block(lines, name):
        if lines[k].startswith("columns = { "):
            lines[k] = lines[k][:-2] + ', voltage = "va" }'
        elif lines[k].startswith("voltage = ["):
            lines[k] = None
    out["session.toml"] = "\n".join(x for x in lines if x is not None)
    return out


def _tau_63(plan: Plan, voltage: float, tau_m: float) -> float:
    """The 63.2 % time of the rig's noise-free step from rest (linear between 4,000
    samples over six mechanical time constants)."""
    duration = 6.0 * tau_m
    spec = TraceSpec(name="reading", kind="step", duration=duration, rate=4000 / duration,
                     voltage=((0.0, voltage),), load_torque=None, initial="rest",
                     speed_unit="rad/s", record_current=False, speed_noise=0.0,
                     speed_quantum=0.0, current_noise=0.0, current_quantum=0.0, delay=0.0)
    tr = rig_trace(plan.truth, plan.rig, spec)
    w, t = tr["speed"], tr["time"]
    level = 0.632 * w[-1]
    k = int(np.argmax(w >= level))
    return float(t[k - 1] + (level - w[k - 1]) / (w[k] - w[k - 1]) * (t[k] - t[k - 1]))


def add_step_reading(files: dict[str, str], plan: Plan, seed: int) -> dict[str, str]:
    """``files`` with a ``[[step_reading]]`` at the largest voltage of the plan's traces:
    the rig's 63.2 % time and steady speed, each with :data:`STEP_READING_SD` relative
    Gaussian error.  Only where the electrical time constant is under 5 % of the
    mechanical one (what a 63.2 % reading measures); ``files`` unchanged otherwise."""
    p = plan.truth
    tau_m = p["J"] * p["Ra"] / (p["K"] ** 2 + p["Ra"] * p["B"])
    if p["La"] / p["Ra"] > 0.05 * tau_m:
        return files
    v = max(abs(b) for tr in plan.traces for _, b in tr.voltage)
    _, w = rig_steady(plan.truth, plan.rig, np.array([v]), np.array([0.0]))
    z = np.random.default_rng([int(seed), 632]).standard_normal(2)
    tau = _tau_63(plan, v, tau_m) * (1 + STEP_READING_SD * z[0])
    speed = float(w[0]) * (1 + STEP_READING_SD * z[1])
    units = {"voltage": '"V"', "final_speed": '"rad/s"', "tau": '"s"'}
    block = ["", "[[step_reading]]", 'name = "plot"', f"voltage = {number(v)}",
             f"final_speed = {number(speed)}", f"tau = {number(tau)}", f"units = {inline(units)}"]
    text = files["session.toml"].rstrip("\n").split("\n")
    first = next((k for k, x in enumerate(text) if re.fullmatch(r"\[\[trace\]\]", x)),
                 len(text))
    while first > 0 and (text[first - 1].startswith("#") or not text[first - 1].strip()):
        first -= 1
    return dict(files, **{"session.toml": "\n".join(text[:first] + block + text[first:])
                          + "\n"})


def log_uniform(rng, lo, hi) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_sensors(rng, t: dict, motor: BenchMotor, v: float, features: set) -> None:
    """Noise, quantum, unit, encoder and current channel of a driven trace."""
    span = steady_point(motor, v)[1]
    i_span = v / motor.Ra
    edges_ok = t["initial"] == "rest" and t["kind"] == "step"
    u = rng.uniform()
    if u < 0.12 or (u < 0.24 and edges_ok):
        revs = span * t["duration"] / (2 * math.pi)
        output = "position" if u < 0.12 else "edges"
        cap = 20_000 if output == "edges" else 1e9
        counts = int(max(1, min(int(rng.choice([16, 64, 256, 1024, 4096])), cap / revs)))
        t["encoder"] = {"counts_per_rev": counts, "output": output}
        features.add(f"encoder {output}")
    else:
        t["speed_noise"] = float(f"{log_uniform(rng, 1e-3, 5e-2) * span:.4g}")
        if rng.uniform() < 0.3:
            t["speed_quantum"] = float(f"{log_uniform(rng, 1e-3, 2e-2) * span:.4g}")
            features.add("quantised speed")
        if rng.uniform() < 0.3:
            t["speed_unit"] = "rpm"
    record = rng.uniform() < 0.5
    t["record_current"] = bool(record)
    if record:
        t["current_noise"] = float(f"{log_uniform(rng, 1e-3, 5e-2) * i_span:.4g}")
