"""A plan's rig: the non-idealities of a real bench that ``[rig]`` asks for, simulated on
the plan's traces and steady readings by the independent bench simulator
(:mod:`.bench`, LSODA), not by the package's own model.

``[rig]`` (all optional, SI)::

    [rig]
    dead_time = 0.002          # s between the commanded voltage and the motor (every trace)
    voltage_drop = 0.8         # V at brushes and driver, opposing the current
    source_resistance = 0.3    # ohm between the logged (supply) voltage and the terminals
    current_limit = 2.0        # A: the driver holds |ia| at it
    dead_zone_forward = 0.5    # V of a positive command the driver does not put out
    dead_zone_reverse = 0.7    # V of a negative command, likewise
    freewheel_voltage = 13.4   # V: the driver opens the armature at a zero command (an
                               # L298N's enable low), its diodes returning the current
    speed_lag = 0.005          # s: a first-order lag of the speed sensor (a tachometer)
    current_lag = 0.0          # s: the same of the current sensor
    speed_gain = 1.0           # the traces' speed sensor reads gain × speed + offset
    speed_offset = 0.0         # rad/s
    current_gain = 1.0         # the traces' current sensor, likewise
    current_offset = 0.0       # A
    unknown_load = { step_9v = { viscous = 1e-4, constant = 0.0 } }  # drag nobody declared

and per trace ``encoder = { counts_per_rev = 400, output = "position" }`` (``"position"``:
the counts at the samples; ``"edges"``: one row per edge, its time to 1 µs, and its
direction when the rotor turns back; ``"speed"``: the counts differenced over each
sample interval).  The session written declares only
what a user would know (the commanded voltage, the declared load); ``truth.json`` holds
the rig's true values under the names the fit reports (``Vdrop``, ``Imax``,
``dead_time`` and ``dead_time_<trace>``, ``Rs``, ``speed_lag``, ``current_lag``,
``Vdz_fwd``, ``Vdz_rev``,
``speed_gain``, ``speed_offset``, ``current_gain``, ``current_offset``, ``drag_<trace>``,
``load_<trace>``).  The gains and offsets are the traces' sensors'; the steady readings
are taken by other instruments, without them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..inference.model.nuisances import dead_time_name, load_names
from ..io.toml_tables import Table
from ._encoder import EDGE_FINE, ENCODER_OUTPUTS, encoder_trace_parts
from .bench import BenchMotor, integrate, steady_point

__all__ = ["RigSpec", "check_rig", "check_encoder", "rig_truth", "rig_steady", "rig_trace"]

_KEYS = ("dead_time", "voltage_drop", "source_resistance", "current_limit", "speed_lag",
         "current_lag", "speed_gain", "speed_offset", "current_gain", "current_offset",
         "unknown_load", "dead_zone_forward", "dead_zone_reverse", "freewheel_voltage")


@dataclass(frozen=True)
class RigSpec:
    """The rig's non-idealities (SI); ``unknown_load`` holds ``(trace, constant N·m,
    viscous N·m·s/rad)``."""

    dead_time: float = 0.0
    voltage_drop: float = 0.0
    source_resistance: float = 0.0
    current_limit: float | None = None
    speed_lag: float = 0.0
    current_lag: float = 0.0
    speed_gain: float = 1.0
    speed_offset: float = 0.0
    current_gain: float = 1.0
    current_offset: float = 0.0
    unknown_load: tuple[tuple[str, float, float], ...] = ()
    dead_zone_forward: float = 0.0
    dead_zone_reverse: float = 0.0
    freewheel_voltage: float = 0.0  # nonzero: the driver opens the armature at a zero
    # command, its current returning through diodes against this voltage (V)

    def driver(self, va: float) -> float:
        """The driver's output (V) for the command ``va``: less its dead zone, and 0
        within it."""
        if va > 0:
            return max(va - self.dead_zone_forward, 0.0)
        return min(va + self.dead_zone_reverse, 0.0) if va < 0 else 0.0


def check_rig(t: Table, trace_names) -> RigSpec:
    """``[rig]`` of a plan, checked (one line naming the key and the fix on a problem)."""
    t.check_keys(_KEYS)
    loads = []
    lt = t.table("unknown_load", required=False)
    if lt is not None:
        for name in lt.data:
            if name not in trace_names:
                lt.fail(name, f"names no trace of the plan; use one of {sorted(trace_names)}")
            part = lt.table(name)
            part.check_keys(("constant", "viscous"))
            loads.append((name, part.number("constant", default=0.0, low=0.0),
                          part.number("viscous", default=0.0, low=0.0)))
    limit = t.value("current_limit", default=None)
    return RigSpec(dead_time=t.number("dead_time", default=0.0, low=0.0),
                   voltage_drop=t.number("voltage_drop", default=0.0, low=0.0),
                   source_resistance=t.number("source_resistance", default=0.0, low=0.0),
                   current_limit=None if limit is None else t.number("current_limit",
                                                                     positive=True),
                   speed_lag=t.number("speed_lag", default=0.0, low=0.0),
                   current_lag=t.number("current_lag", default=0.0, low=0.0),
                   speed_gain=t.number("speed_gain", default=1.0, positive=True),
                   speed_offset=t.number("speed_offset", default=0.0),
                   current_gain=t.number("current_gain", default=1.0, positive=True),
                   current_offset=t.number("current_offset", default=0.0),
                   unknown_load=tuple(loads),
                   dead_zone_forward=t.number("dead_zone_forward", default=0.0, low=0.0),
                   dead_zone_reverse=t.number("dead_zone_reverse", default=0.0, low=0.0),
                   freewheel_voltage=t.number("freewheel_voltage", default=0.0, low=0.0))


def check_encoder(t: Table) -> tuple[int, str] | None:
    """A trace's ``encoder = { counts_per_rev, output }``, or None."""
    et = t.table("encoder", required=False)
    if et is None:
        return None
    et.check_keys(("counts_per_rev", "output"))
    counts = et.value("counts_per_rev", what="whole number of counts per revolution")
    if isinstance(counts, bool) or not isinstance(counts, int) or counts < 1:
        et.fail("counts_per_rev", f"expected a whole number >= 1, got {counts!r}")
    return counts, et.string("output", default="position", choices=ENCODER_OUTPUTS)


def _motor(truth: dict, rig: RigSpec, encoder=None) -> BenchMotor:
    """The bench simulator's motor; an encoder counts the rotor's own angle (no
    tachometer lag)."""
    return BenchMotor(**{k: truth[k] for k in ("Ra", "La", "K", "B", "J", "Tc")},
                      dead_time=rig.dead_time,
                      speed_lag=rig.speed_lag if encoder is None else 0.0,
                      current_lag=rig.current_lag, voltage_drop=rig.voltage_drop,
                      source_resistance=rig.source_resistance,
                      current_limit=rig.current_limit,
                      freewheel_voltage=rig.freewheel_voltage,
                      encoder_counts_per_rev=None if encoder is None else encoder[0],
                      encoder_output="speed" if encoder is None else encoder[1],
                      extra_load={n: (c, v) for n, c, v in rig.unknown_load},
                      speed_noise=0.0, current_noise=0.0)


def rig_truth(rig: RigSpec, trace_names) -> dict[str, float]:
    """The rig's true values under the names the fit reports."""
    out = {"Vdrop": rig.voltage_drop, "Rs": rig.source_resistance,
           "speed_lag": rig.speed_lag, "current_lag": rig.current_lag,
           "speed_gain": rig.speed_gain, "speed_offset": rig.speed_offset,
           "current_gain": rig.current_gain, "current_offset": rig.current_offset,
           "dead_time": rig.dead_time, "Vdz_fwd": rig.dead_zone_forward,
           "Vdz_rev": rig.dead_zone_reverse}
    if rig.current_limit is not None:
        out["Imax"] = rig.current_limit
    for name in trace_names:
        out[dead_time_name(name)] = rig.dead_time
    for name, constant, viscous in rig.unknown_load:
        load, drag = load_names(name)
        out[load], out[drag] = constant, viscous
    return out


def rig_steady(truth: dict, rig: RigSpec, va, tl) -> tuple[np.ndarray, np.ndarray]:
    """True steady ``(ia, ω)`` at commanded voltages ``va`` and loads ``tl`` on the rig
    (its driver's dead zone, drop, source resistance and current limit; read by other
    instruments than the traces' sensors, so without their gains and offsets)."""
    m = _motor(truth, rig)
    ia, w = np.array([steady_point(m, rig.driver(float(v)), float(x))
                      for v, x in zip(np.atleast_1d(va), np.atleast_1d(tl), strict=True)]).T
    return ia, w


def _held(pairs, at: float) -> float:
    """The value of a schedule ``((time, value), ...)`` at ``at`` (its first before it)."""
    value = pairs[0][1]
    for time, v in pairs:
        if time <= at:
            value = v
    return float(value)


def _segments(spec, rig: RigSpec, end: float):
    """``(start, end, va, tl)`` pieces of constant input as the motor sees them (the
    commands through the driver, its dead time later)."""
    volts = tuple((time + rig.dead_time, rig.driver(v)) for time, v in spec.voltage)
    loads = spec.load_torque or ((0.0, 0.0),)
    cuts = sorted({0.0, end} | {x for x, _ in volts + loads if 0.0 < x < end})
    return [(a, b, _held(volts, a), _held(loads, a))
            for a, b in zip(cuts, cuts[1:], strict=False)]


def rig_trace(truth: dict, rig: RigSpec, spec) -> dict[str, np.ndarray]:
    """Noise-free readings of a plan trace ``spec`` on the rig, SI: ``time``, ``speed``
    and ``current`` (the sensors', with their lags, gains, offsets and the plan's delay:
    a sample at ``t`` reads the state at ``max(t − delay, 0)``); with an encoder,
    ``position`` (counted angle, NaN where unread) and ``speed`` from it; edges of a
    rotor that turns back carry their ``direction`` (1 forward, 0 backward)."""
    m = _motor(truth, rig, spec.encoder)
    if spec.drag.nonzero:  # the trace's known load, on top of any unknown one
        c, v = m.extra_load.get(spec.name, (0.0, 0.0))[:2]
        d = spec.drag
        m = replace(m, extra_load={**m.extra_load, spec.name: d._replace(
            constant=c + d.constant, viscous=v + d.viscous)})
    t = spec.time
    end = float(t[-1])
    segs = _segments(spec, rig, end)
    v_ref = max(max(abs(v) for _, v in spec.voltage), 1e-9)
    w_eps = 1e-3 * m.K * v_ref / (m.Ra * m.B + m.K**2)
    # the drop's sign smoothed over a band far below any logged current: wider, the
    # band lets a current flow where none can (a rotor braked at 0 V coasting below
    # the drop's back-emf), whose torque would read as friction
    i_eps = 1e-7 * v_ref / m.Ra
    if spec.initial == "rest":
        x0 = np.zeros(5)
    else:
        if spec.initial == "steady":
            ia, w = steady_point(m, segs[0][2], segs[0][3], m.extra_load.get(spec.name,
                                                                               (0.0, 0.0)))
        else:
            ia, w = spec.initial
        x0 = np.array([ia, w, w, 0.0, ia])
    dt = end / max(t.size - 1, 1)
    shifted = np.maximum(t - spec.delay, 0.0)
    ia, _, ws, th, ias = integrate(m, spec.name, shifted, segs, x0, w_eps, i_eps, dt)
    out = {"time": t, "speed": rig.speed_gain * ws + rig.speed_offset,
           "current": rig.current_gain * ias + rig.current_offset}
    if spec.encoder is not None:
        q = 2.0 * np.pi / spec.encoder[0]
        fine = None
        if spec.encoder[1] == "edges":
            t_fine = np.linspace(0.0, end, (t.size - 1) * EDGE_FINE + 1)
            fine = (t_fine, integrate(m, spec.name, t_fine, segs, x0, w_eps, i_eps, dt)[3])
        if spec.encoder[1] == "speed":
            counts = np.floor(th / q + 1e-9)
            out["speed"] = np.concatenate([[0.0], np.diff(counts)]) * (q * spec.rate)
        else:
            parts = encoder_trace_parts(spec.encoder[1], t, th, q, fine)
            out.update(time=parts["time"], position=parts["position"], speed=None,
                       direction=parts.get("direction"))
            if spec.encoder[1] == "edges":
                out["current"] = None
    return out
