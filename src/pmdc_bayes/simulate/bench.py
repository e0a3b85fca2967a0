"""A non-ideal bench: in-memory sessions from a motor richer than the fitted model.

The motor (state ``ia`` A, ``ω`` rad/s; inputs ``Va`` V, ``TL`` N·m)::

    La·dia/dt = Va − Ra·ia − K·ω
    J·dω/dt   = K·ia − B·ω − Tc·sign(ω) − TL

is integrated with :func:`scipy.integrate.solve_ivp` (LSODA, ``rtol=1e-8``), independently
of :mod:`pmdc_bayes.physics`, with the non-idealities of real benches switched on one by
one in :class:`BenchMotor`: dead time, sensor lag, brush drop, supply source
resistance, a current-limited driver, one that opens the armature at a zero command,
undeclared load, speed-sensor gain error and an encoder-based speed estimate.  The
session declares only the ideal inputs: a fit of the ideal model is misspecified.

Smoothing: ``sign(ω)`` is ``tanh(ω/ω_eps)`` with ``ω_eps`` = 1e-3 × the no-load speed at
the largest voltage of the session, blended with static friction so that a motor at rest
whose driving torque ``|K·ia − TL|`` is below the Coulomb torque stays exactly at rest;
``sign(ia)`` of the brush drop (and of an open armature's freewheel voltage) is
``tanh(ia/i_eps)``, ``i_eps`` = 1e-4 × the stall current ``V/Ra`` (the full drop acts
in steady state; below the drop's back-emf a current of about ``i_eps`` flows: a plan's
``[rig]`` narrows the band to 1e-7 × the stall current).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.session import Drag, Measurement, Schedule, Session, SteadyTable, Trace
from ..physics.load import curve_arrays, curve_tangent
from ._encoder import EDGE_FINE, encoder_trace_parts
from ._lsoda import integrate

__all__ = ["BenchMotor", "StepSpec", "bench_session", "steady_point", "integrate"]


@dataclass(frozen=True)
class BenchMotor:
    """A motor on a bench: true parameters, non-idealities and sensor noise (SI).

    Attributes
    ----------
    Ra, La, K, B, J, Tc : float
        Armature resistance (Ω), inductance (H), torque/back-emf constant (N·m/A),
        viscous friction (N·m·s/rad), inertia (kg·m²) and Coulomb friction (N·m).
    dead_time : float
        The motor sees the commanded voltage step this late (s).
    speed_lag : float
        Time constant (s) of a first-order low-pass between the true and logged speed.
    current_lag : float
        The same between the true and logged current.
    voltage_drop : float
        A constant voltage drop opposing the current (V): ``Va − voltage_drop·sign(ia)``.
    source_resistance : float
        Resistance of the supply (Ω): the logged voltage is the supply's open-circuit
        voltage, the motor sees ``Va − source_resistance·ia``.
    current_limit : float or None
        The driver lowers its output voltage so that ``|ia|`` never exceeds this (A):
        a current loop that pulls ``ia`` to the limit with time constant 1e-3·La/Ra.
    freewheel_voltage : float
        Nonzero: the driver opens the armature at a zero command, its current then
        returning through diodes against this voltage (V) until it stops.
    speed_gain : float
        Multiplicative calibration error of the speed sensor.
    encoder_counts_per_rev : int or None
        If set, the logged speed is the backward difference of the angle quantised to
        ``2π/counts`` (counted down with ``floor``), divided by the sample interval.
        The encoder replaces the analogue sensor: no speed noise is added.
    encoder_output : str
        What the encoder trace logs (:data:`~._encoder.ENCODER_OUTPUTS`): ``"speed"``
        (the differenced counts above), ``"position"`` (the counted angle at each
        sample, no speed), ``"edges"`` (one sample per edge at its time, to 1 µs,
        after an unread first sample at rest; both ways, each edge on the count
        boundary crossed).
    extra_load : dict
        Trace name -> ``(constant N·m, viscous N·m·s/rad)``, or a
        :class:`~pmdc_bayes.io.session.Drag` with a curved part: load the session does not
        declare.  The constant part is a drag opposing the motion (it acts like extra
        Coulomb friction, so it cannot turn a motor at rest); the viscous part adds to B.
    speed_noise, current_noise : float
        Standard deviations of white Gaussian noise on the logged speed (rad/s) and
        current (A).
    """

    Ra: float
    La: float
    K: float
    B: float
    J: float
    Tc: float = 0.0
    dead_time: float = 0.0
    speed_lag: float = 0.0
    current_lag: float = 0.0
    voltage_drop: float = 0.0
    source_resistance: float = 0.0
    current_limit: float | None = None
    freewheel_voltage: float = 0.0
    speed_gain: float = 1.0
    encoder_counts_per_rev: int | None = None
    encoder_output: str = "speed"
    extra_load: dict = field(default_factory=dict)
    speed_noise: float = 0.05
    current_noise: float = 0.002


@dataclass(frozen=True)
class StepSpec:
    """One logged voltage step from rest.

    Attributes
    ----------
    name : str
        Trace name (also its nominal file name, ``name + ".csv"``).
    voltage : float
        Commanded voltage after the step (V); 0 V before ``t_step``.
    duration, dt : float
        Length of the record and sample interval (s); samples at ``0, dt, …``.
    t_step : float
        Time of the commanded step within the trace (s).
    load : float
        Declared constant load torque (N·m), signed as in the fitted model.
    log_current : bool
        Whether the trace has a current channel.
    """

    name: str
    voltage: float
    duration: float
    dt: float
    t_step: float = 0.0
    load: float = 0.0
    log_current: bool = True


def steady_point(motor: BenchMotor, voltage: float, load: float = 0.0,
                 drag: tuple = (0.0, 0.0)) -> tuple[float, float]:
    """True steady ``(ia, ω)`` (A, rad/s) of the motor at a constant voltage.

    Parameters
    ----------
    motor : BenchMotor
    voltage : float
        Commanded voltage (V).
    load : float
        Signed load torque (N·m).
    drag : (float, float) or Drag
        Extra ``(constant, viscous)`` drag, as in ``BenchMotor.extra_load``; a curved part
        is solved by Newton steps on its tangent.

    Returns
    -------
    (float, float)
        Current and speed, with the drop, Coulomb friction and limit (sign unsmoothed).

    Notes
    -----
    Forward: ``ω = (K·(Va − drop) − R·(TL + Tc))/(R·B + K²)``, ``ia = (B·(Va − drop) +
    K·(TL + Tc))/(R·B + K²)``, ``R = Ra + source_resistance``, ``Tc`` and ``B`` with the
    drag; the reverse by symmetry; at rest (``ia = (Va − drop·sign Va)/R``, 0 if
    ``|Va| ≤ drop``) when ``|K·ia − TL| ≤ Tc``; a current past the limit held at it.
    """
    d = Drag(*drag)
    if not d.curved:
        return _steady_affine(motor, voltage, load, d.constant, d.viscous)
    q, kw, kt = (a[0] for a in curve_arrays([d]))
    w = 0.0
    for _ in range(60):
        slope, t0 = curve_tangent(w, q, kw, kt)
        ia, w_new = _steady_affine(motor, voltage, load + t0, d.constant, d.viscous + slope)
        if abs(w_new - w) <= 1e-13 * max(abs(w_new), 1.0):
            break
        w = w_new
    return ia, w_new


def _steady_affine(m: BenchMotor, voltage: float, load: float, tc_extra: float,
                   b_extra: float) -> tuple[float, float]:
    tc, b, r = m.Tc + tc_extra, m.B + b_extra, m.Ra + m.source_resistance
    den = r * b + m.K**2
    w, ia = 0.0, math.copysign(max(abs(voltage) - m.voltage_drop, 0.0), voltage) / r
    if abs(m.K * ia - load) > tc:  # it turns: take the direction of the driving torque
        s = math.copysign(1.0, m.K * ia - load)
        v = voltage - s * m.voltage_drop
        w, ia = (m.K * v - r * (load + s * tc)) / den, (b * v + m.K * (load + s * tc)) / den
    lim = m.current_limit
    if lim is not None and abs(ia) > lim:
        ia = math.copysign(lim, ia)
        net = m.K * ia - load
        w = 0.0 if abs(net) <= tc or b == 0 else (net - math.copysign(tc, net)) / b
    return ia, w


def _integrate(m: BenchMotor, spec: StepSpec, t: np.ndarray, w_eps: float, i_eps: float):
    """A step trace's states at ``t``: at rest until the voltage reaches the motor
    (``t_step + dead_time``), then at the step's voltage."""
    t_on, t_end = spec.t_step + m.dead_time, float(t[-1])
    segments = ((0.0, min(t_on, t_end), 0.0, spec.load), (t_on, t_end, spec.voltage, spec.load))
    return integrate(m, spec.name, t, segments, np.zeros(5), w_eps, i_eps, spec.dt)


def _trace(m: BenchMotor, spec: StepSpec, rng: np.random.Generator, w_eps: float,
           i_eps: float) -> Trace:
    n = int(round(spec.duration / spec.dt)) + 1
    if n < 3 or not 0 <= spec.t_step < spec.duration:
        raise ValueError(f"trace {spec.name!r}: need duration >= 2·dt and "
                         "0 <= t_step < duration")
    t = np.arange(n) * spec.dt
    _, _, ws, th, ia = _integrate(m, spec, t, w_eps, i_eps)
    speed_noise = rng.standard_normal(n)
    current_noise = rng.standard_normal(n)
    volts = (Schedule(np.array([0.0, spec.t_step]), np.array([0.0, float(spec.voltage)]))
             if spec.t_step > 0 else Schedule(np.array([0.0]), np.array([float(spec.voltage)])))
    load = Schedule(np.array([0.0]), np.array([float(spec.load)]))
    if m.encoder_counts_per_rev and m.encoder_output != "speed":
        q = 2.0 * np.pi / m.encoder_counts_per_rev
        fine = None
        if m.encoder_output == "edges":
            t_fine = np.arange((n - 1) * EDGE_FINE + 1) * (spec.dt / EDGE_FINE)
            fine = (t_fine, _integrate(m, spec, t_fine, w_eps, i_eps)[3])
        parts = encoder_trace_parts(m.encoder_output, t, th, q, fine)
        current = ia + m.current_noise * current_noise if spec.log_current else None
        if m.encoder_output == "edges":
            current = None
        return Trace(spec.name, "step", Path(spec.name + ".csv"), parts["time"],
                     parts["speed"], current, volts, load, initial="rest",
                     position=parts["position"], speed_logged=False, encoder_step=q)
    if m.encoder_counts_per_rev:
        q = 2.0 * np.pi / m.encoder_counts_per_rev
        counts = np.floor(th / q + 1e-9)
        speed = m.speed_gain * np.concatenate([[0.0], np.diff(counts)]) * (q / spec.dt)
    else:
        speed = m.speed_gain * ws + m.speed_noise * speed_noise
    current = ia + m.current_noise * current_noise if spec.log_current else None
    return Trace(spec.name, "step", Path(spec.name + ".csv"), t, speed,
                 current, volts, load, initial="rest")


def bench_session(motor: BenchMotor, steps: Sequence[StepSpec], *, seed: int = 0,
                  Ra_bench: tuple[float, float] | None = None,
                  La_bench: tuple[float, float] | None = None,
                  steady_voltages: Sequence[float] = (),
                  friction: str = "viscous", name: str = "bench") -> Session:
    """A session logged on a non-ideal bench.

    Parameters
    ----------
    motor : BenchMotor
        The true motor, its non-idealities and the sensor noise.
    steps : sequence of StepSpec
        The logged step traces (at least one with a current for the closed form).
    seed : int
        Seed of all the noise: ``numpy.random.default_rng(seed)`` spawns one stream for
        the bench values, one per trace and one for the steady table.
    Ra_bench, La_bench : (value, sd) or None
        The session's bench measurements of Ra (Ω) and La (H).  By default the true
        value plus Gaussian noise of 3 % (Ra) or 10 % (La), with that sd.
    steady_voltages : sequence of float
        If given, a steady table ``"steady"`` of unloaded speed and current at these
        voltages (brush drop, Coulomb friction, current limit and speed gain applied;
        extra load, lag and encoder not), each value with 0.3 % relative noise.
    friction : str
        The session's friction model, ``"viscous"`` or ``"coulomb"``.
    name : str
        Session name.

    Returns the :class:`Session`, with ``truth`` the true ``Ra, La, K, B, J, Tc``; its
    traces declare only the commanded voltage and the declared load.  Raises
    ``ValueError`` for duplicate trace names, ``extra_load`` naming no trace, or a bad step.
    """
    m, steps = motor, tuple(steps)
    names = [s.name for s in steps]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate trace names in {names}")
    if unknown := set(m.extra_load) - set(names):
        raise ValueError(f"extra_load names no trace: {sorted(unknown)}")
    v_ref = max([abs(s.voltage) for s in steps] + [abs(v) for v in steady_voltages] + [1e-9])
    w_eps = 1e-3 * m.K * v_ref / (m.Ra * m.B + m.K**2)
    i_eps = 1e-4 * v_ref / m.Ra
    bench_rng, table_rng, *trace_rngs = np.random.default_rng(seed).spawn(2 + len(steps))
    z_ra, z_la = bench_rng.standard_normal(2)
    ra = Ra_bench or (m.Ra * (1 + 0.03 * z_ra), 0.03 * m.Ra)
    la = La_bench or (m.La * (1 + 0.10 * z_la), 0.10 * m.La)
    traces = tuple(_trace(m, s, r, w_eps, i_eps) for s, r in zip(steps, trace_rngs,
                                                                  strict=True))
    tables = ()
    if len(steady_voltages):
        v = np.asarray(steady_voltages, dtype=float)
        ia, w = np.array([steady_point(m, float(x)) for x in v]).T
        w = m.speed_gain * w * (1 + 0.003 * table_rng.standard_normal(v.size))
        ia = ia * (1 + 0.003 * table_rng.standard_normal(v.size))
        tables = (SteadyTable("steady", Path("steady.csv"), v, w, ia, np.zeros(v.size)),)
    truth = {k: float(getattr(m, k)) for k in ("Ra", "La", "K", "B", "J", "Tc")}
    return Session(name=name, root=Path("."), motor="simulated bench motor",
                   Ra=Measurement(float(ra[0]), float(ra[1]), "ohm", "bench"),
                   La=Measurement(float(la[0]), float(la[1]), "H", "bench"),
                   friction=friction, steady_tables=tables, traces=traces, truth=truth)
