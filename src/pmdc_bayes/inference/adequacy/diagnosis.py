"""What an inadequate fit's pattern suggests, in words a bench user can act on.

Each rule reads the data and the MAP prediction:

* the **start** of each step: a channel that leaves rest
  clearly later than the model's, or a rise that a delayed or lagged shape fits far
  better on the data than on the model, means dead time or a sensor lag; a rise that
  is a ramp on the data but not on the model means a current-limited driver;
* a logged current with a **flat top** well below the model's peak: a current limit;
* the **steady levels** (:mod:`.diagnosis_levels`, from :mod:`.levels`): a trace off
  the line the other levels draw means an unmeasured load on it (or, with a declared
  drag, a drag declared too strong or too weak); a speed-voltage line crossing zero
  speed well above 0 V means a voltage drop (brushes, driver), a current left at zero
  speed means Coulomb friction;
* a speed that falls far more slowly after each **switch to zero** than it rises
  after a switch on (:mod:`.zero_command`): a driver that opens the armature there;
* **anti-correlated noise** on a speed: a speed differenced from encoder counts;
* a **bench resistance** below or above the fitted one; and unit slips (a ratio of
  2π, 60/2π or 1000 between the data and the model);
* the **steady readings** missed beyond their scatter (:mod:`.steady`): the traces'
  sensor's calibration, or for the currents Coulomb friction;
* a failing channel of a trace stamped by a clock that does not set its pace
  (:mod:`.clock_rule`): a misfit its stamps alone can make.
"""

from __future__ import annotations

import numpy as np

from ...io.channel import ChannelId
from ...io.lattice import analogue_channels
from ..model.noise import noise_scale
from ..model.nuisances import sensor_readings
from .clock_rule import clock_rules
from .diagnosis_levels import level_rules
from .findings import Check
from .onset import departure, onset_shape, step_window
from .proposals import COULOMB, Proposal, has, said
from .zero_command import coast_rules

__all__ = ["diagnose", "Proposal"]

BETTER = 0.6  # a shape explains the onset when its error is below this share of the plain one
LATE_SAMPLES = 2  # a start later than the model's by at least this many samples ...
LATE_SHARE = 0.03  # ... and this share of the rise time counts as late
SLOW_START = 1.5  # fitted La/Ra this many times the bench's: something delays the start
DEPART = 5.0  # a channel has left rest when it is this many noise sd from its level ...
DEPART_SPAN = 0.01  # ... and this share of its span


def _late_start(t, y, yhat, s0, t_step, t_rise):
    """How much later than the model (s) the channel leaves rest, or None."""
    span = float(np.max(y) - np.min(y))
    threshold = max(DEPART * s0, DEPART_SPAN * span)
    d_obs = departure(t, y, t_step, threshold)
    d_mod = departure(t, yhat, t_step, threshold)
    if d_obs is None or d_mod is None:
        return None
    dt = float(np.median(np.diff(t)))
    late = d_obs - d_mod
    return late if late >= LATE_SAMPLES * dt and late > LATE_SHARE * t_rise else None


def _start_rules(model, tr, pred):
    """Sentences on the start of a trace's largest step, read up to its next voltage
    change (:func:`.onset.step_window`)."""
    ia, w = pred
    out = []
    t_step, upto = step_window(tr)
    t = np.asarray(tr.time, float)[upto]
    data = onset_shape(t, np.asarray(tr.speed)[upto], t_step)
    fitted = onset_shape(t, np.asarray(w)[upto], t_step)
    t_rise = fitted["t90"] if fitted else float(t[-1] - t_step)
    lates = {}
    for what, y, yhat in (("speed", tr.speed, w), ("current", tr.current, ia)):
        if y is not None:
            late = _late_start(t, np.asarray(y)[upto], np.asarray(yhat)[upto],
                               _noise(model, tr, what, y), t_step, t_rise)
            if late is not None:
                lates[what] = late
    lagged = ramp = False
    if data and fitted:
        dt = float(np.median(np.diff(t)))
        lag_d = min(data["delayed"], data["lagged"])
        lagged = (lag_d < BETTER and lag_d < data["ramp"]
                  and data["dead_time"] - fitted["dead_time"] > max(LATE_SAMPLES * dt,
                                                                    LATE_SHARE * data["t90"]))
        ramp = (data["ramp"] < BETTER and data["ramp"] < lag_d
                and data["ramp"] < BETTER * fitted["ramp"])
    if lates or lagged:
        late = max(lates.values()) if lates else data["dead_time"] - fitted["dead_time"]
        if "current" in lates:
            out.append(said(f"{tr.name}: the current and speed start about {1e3 * late:.2g} ms "
                       "later than the model allows: add a dead time between the command "
                       "and the motion (driver, PWM start, logging trigger): --add dead-time, "
                       "or dead_time = true under [model] in session.toml (\"shared\" when "
                       "one driver and logger serve every trace)",
                            Proposal("dead_time", tr.name)))
        elif tr.current is not None:
            out.append(said(f"{tr.name}: the speed starts about {1e3 * late:.2g} ms later than "
                       "the model allows while the current starts on time: a lag in the "
                       "speed sensor or its filter: --add speed-lag, or speed_lag = true "
                       "under [model] in session.toml", Proposal("speed_lag")))
        else:
            out.append(said(f"{tr.name}: the speed starts about {1e3 * late:.2g} ms later than "
                       "the model allows: add a dead time between the command and the "
                       "motion (--add dead-time), or a speed-sensor/filter lag "
                       "(--add speed-lag)", Proposal("dead_time", tr.name),
                            Proposal("speed_lag")))
    if ramp:
        out.append(said(f"{tr.name}: the speed ramps up at a constant rate for "
                   f"{1e3 * data['ramp_time']:.3g} ms before turning exponential: a "
                   "current-limited driver (a ramp instead of an exponential at the start): "
                   "--add current-limit, or current_limit = true (or the driver's limit in "
                   "A) under [model] in session.toml", Proposal("current_limit")))
    return out


def _flat_top(tr, ia):
    if tr.current is None:
        return []
    top = float(np.max(np.abs(tr.current)))
    near = np.abs(np.abs(tr.current) - top) < 0.03 * top
    peak = float(np.max(np.abs(ia)))
    if near.sum() >= 5 and peak > 1.2 * top:
        return [said(f"{tr.name}: the logged current is flat at about {top:.3g} A while the model "
                f"would draw {peak:.3g} A: a current-limited driver: --add current-limit, "
                f"or current_limit = {top:.3g} under [model] in session.toml",
                     Proposal("current_limit"))]
    return []


def _finding_rules(model, fit, findings, already=()):
    out = []
    la, ra = model.registry["La"].prior, model.registry["Ra"].prior
    limited = any(p.nuisance == "current_limit"  # a current limit explains a slow start
                  for text in already for p in getattr(text, "proposals", ()))
    if (la.source == "bench" and not limited and any(f.where == "La" and f.failed
                                                     for f in findings)):
        fitted = fit.values["La"] / fit.values["Ra"]
        bench = la.centre / ra.centre
        current = any(tr.current is not None for tr in model.session.traces)
        if fitted > SLOW_START * bench or (current and fitted > bench):
            out.append(said(f"the fit stretches the electrical time constant La/Ra to "
                       f"{1e3 * fitted:.2g} ms against {1e3 * bench:.2g} ms on the bench: the "
                       "response starts more slowly than the motor's inductance explains: a "
                       "dead time (--add dead-time) or a speed-sensor/filter lag "
                       "(--add speed-lag)" + (", or a current-sensor/filter lag "
                                              "(--add current-lag)" if current else ""),
                            Proposal("dead_time"), Proposal("speed_lag"),
                            *((Proposal("current_lag"),) if current else ())))
    for f in findings:
        if not f.failed:
            continue
        channel = f.where if isinstance(f.where, ChannelId) else None
        if f.check is Check.SYSTEMATIC_MISFIT and f.where in analogue_channels(model.session):
            out.append(said(f"{f.where}: the residual wanders slowly: a response the model "
                            "lacks, or a sensor whose noise is correlated from one sample to "
                            "the next (a filter, an average, a tachometer's ripple); fit that "
                            "noise: --add coloured-noise (coloured_noise = true under "
                            "[model]), which the evidence weighs against what the rest of "
                            "this diagnosis proposes",
                            Proposal("coloured_noise", analogue_channels(model.session)[f.where])))
        if f.check is Check.PHYSICAL_BOUND:
            text = f"{f.where} at its bound: {f.suggestion}"
            out.append(said(text, Proposal("dead_time")) if f.where == "La" else text)
        if f.check is Check.SOLVER:
            out.append(f"{f.where}: the solution's limit, not necessarily the model's: "
                       f"{f.suggestion}")
        if f.check is Check.STEADY_MISS and channel is not None:
            out += _steady_rule(model, channel.signal, f)
        if f.check is Check.STEP_START and channel is not None:
            sensor = channel.signal
            out.append(said(f"{channel.trace}: the model misses the start of the voltage "
                       "steps: the steps are earlier or later than the session says (a "
                       "logged voltage column, a trigger offset, a dead time): --add "
                       f"dead-time; or the {sensor} sensor lags: --add {sensor}-lag",
                            Proposal("dead_time", channel.trace),
                            Proposal(f"{sensor}_lag")))
        whiteness = f.check is Check.RESIDUAL_WHITENESS and channel is not None
        if whiteness and channel.signal == "current":
            out.append(f"{f.where}: {f.message}: a ripple near half the sampling rate (a "
                       "PWM ripple aliased by the sampling) rather than white noise; filter "
                       "the current before sampling it, or average each sample over whole "
                       "PWM periods")
        if whiteness and channel.signal == "speed":
            out.append(f"{f.where}: {f.message}: a speed differenced from encoder counts or a "
                       "quantised position; declare the encoder's counts_per_rev on the "
                       "trace (its speed is then read as the counted angle), or log the "
                       "count as the position (columns.position, or edges = true), or "
                       "average over more samples")
        if f.where == "Ra" and f.check in (Check.BENCH_CONFLICT, Check.PLAUSIBILITY):
            if fit.values["Ra"] > model.registry["Ra"].prior.centre:
                out.append(said("the fitted resistance exceeds the bench Ra: a supply source "
                           "resistance, leads or a driver in the loop, or a constant drop "
                           "at the brushes or the driver's switches (at a steady current "
                           "the two look alike); log the terminal voltage, or fit them: "
                           "--add source-resistance or --add voltage-drop (or "
                           "source_resistance, voltage_drop = true under [model])",
                                Proposal("source_resistance"), Proposal("voltage_drop")))
            else:
                out.append("the fitted resistance is far below the bench Ra: the ideal motor "
                           "is absorbing something it lacks (a current limit, a voltage "
                           "drop, a lag); see the trace findings")
        if (f.where in ("K", "J", "B") and f.check is Check.BENCH_CONFLICT
                and "speed_gain" not in model.session.nuisances
                and any(tr.speed_logged for tr in model.session.traces)):
            out.append(said(f"the fit puts {f.where} off its bench value: a speed sensor whose "
                       "calibration is off (a tachometer constant, a scale) scales K, J and B "
                       "together, which a bench value then contradicts; fit the sensor's "
                       "gain: --add speed-gain, or speed_gain = true under [model] (or check "
                       "the bench value)", Proposal("speed_gain")))
    return out


def _steady_rule(model, signal: str, f) -> list:
    """A sentence on steady readings that the traces' fit misses: the traces' sensor
    reads the signal at another scale or zero than the steady instrument (a gain, an
    offset), or, for a current, a torque the model lacks at every speed."""
    out = []
    if sensor_readings(model.session, signal):
        out.append(said(f"{f.where}: {f.message}: the traces' {signal} sensor reads on "
                        "another scale or zero than the steady readings' instrument (a "
                        "tachometer constant, a shunt, a scale, an offset); fit its "
                        f"calibration: --add {signal}-gain, --add {signal}-offset (or "
                        f"{signal}_gain, {signal}_offset = true under [model]), or check "
                        "the steady readings", Proposal(f"{signal}_gain"),
                        Proposal(f"{signal}_offset")))
    if signal == "current" and not model.coulomb:
        out.append(said(f"{f.where}: the steady currents stand off the model's by a "
                        "constant in each direction: a friction torque that does not "
                        "grow with speed (Coulomb friction): --friction coulomb",
                        Proposal(COULOMB)))
    return out


def _noise(model, tr, what, y) -> float:
    """The channel's model-free noise level; for a speed estimated from an angle (no
    speed channel), that of the estimate."""
    s0 = {c.id: c.s0 for c in model.channels}.get(ChannelId(tr.name, what))
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


def diagnose(model, fit, preds, findings) -> tuple[list[str], list[Proposal]]:
    """Sentences naming what the data suggest the model lacks, most specific first, and
    the additions they propose.  A sentence whose every proposal the model already fits
    is left out; when that leaves nothing to propose, a sentence says so."""
    out = clock_rules(model, findings)
    for tr in model.session.traces:
        out += _still(model, tr)
    for tr, pred in zip(model.session.traces, preds, strict=True):
        # every trace, not only failing ones: a model that absorbs a delay in Ra and La
        # fails on those parameters while its traces only warn
        out += _flat_top(tr, pred[0])
        out += _start_rules(model, tr, pred)
        out += coast_rules(model, tr)
    out += level_rules(model, fit, preds, findings)
    out += _finding_rules(model, fit, findings, out)
    kept, proposals, fitted = [], [], []
    for text in dict.fromkeys(out):
        props = getattr(text, "proposals", ())
        new = [p for p in props if not has(model, p)]
        if props and not new:
            fitted += [p for p in props if p not in fitted]
            continue
        kept.append(str(text))
        proposals += [p for p in new if p not in proposals]
    if fitted and not proposals:
        names = ", ".join(p.nuisance + (f" on {p.trace}" if p.trace else "") for p in fitted)
        kept.append(f"the patterns in the data point to what the model already fits "
                    f"({names}): nothing more to propose; look at the residual figures of "
                    "the failing channels")
    if not kept:
        kept.append("no single known pattern explains the misfit; look at the residual "
                    "figures of the failing channels")
    return kept, proposals
