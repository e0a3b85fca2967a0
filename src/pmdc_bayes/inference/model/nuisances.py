"""The rig's non-idealities as fitted parameters: their registry entries.

``nuisance_specs`` lists what ``[model]`` (``session.nuisances``) asks for (a trace's own
starting state is in :mod:`.trace_states`).  :class:`~.effects.RigEffects` applies them
in the prediction.
"""

from __future__ import annotations

import numpy as np

from ...io.session import Session
from ...physics.regimes import NO_LIMIT
from .coloured import ar_specs
from .column_levels import level_specs
from .params import ParamSpec, Prior, identifier
from .switch_lead import lead_specs

__all__ = ["nuisance_specs", "dead_time_name", "load_names", "open_data", "OPEN_VOLTS",
           "DEAD_TIME_PRIOR", "DROP_PRIOR", "LAG_PRIOR_SAMPLES", "LAG_PRIOR_FACTOR",
           "NO_LIMIT", "DEAD_ZONE_NAMES", "sensor_readings"]

DEAD_TIME_PRIOR = 0.05  # sd of a trace's dead time, as a share of the trace's length
DROP_PRIOR = 0.1  # sd of the voltage drop, as a share of the session's largest voltage
DROP_START = 0.1  # a drop's least seed (no intercept, or a tiny one), as a share of that sd
LAG_PRIOR_SAMPLES = 3.0  # centre of a sensor lag's prior, in sample intervals
LAG_PRIOR_FACTOR = 30.0  # its one-sd width (a factor)
LOAD_PRIOR_SHARE = 0.3  # centre of an unknown drag's prior, as a share of the motor's own
LOAD_PRIOR_FACTOR = 30.0  # its one-sd width (a factor)
OPEN_VOLTS = 2.0  # an open armature's freewheel voltage, as a multiple of the largest
# voltage: the supply's and the diodes' (which stops the current within a fraction of
# La/Ra and lets none flow while the back-emf stays below it)
GAIN_PRIOR = 0.1  # sd of a sensor gain's logarithm (a calibration 10 % off at one sd)
SOURCE_PRIOR = 0.1  # centre of a source resistance's prior, as a share of the bench Ra
SOURCE_PRIOR_FACTOR = 10.0  # its one-sd width (a factor): 1e-3 to 10 x Ra within 2 sd
OFFSET_PRIOR = 0.05  # sd of a sensor offset, as a share of the channel's largest reading
LIMIT_PRIOR_FACTOR = 3.0  # one-sd width (a factor) of an unknown current limit's prior
LIMIT_SETTING_SD = 0.05  # sd of the limit's logarithm around a driver setting the user gave
CALIBRATION = {"speed_gain": ("speed", "gain"), "speed_offset": ("speed", "offset"),
               "current_gain": ("current", "gain"), "current_offset": ("current", "offset")}


def dead_time_name(trace_name: str, shared: bool = False) -> str:
    """The parameter name of a trace's dead time: ``dead_time`` when the session's
    traces share one (``session.shared_dead_time``)."""
    return "dead_time" if shared else f"dead_time_{identifier(trace_name)}"


def load_names(trace_name: str) -> tuple[str, str]:
    """The parameter names of a trace's unknown drag: constant (N·m), viscous."""
    return f"load_{identifier(trace_name)}", f"drag_{identifier(trace_name)}"


def _load_specs(session: Session, b_seed: float) -> list[ParamSpec]:
    """Per trace ``unknown_load`` names, ``load_<trace>`` (N·m), a friction-like constant
    drag (a brake, a rubbing coupling), and ``drag_<trace>`` (N·m·s/rad), a viscous one
    (an eddy-current brake, a generator into a resistor); only the one the session asks
    for when it names the trace's kind (``session.load_kind``), the other then zero.
    Priors log-normal (a drag is positive), a factor :data:`LOAD_PRIOR_FACTOR` wide,
    centred on :data:`LOAD_PRIOR_SHARE` of the motor's seeded viscous drag, as a torque
    at the trace's top speed for the constant part."""
    specs = []
    for tr in session.traces:
        if tr.name not in session.unknown_load_traces():
            continue
        w_top = max(float(np.max(np.abs(tr.speed))), 1e-9)
        load, drag = load_names(tr.name)
        kind = session.load_kind(tr.name)
        for name, unit, centre, what in (
                (load, "N*m", LOAD_PRIOR_SHARE * b_seed * w_top, "constant"),
                (drag, "N*m*s/rad", LOAD_PRIOR_SHARE * b_seed, "viscous")):
            if kind not in ("both", what):
                continue
            specs.append(ParamSpec(name, unit, "trace",
                                   Prior("lognormal", centre, float(np.log(LOAD_PRIOR_FACTOR)),
                                         "nuisance"), centre,
                                   description=f"unknown {what} drag on trace {tr.name!r}",
                                   trace=tr.name))
    return specs


def nuisance_specs(session: Session, drop_seed: float = 0.0,
                   b_seed: float = 0.0) -> list[ParamSpec]:
    """The rig's non-idealities the session asks to fit (``session.nuisances``):

    * ``voltage_drop`` — ``Vdrop`` (V), a constant drop at the brushes and driver
      opposing the current (no current while the back-emf is within it), positive
      (log-transformed: a drop below zero would drive the current); prior half-normal,
      sd :data:`DROP_PRIOR` × the largest voltage; seeded at ``drop_seed``, or at
      :data:`DROP_START` × that sd where the session gives no positive one;
    * ``dead_time`` — per trace ``dead_time_<trace>`` (s), or one ``dead_time`` for all
      traces (``session.shared_dead_time``), the delay between the logged command and
      the response; prior normal, centre 0, sd :data:`DEAD_TIME_PRIOR` × the trace's
      length (a negative value is a response that leads its logged command: a clock or
      trigger offset).

    * ``speed_lag``, ``current_lag`` — the time constant (s) of a first-order lag in
      the speed or current sensor (a tachometer, a filter); prior log-normal centred on
      :data:`LAG_PRIOR_SAMPLES` sample intervals, a factor :data:`LAG_PRIOR_FACTOR` wide
      (one sd), log-transformed (a lag is positive).

    * ``switch_lead_<trace>_<j>`` — not asked for: each change of a trace whose
      switching inputs come from logged columns (:mod:`.switch_lead`), how long before
      the first sample showing it the change happened (``switch_lead_<trace>``, one for
      all, where the trace changes once or more than 16 times).

    * ``voltage_level_<trace>_<j>``, ``load_level_<trace>_<j>`` — not asked for: each
      level a noisy logged input column held (:mod:`.column_levels`), known from its
      readings to their standard error.

    * ``unknown_load`` — per loaded trace a constant and a viscous drag (see
      :func:`_load_specs`; ``b_seed`` is the motor's seeded viscous friction).

    * ``source_resistance`` — ``Rs`` (Ω), the resistance between the logged voltage
      (the supply's) and the terminals, positive (log-transformed); prior log-normal,
      centred on :data:`SOURCE_PRIOR` × the bench Ra, a factor
      :data:`SOURCE_PRIOR_FACTOR` wide (one sd), so "none" (a thousandth of Ra) stays
      within two sd (the data and the bench Ra split the circuit's resistance between
      them).

    * ``speed_gain``, ``speed_offset``, ``current_gain``, ``current_offset`` — the
      traces' sensor calibration (see :func:`_calibration_specs`).

    * ``current_limit`` — ``Imax`` (A), the driver's current limit (see
      :func:`_limit_specs`).

    * ``dead_zone`` — ``Vdz_fwd`` and ``Vdz_rev`` (V), the widths of a driver's dead zone
      for positive and for negative commands (see :func:`_dead_zone_specs`).

    * ``open_at_zero`` — no parameter: the driver opens the armature at a zero command
      (:func:`open_data`).

    * ``coloured_noise`` — per analogue channel the lag-1 correlation of its noise
      (:func:`.coloured.ar_specs`).

    The dead times and the dead zone's widths are untransformed (they may be zero or of
    either sign).  The drop, the source resistance, the lags, the drags and the current
    limit are positive.
    """
    specs = _limit_specs(session)
    if "voltage_drop" in session.nuisances:
        sd = DROP_PRIOR * _largest_voltage(session)
        specs.append(ParamSpec("Vdrop", "V", "driver", Prior("half_normal", 0.0, sd, "nuisance"),
                               max(float(drop_seed), DROP_START * sd),  # not where a
                               # drop's effect, and so its gradient in log, vanishes
                               description="voltage drop at brushes and driver"))
    if "source_resistance" in session.nuisances:
        centre = SOURCE_PRIOR * session.Ra.value
        specs.append(ParamSpec("Rs", "ohm", "driver",
                               Prior("lognormal", centre, float(np.log(SOURCE_PRIOR_FACTOR)),
                                     "nuisance"), centre,
                               description="resistance of the supply, leads and driver"))
    dts = [float(np.median(np.diff(tr.time))) for tr in session.traces
           + session.coast_downs]
    for key, words in (("speed_lag", "speed sensor"), ("current_lag", "current sensor")):
        if key in session.nuisances and dts:
            centre = LAG_PRIOR_SAMPLES * min(dts)
            specs.append(ParamSpec(key, "s", "sensor",
                                   Prior("lognormal", centre, float(np.log(LAG_PRIOR_FACTOR)),
                                         "nuisance"), centre,
                                   description=f"first-order lag of the {words}"))
    if "dead_time" in session.nuisances:
        specs += _dead_time_specs(session)
    return (specs + _dead_zone_specs(session) + _load_specs(session, b_seed)
            + _calibration_specs(session) + ar_specs(session) + lead_specs(session)
            + level_specs(session))


DEAD_ZONE_NAMES = {1: ("Vdz_fwd", "positive"), -1: ("Vdz_rev", "negative")}


def _dead_zone_specs(session: Session) -> list[ParamSpec]:
    """``Vdz_fwd``, ``Vdz_rev`` (V): how much of a positive (negative) command the driver
    does not put out (:func:`~pmdc_bayes.physics.motor.driver_output`), one for each sign
    the session commands.  Prior normal, centre 0, sd :data:`DROP_PRIOR` × the largest
    voltage, the voltage drop's scale, but in value (a negative width is a driver that
    adds to its command)."""
    if "dead_zone" not in session.nuisances:
        return []
    volts = np.array([float(v) for tr in session.traces for v in tr.voltage.values]
                     + [float(v) for tab in session.steady_tables for v in tab.voltage]
                     + [op.voltage for op in session.operating_points]
                     + [r.voltage for r in session.step_readings])
    sd = DROP_PRIOR * _largest_voltage(session)
    return [ParamSpec(name, "V", "driver", Prior("normal", 0.0, sd, "nuisance"), 0.0,
                      transform="identity",
                      description=f"dead zone of the driver for {words} commands")
            for sign, (name, words) in DEAD_ZONE_NAMES.items()
            if np.any(np.sign(volts) == sign)]


def _dead_time_specs(session: Session) -> list[ParamSpec]:
    """A dead time per driven trace, or one shared by all (``session.shared_dead_time``),
    its prior's sd :data:`DEAD_TIME_PRIOR` × the (shortest) trace's length."""
    lengths = {tr.name: float(tr.time[-1] - tr.time[0]) for tr in session.traces}
    if session.shared_dead_time and lengths:
        return [ParamSpec("dead_time", "s", "driver",
                          Prior("normal", 0.0, DEAD_TIME_PRIOR * min(lengths.values()),
                                "nuisance"), 0.0, transform="identity",
                          description="dead time of every trace (one driver and logger)")]
    return [ParamSpec(dead_time_name(name), "s", "trace",
                      Prior("normal", 0.0, DEAD_TIME_PRIOR * length, "nuisance"), 0.0,
                      transform="identity", description=f"dead time of trace {name!r}",
                      trace=name) for name, length in lengths.items()]


def open_data(session: Session) -> dict:
    """The traces' data of a driver that opens the armature at a zero command
    (``open_at_zero``): ``open_volts``, :data:`OPEN_VOLTS` × the session's largest
    voltage, the drop its freewheel path sets against the current
    (:func:`~pmdc_bayes.physics.regimes.drop_at`); empty without one."""
    if "open_at_zero" not in session.nuisances:
        return {}
    return {"open_volts": np.float64(OPEN_VOLTS * _largest_voltage(session))}


def _largest_voltage(session: Session) -> float:
    volts = [abs(float(v)) for tr in session.traces for v in tr.voltage.values]
    volts += [abs(float(v)) for tab in session.steady_tables for v in tab.voltage]
    volts += [abs(op.voltage) for op in session.operating_points]
    return max(volts + [1.0])


def _limit_specs(session: Session) -> list[ParamSpec]:
    """``Imax`` (A), the level at which the driver holds the current (it lowers its
    voltage instead).  Prior log-normal: centred on the driver's setting when the user
    gave one, :data:`LIMIT_SETTING_SD` wide; otherwise on the largest logged current
    (a limited current sits at its limit), or, with no current logged, on half the
    largest voltage over the bench Ra, a factor :data:`LIMIT_PRIOR_FACTOR` wide."""
    if "current_limit" not in session.nuisances:
        return []
    if session.current_limit_setting is not None:
        centre, width, source = session.current_limit_setting, LIMIT_SETTING_SD, "driver setting"
    else:
        logged = [float(np.max(np.abs(tr.current))) for tr in session.traces
                  if tr.current is not None]
        centre = max(logged) if logged else 0.5 * _largest_voltage(session) / session.Ra.value
        width, source = float(np.log(LIMIT_PRIOR_FACTOR)), "nuisance"
    return [ParamSpec("Imax", "A", "driver", Prior("lognormal", centre, width, source),
                      centre, description="current limit of the driver")]


def sensor_readings(session: Session, signal: str) -> list[np.ndarray]:
    """What the traces' ``signal`` sensor ("speed" or "current") logged: each trace's
    readings, and for the speed each coast-down's (the same sensor)."""
    logged = [y for tr in session.traces
              if (y := (tr.speed if tr.speed_logged else None) if signal == "speed"
                  else tr.current) is not None]
    if signal == "speed":
        logged += [tr.speed for tr in session.coast_downs]
    return logged


def _calibration_specs(session: Session) -> list[ParamSpec]:
    """``speed_gain``, ``speed_offset``, ``current_gain``, ``current_offset``: the
    traces' sensor reads ``gain·x + offset`` of the true (lagged) signal.  A gain's
    prior is log-normal at 1, :data:`GAIN_PRIOR` wide; an offset's normal at 0, sd
    :data:`OFFSET_PRIOR` × the channel's largest logged reading."""
    specs = []
    for key, (channel, kind) in CALIBRATION.items():
        if key not in session.nuisances:
            continue
        logged = [np.abs(y) for y in sensor_readings(session, channel)]
        if not logged:
            continue
        unit = "rad/s" if channel == "speed" else "A"
        if kind == "gain":
            specs.append(ParamSpec(key, "1", "sensor",
                                   Prior("lognormal", 1.0, GAIN_PRIOR, "nuisance"), 1.0,
                                   description=f"calibration gain of the {channel} sensor"))
        else:
            top = max(float(np.max(y)) for y in logged)
            specs.append(ParamSpec(key, unit, "sensor",
                                   Prior("normal", 0.0, OFFSET_PRIOR * top, "nuisance"), 0.0,
                                   transform="identity",
                                   description=f"offset of the {channel} sensor"))
    return specs
