"""A trace's inputs as session.toml gives them: a schedule of ``[time, value]`` pairs
checked against the samples (on their clock, within their span), and a voltage logged
as a PWM duty read as the armature voltage."""

from __future__ import annotations

import numpy as np

from .._errors import SessionError
from .position import edges_flag
from .robust import AT_REST, CONSECUTIVE, difference_sd
from .session import Schedule
from .toml_tables import Table as _Table
from .toml_tables import describe as _describe
from .units import to_si, unit_factor

__all__ = ["schedule", "duty_scale", "duty_to_volts", "signed_voltage", "signed_current",
           "signed_speed",
           "DUTY_UNITS", "SUPPLY"]

DUTY_UNITS = {"1": 1.0, "%": 100.0}  # a voltage logged as a duty: its full scale
SUPPLY = "supply_voltage"  # the key a duty is read against
SIGNED_NOISE = 5.0  # a magnitude column's noise reads below zero by less than this many sds


def schedule(t: _Table, key: str, u: dict, kind: str, t_raw: np.ndarray, start: float,
              duty=None) -> Schedule:
    """A ``[[time, value], ...]`` schedule in the trace's units, checked against the samples
    (``start``: the file's first row's time, before rows missing a reading were left out;
    a voltage logged as a duty of ``duty``'s supply when given)."""
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
    inside = [v for tk, v in zip(times, values, strict=True) if tk <= t_raw[-1]]
    later = [tk for k, tk in enumerate(times) if tk > t_raw[-1] and values[k] != inside[-1]]
    if len(set(inside)) == 1 and later:
        t.fail(key, f"the {key} changes at {later[0]:g} {tu}, after the last sample at "
               f"{t_raw[-1]:g} {tu}, and is constant over the samples; check the schedule's "
               "times (they are in the trace's time unit)")
    changes = [tk for k, tk in enumerate(times) if k and values[k] != values[k - 1]]
    if changes and changes[-1] < start and not edges_flag(t):  # an edge comes after a step
        t.fail(key, f"the {key} changes last at {changes[-1]:g} {tu}, before the first row "
               f"at {start:g} {tu}, and is constant over the samples; write the "
               "schedule's times on the time column's clock (a time column that does not "
               "start at 0 is read as written)")
    per_second = 1.0 / unit_factor("time", tu)  # 1000 for ms
    if (changes and t_raw.size > 10 and not edges_flag(t) and per_second > 1.5
            and all(t_raw[0] < tk < t_raw[1] for tk in changes)
            and all(t_raw[1] < tk * per_second < t_raw[-1] for tk in changes)):
        t.fail(key, f"the {key} changes only at {changes[0]:g} {tu}, between the first two "
               f"samples ({t_raw[0]:g} and {t_raw[1]:g} {tu}): is the schedule written in "
               f"seconds? Its times are in the trace's time unit ({tu}, units.time); write "
               f"{changes[0] * per_second:g} for {changes[0]:g} s")
    values = (duty_to_volts(t, key, np.array(values), duty) if duty is not None
              else to_si(np.array(values), kind, u[key]))
    return Schedule(to_si(np.array(times), "time", tu), values)


def duty_scale(t: _Table, u: dict) -> tuple[float, float] | None:
    """``(supply voltage, full scale)`` when the trace's voltage is logged as a duty (a
    fraction, a percentage, or PWM counts of ``pwm_full_scale``) of ``supply_voltage``;
    None when it is a voltage."""
    duty_unit = u["voltage"] in (*DUTY_UNITS, "pwm")
    if SUPPLY not in t.data:
        if duty_unit:
            t.fail(SUPPLY, f"the voltage is logged as a duty (units.voltage = "
                   f"\"{u['voltage']}\") but no supply_voltage is given; add the driver's "
                   "supply, e.g. supply_voltage = 12.0")
        if "pwm_full_scale" in t.data:
            t.fail("pwm_full_scale", "is only read with a voltage logged as PWM counts; set "
                   "units.voltage = \"pwm\" and supply_voltage, or remove it")
        return None
    if not duty_unit:
        t.fail(SUPPLY, "is only read with a voltage logged as a duty; set "
               "units.voltage = \"%\", \"1\" (a fraction) or \"pwm\" (with pwm_full_scale), "
               "or remove supply_voltage")
    supply = t.number(SUPPLY, "voltage", u[SUPPLY], positive=True)
    if u["voltage"] == "pwm":
        return supply, t.number("pwm_full_scale", positive=True)
    if "pwm_full_scale" in t.data:
        t.fail("pwm_full_scale", "is only read with units.voltage = \"pwm\"; remove it or "
               "set that unit")
    return supply, DUTY_UNITS[u["voltage"]]


def duty_to_volts(t: _Table, where: str, duty: np.ndarray, scale) -> np.ndarray:
    """A duty (in its unit, signed for a reversing bridge) as the mean armature voltage."""
    supply, full = scale
    worst = float(np.max(np.abs(duty))) if duty.size else 0.0
    if worst > full * (1 + 1e-9):
        t.fail(where, f"a duty of {worst:g} is beyond full scale ({full:g}); check "
               "units.voltage (\"1\" for a fraction, \"%\", or \"pwm\" with pwm_full_scale)")
    return duty / full * supply


def _first_negative(values: np.ndarray) -> int | None:
    """The first row where a column reads below zero by more than :data:`SIGNED_NOISE`
    sds of its noise and :data:`AT_REST` of its largest reading (more than a measured
    magnitude's zero offset), or None: the column is a magnitude."""
    top = float(np.nanmax(np.abs(values))) if np.isfinite(values).any() else 0.0
    below = np.nonzero(values < -max(SIGNED_NOISE * difference_sd(values), AT_REST * top))[0]
    return int(below[0]) if below.size else None


def signed_voltage(path, voltage: np.ndarray, signs: np.ndarray, lines) -> np.ndarray:
    """A voltage column logged as a magnitude (a driver's PWM and direction pins: a duty,
    or a voltage, and a direction bit) signed by the trace's direction column's ``signs``
    (:func:`.position.direction_signs`).  A column signed already (it reads below zero
    beyond a magnitude's offset) is refused, with its line (``lines``: each row's), as
    the two would disagree on the sign."""
    v = np.asarray(voltage, dtype=float)
    k = _first_negative(v)
    if k is not None:
        raise SessionError(path, f"the voltage column reads {v[k]:g} V here: it is signed "
                           "already, where a direction column gives the sign of a voltage "
                           "logged as a magnitude; remove columns.direction from "
                           "session.toml (or log the magnitude)", where=f"line {lines[k]}")
    return np.abs(v) * signs


def signed_current(current: np.ndarray, signs: np.ndarray, voltage: np.ndarray) -> np.ndarray:
    """A current column beside a driver's direction bit: a magnitude (a driver's current
    sense, which reads the same whichever way the motor is driven) signed by ``signs``
    where ``voltage`` (the signed levels the driver held, at each sample) drives the
    motor, and against the direction last driven for :data:`~.robust.CONSECUTIVE` rows
    or more where it is at rest (within :data:`AT_REST` of its largest: the driver
    shorts the armature, and the motor, still turning that way, brakes).  A column that
    reads negative where the motor is driven backwards (its median there), or, with no
    such rows, below zero beyond a magnitude's offset, reads both ways, and is kept as
    it is.  A magnitude cannot show a current running against a voltage it keeps the
    sign of (a step down's regeneration); it is signed with the voltage there."""
    i = np.asarray(current, dtype=float)
    v = np.asarray(voltage, dtype=float)
    top = float(np.nanmax(np.abs(v))) if np.isfinite(v).any() else 0.0
    driven = np.abs(v) > AT_REST * top
    backwards = driven & (v < 0)
    if (np.nanmedian(i[backwards]) < 0 if backwards.any() else _first_negative(i) is not None):
        return i
    held = driven.copy()  # a level driven for CONSECUTIVE rows, not a glitch
    for lag in range(1, CONSECUTIVE):
        held[lag:] &= driven[:-lag]
    last = np.maximum.accumulate(np.where(held, np.arange(v.size), 0))
    braking = np.where(held[last], -np.sign(v[last]), signs)
    return np.abs(i) * np.where(driven, np.sign(v), braking)


def signed_speed(speed: np.ndarray, time: np.ndarray, inputs: dict) -> np.ndarray:
    """A logged speed that reads a magnitude (a tachometer or a one-channel Hall sensor),
    signed.  It is one where the motor is driven both ways (a voltage held beyond rest
    each way for :data:`~.robust.CONSECUTIVE` rows or more) and the speed never reads
    below zero beyond a magnitude's offset, yet shows the rotor turning backwards: driven
    backwards, its reading rises (from rest, or after falling: a rotor turning forward
    can only slow down while the voltage is below zero, so the rise is its turn).  A
    trace driven one way is kept as logged: there a magnitude and a sensor wired
    against the voltage read alike, which the session's checks refuse, naming both.
    Signed, the rotor turns the way first driven and takes each new direction at the
    slowest reading between the end of the drive before and the end of this one.  Kept
    as logged where a load is declared (a load may turn the rotor against its
    voltage)."""
    w = np.asarray(speed, dtype=float)
    v = inputs["voltage"].at(time)
    if _first_negative(w) is not None or np.any(inputs["load_torque"].values != 0):
        return w
    top = float(np.nanmax(np.abs(v))) if np.isfinite(v).any() else 0.0
    held = np.abs(v) > AT_REST * top
    for lag in range(1, CONSECUTIVE):
        held[lag:] &= held[:-lag]
    at = np.flatnonzero(held)
    if at.size == 0:
        return w
    signs = np.sign(v[at])
    if not (np.any(signs > 0) and np.any(signs < 0)):
        return w  # driven one way: a magnitude and a sensor wired against it read alike
    turns = np.flatnonzero(signs[1:] != signs[:-1]) + 1  # the first row of each new drive
    starts = np.append(0, turns)
    ends = np.append(at[turns - 1], at[-1])  # each drive's last row
    slow = np.where(np.isfinite(w), np.abs(w), np.inf)
    if not any(_turned(w, slow, at[a], end) for a, end in zip(starts, ends, strict=True)
               if signs[a] < 0):
        return w
    sense = np.full(w.size, signs[0])
    for j, end in zip(turns, ends[1:], strict=True):
        lo = at[j - 1]
        k = lo + int(np.argmin(slow[lo:end + 1]))
        sense[k:] = signs[j]
    return w * sense


def _turned(w, slow, first: int, last: int) -> bool:
    """Whether a positive reading of a drive backwards (rows ``first`` to ``last``) shows
    the rotor turning backwards: it rises, after its slowest, by a tenth of the record's
    largest reading and :data:`SIGNED_NOISE` sds of its noise."""
    k = first + int(np.argmin(slow[first:last + 1]))
    after = slow[k:last + 1]
    after = after[np.isfinite(after)]
    top = float(np.nanmax(np.abs(w)))
    rise = float(after.max() - slow[k]) if after.size else 0.0
    return rise > max(0.1 * top, SIGNED_NOISE * difference_sd(w))
