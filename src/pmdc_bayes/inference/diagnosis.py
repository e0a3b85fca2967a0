"""What an inadequate fit's pattern suggests, in words a bench user can act on.

Each rule reads the data and the MAP prediction:

* the **start** of each step: a channel that leaves rest
  clearly later than the model's, or a rise that a delayed or lagged shape fits far
  better on the data than on the model, means dead time or a sensor lag; a rise that
  is a ramp on the data but not on the model means a current-limited driver;
* a logged current with a **flat top** well below the model's peak: a current limit;
* the **steady levels** (:mod:`.levels`): a trace off the line the other levels draw
  means an unmeasured load on it; a speed-voltage line crossing zero speed well above
  0 V means a voltage drop (brushes, driver), a current left at zero speed means
  Coulomb friction;
* **anti-correlated noise** on a speed: a speed differenced from encoder counts;
* a **bench resistance** below or above the fitted one; and unit slips (a ratio of
  2π, 60/2π or 1000 between the data and the model).
"""

from __future__ import annotations

import numpy as np

from .checks import step_time
from .levels import LEVEL_MISS, friction_offset, level_outliers, voltage_intercept
from .noise import noise_scale
from .onset import departure, onset_shape

__all__ = ["diagnose"]

BETTER = 0.6  # a shape explains the onset when its error is below this share of the plain one
LATE_SAMPLES = 2  # a start later than the model's by at least this many samples ...
LATE_SHARE = 0.03  # ... and this share of the rise time counts as late
SLOW_START = 1.5  # fitted La/Ra this many times the bench's: something delays the start
DEPART = 5.0  # a channel has left rest when it is this many noise sd from its level ...
DEPART_SPAN = 0.01  # ... and this share of its span
UNIT_RATIOS = {"rpm given as rad/s": 60 / (2 * np.pi), "rad/s given as rpm": 2 * np.pi / 60,
               "rev/s given as rad/s": 1 / (2 * np.pi), "rad/s given as rev/s": 2 * np.pi,
               "mA given as A": 1000.0, "A given as mA": 1e-3,
               "a reversed sign (the speed counts the other way)": -1.0}
SLIP_TOLERANCE = 0.03


def _late_start(tr, y, yhat, s0, t_step, t_rise):
    """How much later than the model (s) the channel leaves rest, or None."""
    span = float(np.max(y) - np.min(y))
    threshold = max(DEPART * s0, DEPART_SPAN * span)
    d_obs = departure(tr.time, y, t_step, threshold)
    d_mod = departure(tr.time, yhat, t_step, threshold)
    if d_obs is None or d_mod is None:
        return None
    dt = float(np.median(np.diff(tr.time)))
    late = d_obs - d_mod
    return late if late >= LATE_SAMPLES * dt and late > LATE_SHARE * t_rise else None


def _start_rules(model, tr, pred, t_step):
    """Sentences on the start of a failing trace."""
    ia, w = pred
    out = []
    data, fitted = onset_shape(tr.time, tr.speed, t_step), onset_shape(tr.time, w, t_step)
    t_rise = fitted["t90"] if fitted else float(tr.time[-1] - t_step)
    lates = {}
    for what, y, yhat in (("speed", tr.speed, w), ("current", tr.current, ia)):
        if y is not None:
            late = _late_start(tr, np.asarray(y), np.asarray(yhat),
                               _noise(model, tr, what, y), t_step, t_rise)
            if late is not None:
                lates[what] = late
    lagged = ramp = False
    if data and fitted:
        dt = float(np.median(np.diff(tr.time)))
        lag_d = min(data["delayed"], data["lagged"])
        lagged = (lag_d < BETTER and lag_d < data["ramp"]
                  and data["dead_time"] - fitted["dead_time"] > max(LATE_SAMPLES * dt,
                                                                    LATE_SHARE * data["t90"]))
        ramp = (data["ramp"] < BETTER and data["ramp"] < lag_d
                and data["ramp"] < BETTER * fitted["ramp"])
    if lates or lagged:
        late = max(lates.values()) if lates else data["dead_time"] - fitted["dead_time"]
        if "current" in lates:
            out.append(f"{tr.name}: the current and speed start about {1e3 * late:.2g} ms "
                       "later than the model allows: add a dead time between the command "
                       "and the motion (driver, PWM start, logging trigger): --add dead-time, "
                       "or dead_time = true under [model] in session.toml (\"shared\" when "
                       "one driver and logger serve every trace)")
        elif tr.current is not None:
            out.append(f"{tr.name}: the speed starts about {1e3 * late:.2g} ms later than "
                       "the model allows while the current starts on time: a lag in the "
                       "speed sensor or its filter: --add speed-lag, or speed_lag = true "
                       "under [model] in session.toml")
        else:
            out.append(f"{tr.name}: the speed starts about {1e3 * late:.2g} ms later than "
                       "the model allows: add a dead time between the command and the "
                       "motion (--add dead-time), or a speed-sensor/filter lag "
                       "(--add speed-lag)")
    if ramp:
        out.append(f"{tr.name}: the speed ramps up at a constant rate for "
                   f"{1e3 * data['ramp_time']:.3g} ms before turning exponential: a "
                   "current-limited driver (a ramp instead of an exponential at the start): "
                   "--add current-limit, or current_limit = true (or the driver's limit in "
                   "A) under [model] in session.toml")
    return out


def _flat_top(tr, ia):
    if tr.current is None:
        return []
    top = float(np.max(np.abs(tr.current)))
    near = np.abs(np.abs(tr.current) - top) < 0.03 * top
    peak = float(np.max(np.abs(ia)))
    if near.sum() >= 5 and peak > 1.2 * top:
        return [f"{tr.name}: the logged current is flat at about {top:.3g} A while the model "
                f"would draw {peak:.3g} A: a current-limited driver: --add current-limit, "
                f"or current_limit = {top:.3g} under [model] in session.toml"]
    return []


def _unit_slips(ratios, outliers) -> dict[str, str]:
    """Traces whose settled speed is a unit ratio (or -1) times what the model or the
    other traces' levels imply: trace name -> the slip's label."""
    out = {}
    for name, r in ratios.items():
        seen = [r] + ([1 + outliers[name]] if name in outliers else [])
        for label, ratio in UNIT_RATIOS.items():
            if any(abs(x / ratio - 1) < SLIP_TOLERANCE for x in seen):
                out[name] = label
    return out


def _level_sentence(name: str, miss: float, against: str, alt: str = "") -> str:
    """A trace that settles ``miss`` (relative) off ``against``, in words."""
    where = f"{name}: settles {100 * abs(miss):.2g} % {'below' if miss < 0 else 'above'} {against}"
    if miss < 0:
        return (f"{where}: an unmeasured load on this trace (a brake, a generator, a rubbing "
                f"coupling){alt}; declare its load torque, or fit it: [model] unknown_load "
                f"= [{name!r}]")
    return (f"{where}: this trace turned more freely than the rest of the session says (a "
            "load on the other traces that this one lacks, a coupling removed), or its "
            "voltage was higher than the session says; check the bench and the voltage")


def _declared_drag_rules(session, ratios, slips) -> list[str]:
    """Traces with a declared drag that settle off the model's level: the drag declared
    too strong (the speed settles above) or too weak (below)."""
    out = []
    for tr in session.traces:
        r = ratios.get(tr.name)
        if not tr.drag.nonzero or r is None or tr.name in slips or abs(r - 1) <= LEVEL_MISS:
            continue
        way = "strong" if r > 1 else "weak"
        out.append(f"{tr.name}: settles {100 * abs(r - 1):.2g} % {'above' if r > 1 else 'below'}"
                   f" the model's speed under its declared drag: the drag is declared too "
                   f"{way} (check its curve, coefficients and units: the curve's speeds are in "
                   "the trace's speed unit, its torques in its load_torque unit)"
                   + ("" if r > 1 else ", or the trace carries a load beside it: [model] "
                      f"unknown_load = [{tr.name!r}]"))
    return out


def _level_rules(model, fit, preds, findings):
    """Sentences on the steady levels: unmeasured loads, unit slips, an offset."""
    session, out = model.session, []
    ratios = {}
    for tr, (_, w) in zip(session.traces, preds, strict=True):
        n_end = max(3, tr.n // 10)
        mod = float(np.mean(w[-n_end:]))
        if abs(mod) > 0:
            ratios[tr.name] = float(np.mean(tr.speed[-n_end:])) / mod
    outliers = level_outliers(session)
    if outliers is None:  # too few levels for a line: compare with the model instead
        declared = {tr.name for tr in session.traces if tr.drag.nonzero}  # said below
        misses = {k: r - 1 for k, r in ratios.items()
                  if abs(r - 1) > LEVEL_MISS and k not in declared}
        outliers = misses if len(misses) < len(ratios) else {}
        alt = ", or a voltage drop the other traces hide"
    else:
        alt = ""
    slips = _unit_slips(ratios, outliers)
    if slips and len(slips) == len(ratios) and len(set(slips.values())) == 1:
        label = next(iter(slips.values()))
        out.append(f"the logged speeds are {UNIT_RATIOS[label]:.4g} x what the rest of the "
                   f"session implies: a unit slip ({label}); check the units in session.toml")
    else:
        out += [f"{name}: its speed is {UNIT_RATIOS[label]:.4g} x what the rest of the "
                f"session implies: {label}; check this trace's units and sign in session.toml"
                for name, label in slips.items()]
    for name, m in outliers.items():
        if name in slips:
            continue
        out.append(_level_sentence(name, m, "the speed the other levels imply", alt))
    out += _declared_drag_rules(session, ratios, slips)
    icpt, offset = voltage_intercept(session), friction_offset(session)
    coulomb = (offset is not None and offset["current"] > 3 * offset["se"]
               and offset["current"] > 0.05 * offset["mean_current"])
    if coulomb and not model.coulomb:
        out.append(f"the steady current extrapolates to {offset['current']:.3g} A at zero "
                   "speed: a friction torque that does not grow with speed (Coulomb "
                   "friction); fit with --friction coulomb")
    elif (icpt and "Vdrop" in model.registry and any(
            f.where.startswith("steady") or f.where == "no-load speed"
            for f in findings if f.severity == "fail")):
        out.append("the steady levels miss the model even with a fitted voltage drop "
                   f"({float(fit.values['Vdrop']):.3g} V): the session's steady numbers "
                   "disagree with each other or with the traces (see the consistency "
                   "checks), or friction or load differ between them")
    elif (icpt and icpt["voltage"] > 3 * icpt["se"]
            and icpt["voltage"] > 0.01 * icpt["largest_voltage"]):
        why = ("" if model.coulomb or offset is not None
               else ", or Coulomb friction (try --friction coulomb)")
        out.append(f"the steady speed-voltage line crosses zero speed at "
                   f"{icpt['voltage']:.3g} V, not 0 V: a voltage drop at the brushes or "
                   f"driver (--add voltage-drop){why}")
    return out


def _finding_rules(model, fit, findings, already=()):
    out = []
    la, ra = model.registry["La"].prior, model.registry["Ra"].prior
    limited = any("current-limited" in text for text in already)  # explains a slow start
    if (la.source == "bench" and not limited and any(f.where == "La" and f.severity == "fail"
                                     for f in findings)):
        fitted = fit.values["La"] / fit.values["Ra"]
        bench = la.centre / ra.centre
        current = any(tr.current is not None for tr in model.session.traces)
        if fitted > SLOW_START * bench or (current and fitted > bench):
            out.append(f"the fit stretches the electrical time constant La/Ra to "
                       f"{1e3 * fitted:.2g} ms against {1e3 * bench:.2g} ms on the bench: the "
                       "response starts more slowly than the motor's inductance explains: a "
                       "dead time (--add dead-time) or a speed-sensor/filter lag "
                       "(--add speed-lag)" + (", or a current-sensor/filter lag "
                                              "(--add current-lag)" if current else ""))
    for f in findings:
        if f.severity != "fail":
            continue
        if f.check == "physical bound":
            out.append(f"{f.where} at its bound: {f.suggestion}")
        if f.check == "solver":
            out.append(f"{f.where}: the solution's limit, not necessarily the model's: "
                       f"{f.suggestion}")
        if f.check == "step start":
            sensor = f.where.rsplit(": ", 1)[-1]
            out.append(f"{f.where.split(':')[0]}: the model misses the start of the voltage "
                       "steps: the steps are earlier or later than the session says (a "
                       "logged voltage column, a trigger offset, a dead time): --add "
                       f"dead-time; or the {sensor} sensor lags: --add {sensor}-lag")
        if f.check == "residual whiteness" and f.where.endswith("current"):
            out.append(f"{f.where}: {f.message}: a ripple near half the sampling rate (a "
                       "PWM ripple aliased by the sampling) rather than white noise; filter "
                       "the current before sampling it, or average each sample over whole "
                       "PWM periods")
        if f.check == "residual whiteness" and f.where.endswith("speed"):
            out.append(f"{f.where}: {f.message}: a speed differenced from encoder counts or a "
                       "quantised position; log the encoder's count as the position "
                       "(columns.position, or edges = true) instead, or average over "
                       "more samples")
        if f.where == "Ra" and f.check in ("bench conflict", "plausibility"):
            if fit.values["Ra"] > model.registry["Ra"].prior.centre:
                out.append("the fitted resistance exceeds the bench Ra: a supply source "
                           "resistance, leads or a driver in the loop; log the terminal "
                           "voltage, or fit the source resistance: --add "
                           "source-resistance, or source_resistance = true under [model]")
            else:
                out.append("the fitted resistance is far below the bench Ra: the ideal motor "
                           "is absorbing something it lacks (a current limit, a voltage "
                           "drop, a lag); see the trace findings")
        if (f.where in ("K", "J", "B") and f.check == "bench conflict"
                and "speed_gain" not in model.session.nuisances
                and any(tr.speed_logged for tr in model.session.traces)):
            out.append(f"the fit puts {f.where} off its bench value: a speed sensor whose "
                       "calibration is off (a tachometer constant, a scale) scales K, J and B "
                       "together, which a bench value then contradicts; fit the sensor's "
                       "gain: --add speed-gain, or speed_gain = true under [model] (or check "
                       "the bench value)")
    return out


def _noise(model, tr, what, y) -> float:
    """The channel's model-free noise level; for a speed estimated from an angle (no
    speed channel), that of the estimate."""
    s0 = {c.name: c.s0 for c in model.channels}.get(f"{tr.name}: {what}")
    return s0 if s0 is not None else noise_scale(np.asarray(y))


def _still(model, tr):
    """A sentence when the speed of a driven trace never leaves its noise."""
    s0 = _noise(model, tr, "speed", tr.speed)
    volts = float(np.max(np.abs(tr.voltage.values)))
    if volts > 0 and np.ptp(tr.speed) < 2 * DEPART * s0:
        return [f"{tr.name}: the speed never leaves its noise although {volts:.3g} V is "
                "applied: the rotor was blocked, the driver off, or the column is not the "
                "speed; check the rig and the column, or remove the trace"]
    return []


def diagnose(model, fit, preds, findings) -> list[str]:
    """Sentences naming what the data suggest the model lacks, most specific first."""
    out = []
    for tr in model.session.traces:
        out += _still(model, tr)
    for tr, pred in zip(model.session.traces, preds, strict=True):
        # every trace, not only failing ones: a model that absorbs a delay in Ra and La
        # fails on those parameters while its traces only warn
        out += _flat_top(tr, pred[0])
        out += _start_rules(model, tr, pred, step_time(tr))
    out += _level_rules(model, fit, preds, findings)
    out += _finding_rules(model, fit, findings, out)
    if not out:
        out.append("no single known pattern explains the misfit; look at the residual "
                   "figures of the failing channels")
    return list(dict.fromkeys(out))
