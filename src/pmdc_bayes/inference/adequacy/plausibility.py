"""Plausibility checks: derived quantities against what the session itself measured
(the speed's rise time after a voltage step, the largest logged current, the no-load
speed), each a :class:`~.calibrate.Test` whose p-value comes from a parametric
bootstrap at the MAP through the data's sensor path, or from the level's own noise."""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_trapezoid
from scipy.stats import norm
from scipy.stats import t as student_t

from ...io.channel import STEADY, ChannelId
from ...io.position import speed_estimate, speed_window
from ...physics import motor
from ..model.coloured import channel_rho, mean_se_factor
from ..model.levels import level_se, unloaded_levels
from ..model.noise import quantum, run_fraction
from ..model.nuisances import DEAD_ZONE_NAMES
from ..model.objective import NU0
from .calibrate import Test, judged_alone, logged_quantum, replicates, session_rng, tail_p
from .findings import NO_LOAD_SPEED, Check, Finding, Severity, sig3
from .onset import rise_time, step_window

__all__ = ["plausibility_tests", "plausibility_checks", "rise_eligible"]


def _as_logged(trace, w):
    """The model's speed ``w`` at the trace's samples as the trace's speed was obtained:
    as it is where a speed was logged; where it was estimated from a counted angle, from
    the angle ``w`` turns by the data's estimate over the data's window (which slows the
    rise the data show)."""
    if trace.speed_logged or trace.position is None:
        return w
    t = np.asarray(trace.time, dtype=float)
    w = np.asarray(w, dtype=float)
    angle = cumulative_trapezoid(w, t, initial=0.0)
    angle = np.where(np.isfinite(trace.position), angle, np.nan)
    return speed_estimate(t, angle, speed_window(t, trace.position))


def rise_eligible(trace) -> bool:
    """Whether the trace's speed answers a real voltage step its rise time can be read
    from: a change of at least half the largest voltage (or a start from rest under a
    voltage) with the load held, not a load change at a constant voltage."""
    v = trace.voltage.values
    if np.ptp(trace.load_torque.values) > 0:
        return False
    if v.size < 2:
        return trace.initial == "rest" and abs(float(v[0])) > 0
    return float(np.max(np.abs(np.diff(v)))) >= 0.5 * float(np.max(np.abs(v)))


def _logged_speeds(model, k, tr, w, sigma, quantum, rng, rho=0.0):
    """Replicates of the trace's speed as logged (rows): the model's speed plus noise
    through the speed sensor, or its angle plus noise counted by the encoder and
    differenced as the data's speed was."""
    if tr.speed_logged or tr.position is None:
        for block in replicates(w, sigma, rng, quantum=quantum, origin=float(tr.speed[0]),
                                rho=rho):
            yield from block
        return
    t, ok = np.asarray(tr.time, float), np.isfinite(tr.position)
    angle = cumulative_trapezoid(w, t, initial=0.0)
    width = speed_window(t, tr.position)
    first = float(tr.position[ok][0])
    for block in replicates(angle[ok] + first, sigma, rng, quantum=tr.encoder_step,
                            origin=first):
        for row in block:
            full = np.full(t.size, np.nan)
            full[ok] = row
            yield speed_estimate(t, full, width)


def plausibility_tests(model, fit, preds, rng=None) -> tuple[dict, list, list]:
    """Derived quantities against the session's own measurements: the figures,
    warnings, and the tests (rise time, peak current, no-load speed), each p-value from
    a parametric bootstrap at the MAP or the level's own noise."""
    session = model.session
    rng = session_rng(session) if rng is None else rng
    p = fit.values
    noise_sd = getattr(fit, "noise_sd", {})
    s0 = {c.id: c.s0 for c in model.channels}
    rho = channel_rho(model, fit.theta) if hasattr(fit, "theta") else {}
    out, found, tests = {}, [], []
    logged = [float(np.max(np.abs(tr.current))) for tr in session.traces
              if tr.current is not None]
    volts = [float(np.max(np.abs(tr.voltage.values))) for tr in session.traces]
    volts += [op.voltage for op in session.operating_points]
    volts += [float(np.max(np.abs(t.voltage))) for t in session.steady_tables]
    if volts:
        v_max = max(volts)
        out["stall_current"] = {"voltage": v_max, "value": v_max / p["Ra"],
                                "largest_logged_current": max(logged) if logged else None}
        i_nl, w_nl = motor.steady_state(p["Ra"], p["K"], p["B"], v_max, 0.0,
                                        p.get("Tc") if model.coulomb else None)
        out["no_load_speed"] = {"voltage": v_max, "value": float(w_nl)}
        tests += _no_load_test(model, fit, out, s0, preds, noise_sd, rho)
    rises = {}
    for k, (tr, (ia, w)) in enumerate(zip(session.traces, preds, strict=True)):
        ia, w = np.asarray(ia, float), np.asarray(w, float)
        if rise_eligible(tr):
            tests += _rise_test(model, k, tr, w, noise_sd, s0, rng, rises, rho)
        if tr.current is not None:
            tests += _peak_test(tr, ia, noise_sd, s0, rng, rho)
    out["rise_time"] = rises
    return out, found, tests


def _rise_test(model, k, tr, w, noise_sd, s0, rng, rises, rho) -> list:
    """The time to 63 % of the speed's change after the step, on the data against its
    distribution on replicates of the MAP through the speed's sensor path; the sample
    interval bounds its resolution (the data's step may fall anywhere within one)."""
    t_step, span = step_window(tr)
    t = np.asarray(tr.time, float)[span]
    obs, mod = (rise_time(t, y[span], t_step) for y in (tr.speed, _as_logged(tr, w)))
    if obs is None or mod is None or not (obs > 0 and mod > 0):
        return []
    name = ChannelId(tr.name, "speed" if tr.speed_logged or tr.position is None else "position")
    sigma = float(noise_sd.get(name, s0.get(name, 0.0)))
    quantum = logged_quantum(tr.speed) if tr.speed_logged else 0.0
    reps = [rise_time(t, row[span], t_step) for row in
            _logged_speeds(model, k, tr, w, sigma, quantum, rng, rho.get(name, 0.0))]
    reps = np.log([x for x in reps if x is not None and x > 0])
    dt = float(np.median(np.diff(t)))
    pv = tail_p(np.log(obs), reps, side="two", floor=dt / (np.sqrt(6.0) * mod))
    rises[tr.name] = {"observed": obs, "model": mod, "ratio": mod / obs, "p_value": pv}
    return [Test(Finding(Check.PLAUSIBILITY, ChannelId(tr.name, "speed"), Severity.FAIL,
                         f"x{mod / obs:.2g}", f"the model rises to 63 % in {sig3(mod)} s "
                         f"where the data take {sig3(obs)} s"), pv)]


def _peak_test(tr, ia, noise_sd, s0, rng, rho) -> list:
    """The largest logged |current| against its distribution on replicates of the MAP:
    a model whose current peaks where the data's never reach (one-sided); a sample's
    change at the model's peak bounds the resolution."""
    name = ChannelId(tr.name, "current")
    sigma = float(noise_sd.get(name, s0.get(name, 0.0)))
    quantum = logged_quantum(tr.current)
    obs, peak = float(np.max(np.abs(tr.current))), float(np.max(np.abs(ia)))
    if not (obs > 0 and peak > 0):
        return []
    reps = np.concatenate([np.log(np.max(np.abs(b), axis=1)) for b in
                           replicates(ia, sigma, rng, quantum=quantum,
                                      origin=float(tr.current[0]), rho=rho.get(name, 0.0))])
    j = int(np.argmax(np.abs(ia)))
    step = float(np.max(np.abs(np.diff(np.abs(ia[max(j - 1, 0):j + 2]))), initial=0.0))
    pv = tail_p(np.log(obs), reps, side="lower", floor=step / (np.sqrt(6.0) * peak))
    return [Test(Finding(Check.PLAUSIBILITY, name, Severity.FAIL, f"x{peak / obs:.2g}",
                         f"the model's current peaks at {sig3(peak)} A but the logged current "
                         f"never passes {sig3(obs)} A"), pv, peak > obs)]


def _no_load_speed(model, p: dict, v: float) -> float:
    """The model's steady speed at the command ``v`` unloaded (a steady point sees the
    driver's output less Vdrop·sign(V) through Ra + Rs)."""
    v = float(motor.driver_output(v, *(p.get(DEAD_ZONE_NAMES[s][0], 0.0) for s in (1, -1))))
    v_seen = v - float(p.get("Vdrop", 0.0)) * float(np.sign(v))
    _, w = motor.steady_state(p["Ra"] + p.get("Rs", 0.0), p["K"], p["B"], v_seen, 0.0,
                              p.get("Tc") if model.coulomb else None)
    return float(w)


def _no_load_speed_sd(model, fit, v: float) -> float:
    """The Laplace sd of :func:`_no_load_speed` at ``v`` (central differences in θ);
    0 without a finite covariance."""
    cov, theta = getattr(fit, "cov_log", None), getattr(fit, "theta", None)
    if cov is None or theta is None or not np.all(np.isfinite(cov)):
        return 0.0
    theta = np.asarray(theta, dtype=float)
    names, h = list(model.names), 1e-6

    def at(th):
        return _no_load_speed(model, dict(zip(names, model.registry.to_values(th),
                                              strict=True)), v)

    g = np.array([(at(theta + h * e) - at(theta - h * e)) / (2 * h)
                  for e in np.eye(theta.size)])
    return float(np.sqrt(max(g @ np.asarray(cov) @ g, 0.0)))


def _quantiser_bias_sd(y, sd: float) -> float:
    """The spread of the bias a quantiser (step q) leaves in a mean of readings however
    many: with analogue noise σa below about q/2 the mean reading follows the lattice,
    off the signal's mean by up to (q/π)·exp(−2π²σa²/q²) (the first harmonic of the
    quantisation error's mean, Widrow), by the signal's place in the lattice; its sd over
    that place is the amplitude over √2.  σa is read from the readings' noise ``sd``
    less the most a quantiser adds to it without dithering (q/2, a reading alternating
    between two steps), so that a quantiser is never taken for dithered when it is not
    (a bound: below q/2 of readings' noise it is the largest bias, q/(π√2)); 0 for a
    channel that is not quantised."""
    q = quantum(np.asarray(y, dtype=float))
    if q == 0.0:
        return 0.0
    analogue2 = max(sd * sd - q * q / 4.0, 0.0)
    return q / np.pi * float(np.exp(-2.0 * np.pi**2 * analogue2 / q**2)) / np.sqrt(2.0)


def _end_speed_se(tr, n: int, noise_sd: dict, s0: dict, rho: dict) -> float:
    """The standard error of a trace's mean speed over its last ``n`` samples: its
    logged speed's noise over the root of the number of independent errors among them
    (a quantised speed that its noise does not dither: one per run of equal readings,
    :func:`.noise.run_fraction`, beside the quantiser's bias), or, for a speed
    estimated from the angle, the angle's noise at both ends of the window over the
    window's length.  A coloured speed's (``rho``, :mod:`.coloured`) averages away
    more slowly."""
    if tr.speed_logged:
        name = ChannelId(tr.name, "speed")
        sd = float(noise_sd.get(name, s0.get(name, 0.0))) * mean_se_factor(rho.get(name, 0.0))
        independent = max(1.0, n * run_fraction(np.asarray(tr.speed)[-n:]))
        return float(np.hypot(sd / np.sqrt(independent), _quantiser_bias_sd(tr.speed, sd)))
    name = ChannelId(tr.name, "position")
    span = float(tr.time[-1] - tr.time[-n])
    sd = float(noise_sd.get(name, s0.get(name, 0.0)))
    return np.sqrt(2.0) * sd / span if span > 0 else 0.0


def _input_noise_sd(model, p: dict, tr, n: int, v: float) -> float:
    """What a logged voltage's noise moves the model's mean speed over a trace's last
    ``n`` samples by: the model is driven by the logged values (a noisy column's last
    level), the motor by the voltage they measure, so its mean speed there follows their
    error (:func:`~.levels.level_se`, or the level's) times the steady speed's slope at
    ``v``; 0 for a voltage given as a schedule."""
    if not tr.voltage_logged:
        return 0.0
    u = np.asarray(tr.voltage.at(tr.time[-n:]), dtype=float)
    if u.size <= 2:
        return 0.0
    h = 1e-3 * max(abs(v), 1e-9)
    slope = (_no_load_speed(model, p, v + h) - _no_load_speed(model, p, v - h)) / (2 * h)
    se = level_se(u, u.size) if tr.voltage.se is None else float(tr.voltage.se[-1])
    return abs(slope) * se


def _no_load_test(model, fit, out, s0, preds, noise_sd, rho) -> list:
    """The model's steady speed at the session's largest settled unloaded voltage
    against the speed logged there; two-sided, in the level's noise: for a steady
    reading, its prior's (Student's t with ν0 degrees at the scale s0: a reading's noise
    is not known from the reading), or for a trace's end, its speed's fitted noise over
    the samples averaged, around the mean the model predicts over them (which a trace
    that has not quite settled holds short of the steady speed), and what a logged
    voltage's noise moves that mean by (:func:`_input_noise_sd`)."""
    rows, names = unloaded_levels(model.session)
    driven = np.abs(rows[:, 0]) > 0  # a rotor at rest at 0 V says nothing of the no-load speed
    if not driven.any():
        return []
    j = int(np.argmax(np.where(driven, np.abs(rows[:, 0]), -1.0)))
    v, w_obs, _ = rows[j]
    p = fit.values
    w_mod = _no_load_speed(model, p, float(v))
    out["no_load_speed"].update(logged_voltage=float(v), logged_speed=float(w_obs),
                                model_at_logged_voltage=w_mod)
    dof = None
    if names[j] is None:
        # a steady reading: its noise level is unknown, the steady channel's prior on it
        # is ν0 pseudo-readings at s0, so marginally its miss is Student's t with ν0
        # degrees at scale s0; the other readings' scatter about the model is not the
        # reference (a model that misses every reading would raise its own yardstick)
        expected, se = w_mod, s0.get(ChannelId(STEADY, "speed"), 0.0)
        dof = NU0
    else:
        k = [t.name for t in model.session.traces].index(names[j])
        tr, n = model.session.traces[k], max(3, model.session.traces[k].n // 10)
        expected = float(np.mean(np.asarray(preds[k][1])[-n:]))
        # the level is the same trace's the model was fitted to: its mean is read against
        # the model's, whose own uncertainty (the fit's) is of the same order, and which
        # follows a logged voltage's noise where the motor did not
        se = float(np.linalg.norm([_end_speed_se(tr, n, noise_sd, s0, rho),
                                   _no_load_speed_sd(model, fit, float(v)),
                                   _input_noise_sd(model, p, tr, n, float(v))]))
    if not se > 0:  # no noise level to read the miss on: no test
        return []
    if expected * w_obs > 0:  # both turning the same way: the ratio, on a log scale
        z = abs(np.log(expected / w_obs)) / max(se / abs(w_obs), 1e-12)
    else:  # one at rest (friction holds the rotor) or the two turning opposite ways
        z = abs(expected - w_obs) / se
    pv = float(2 * (norm.sf(z) if dof is None else student_t.sf(z, dof)))
    out["no_load_speed"]["p_value"] = pv
    d = _digits(w_mod, float(w_obs))
    ratio = w_mod / w_obs if w_obs else 0.0
    return [Test(Finding(Check.PLAUSIBILITY, NO_LOAD_SPEED, Severity.FAIL,
                         f"x{ratio:.{_digits(ratio, 1.0)}g}" if w_obs else "logged 0",
                         f"the model's no-load speed at {sig3(float(v))} V is {w_mod:.{d}g} "
                         f"rad/s where the session settles at {float(w_obs):.{d}g} rad/s"),
                 pv)]


def _digits(*values: float) -> int:
    """The significant digits (3 at least) that show ``values`` apart."""
    digits = 3
    while digits < 12 and len({f"{v:.{digits}g}" for v in values}) < len(values):
        digits += 1
    return digits


def plausibility_checks(model, fit, preds, rng=None) -> tuple[dict, list]:
    """:func:`plausibility_tests` judged as a family of their own: the
    figures and the findings."""
    out, found, tests = plausibility_tests(model, fit, preds, rng)
    return out, found + judged_alone(tests)
