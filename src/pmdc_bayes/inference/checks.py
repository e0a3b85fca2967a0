"""Adequacy checks that look at parameters rather than residuals (bench conflict,
physical plausibility against what the session measured, the global search), and one
that looks at where in a trace the residuals lie (the start of each step).  Each
statistical one is a :class:`~.calibrate.Test` with its p-value under the fitted model;
:func:`~.adequacy.assess` corrects them as one family."""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ..io._position import speed_estimate, speed_window
from ..physics import motor
from .adequacy import BENCH_WARN_Z, Finding, _g
from .calibrate import FAMILY_LEVEL, Test, holm, replicates, session_rng, tail_p
from .levels import unloaded_levels

__all__ = ["bench_checks", "plausibility_checks", "plausibility_tests", "search_checks",
           "rise_time", "step_time", "step_start_check", "step_start_test", "rise_eligible"]

COLLAPSE = 0.1  # a bench quantity fitted below this fraction of its bench value
PRIOR_PULL = 3.0  # a seeded parameter this many prior widths (log) from its seed
COMPETING = 5.0  # another optimum within this many log-posterior units of the MAP
START_SAMPLES = (2, 10)  # the window around a voltage step: samples before, after
START_SHARE = 0.5  # the window holds at least this share of the channel's misfit
START_COVER = 0.25  # the windows may cover at most this share of the samples


def _judged(tests: list) -> list:
    """The findings of ``tests`` judged as a family of their own (a check run alone)."""
    reject = holm([t.p_value for t in tests], FAMILY_LEVEL)
    return [type(t.finding)(**{**t.finding.__dict__, "p_value": t.p_value})
            for t, r in zip(tests, reject, strict=True) if r and t.material]


def _start_window(tr, r):
    t, v = np.asarray(tr.time, float), tr.voltage
    if v.values.size < 2 or r.size < 20:
        return None
    big = np.abs(np.diff(v.values)) > 0.2 * np.ptp(v.values)
    window = np.zeros(r.size, bool)
    for tc in v.times[1:][big]:
        k = int(np.searchsorted(t, tc))
        window[max(k - START_SAMPLES[0], 0):k + START_SAMPLES[1]] = True
    n = int(window.sum())
    return window if 0 < n <= START_COVER * r.size else None


def _start_ratio(r, window):
    """Rows of ``r``: mean square in the window over the mean square outside it."""
    r = np.atleast_2d(r)
    return (np.mean(r[:, window] ** 2, axis=1)
            / np.maximum(np.mean(r[:, ~window] ** 2, axis=1), 1e-300))


def step_start_test(tr, what: str, y, yhat, s0: float, *, sigma: float | None = None,
                    rng=None, quantum: float = 0.0) -> list:
    """Whether the residuals of a channel concentrate at the starts of its voltage
    steps (within a few samples of each change of more than a fifth of the voltage's
    range): their mean square there against elsewhere, calibrated by the bootstrap at
    the MAP; material when the window holds most (:data:`START_SHARE`) of the
    channel's misfit beyond its noise ``s0``.  A step placed late or early (a logged
    voltage column knows a change only to a sample interval; a dead time; a driver's
    delay) does this, which a fit can otherwise hide in a wrong La.  Returns a list of
    at most one :class:`~.calibrate.Test`."""
    r = np.asarray(y, float) - np.asarray(yhat, float)
    window = _start_window(tr, r)
    if window is None or not s0 > 0:
        return []
    sigma = float(np.sqrt(np.mean(r * r))) if sigma is None else sigma
    rng = np.random.default_rng(0) if rng is None else rng
    yhat = np.asarray(yhat, float)
    ratio = float(_start_ratio(r, window)[0])
    reps = np.concatenate([_start_ratio(b - yhat, window) for b in
                           replicates(yhat, sigma, rng, quantum=quantum, origin=float(y[0]))])
    n = int(window.sum())
    excess, total = float(np.sum(r[window] ** 2)) - n * s0**2, float(np.sum(r**2)) - r.size * s0**2
    share = excess / total if total > 0 else 0.0
    finding = Finding("step start", f"{tr.name}: {what}", "fail", f"x{ratio:.3g} elsewhere",
                      f"the model misses the start of the voltage steps ({100 * share:.0f} % "
                      f"of the misfit in {n} samples around them; mean square x{ratio:.3g} "
                      "elsewhere): the step is earlier or later than the model takes it (a "
                      "logged voltage column knows a change only to a sample interval: --add "
                      f"dead-time, which may come out negative), or the {what} sensor lags "
                      f"(--add {what}-lag)")
    return [Test(finding, tail_p(ratio, reps, side="chi2"), share >= START_SHARE)]


def step_start_check(tr, what: str, y, yhat, s0: float, **kw) -> list:
    """:func:`step_start_test` judged on its own at the family's level: a list of at
    most one failing :class:`~.adequacy.Finding`."""
    return _judged(step_start_test(tr, what, y, yhat, s0, **kw))


def bench_checks(model, fit) -> tuple[dict, list, list]:
    """Each bench-measured parameter's MAP against its bench value, in bench sd: the
    figures, warnings (beyond :data:`BENCH_WARN_Z` sd) and a test per parameter
    (two-sided normal p-value; a value below :data:`COLLAPSE` of the bench's is
    material whatever its p-value)."""
    out, found, tests = {}, [], []
    for spec in model.registry.specs:
        if spec.prior.source != "bench":
            continue
        value, bench, sd = fit.values[spec.name], spec.prior.centre, spec.prior.scale
        if spec.prior.kind == "lognormal":
            z = (np.log(value) - np.log(bench)) / sd
        else:
            z = (value - bench) / sd
        out[spec.name] = {"bench": bench, "bench_sd": sd, "fitted": value, "z": float(z),
                          "unit": spec.unit}
        size = f"{_g(value)} {spec.unit} fitted against {_g(bench)} ± {_g(sd)} on the bench"
        p = float(2 * norm.sf(abs(z)))
        if value < COLLAPSE * bench:
            tests.append(Test(Finding("plausibility", spec.name, "fail", size,
                                      f"{spec.description or spec.name} collapses toward "
                                      f"zero ({size})"), p))
            continue
        tests.append(Test(Finding("bench conflict", spec.name, "fail", f"{z:+.1f} bench sd",
                                  f"the fit puts {spec.name} {abs(z):.0f} bench sd "
                                  f"{'above' if z > 0 else 'below'} the bench value ({size})"),
                          p))
        if abs(z) > BENCH_WARN_Z:
            found.append(Finding("bench conflict", spec.name, "warn", f"{z:+.1f} bench sd",
                                 f"{spec.name} is {abs(z):.1f} bench sd from the bench value",
                                 p_value=p))
    for spec in model.registry.specs:
        if spec.prior.source == "bench" or spec.prior.kind != "lognormal":
            continue
        pull = (np.log(fit.values[spec.name]) - np.log(spec.prior.centre)) / spec.prior.scale
        if abs(pull) > PRIOR_PULL:
            found.append(Finding("plausibility", spec.name, "warn", f"{pull:+.1f} prior widths",
                                 f"{spec.name} ended a factor "
                                 f"{np.exp(abs(pull) * spec.prior.scale):.3g} from its seed, "
                                 "far outside the range its prior expects"))
    return out, found, tests


def step_time(trace) -> float:
    """Time of the trace's largest voltage change (its first sample when it starts from
    rest under a constant voltage)."""
    v, t = trace.voltage.values, trace.voltage.times
    if v.size < 2:
        return float(trace.time[0])
    k = int(np.argmax(np.abs(np.diff(v)))) + 1
    return float(max(t[k], trace.time[0]))


def rise_time(t, y, t_step, level: float = 0.632) -> float | None:
    """Time after ``t_step`` for ``y`` (smoothed by a moving average long enough to
    quiet its noise) to cover ``level`` of its change from
    the value at the step to the mean of its last tenth; None without a clear change."""
    from .noise import noise_scale

    t, y = np.asarray(t, float), np.asarray(y, float)
    span = float(np.max(y) - np.min(y))
    # average enough samples that the noise left is a small share of the span
    need = (3 * noise_scale(y) / max(0.02 * span, 1e-300)) ** 2 if span > 0 else 1.0
    w = int(min(max(y.size // 200, np.ceil(need), 1), max(1, y.size // 20)))
    ys = np.convolve(y, np.ones(w) / w, mode="same") if w > 1 else y
    before = ys[t <= t_step]
    y0 = float(before[-1]) if before.size else float(ys[0])
    yf = float(np.mean(y[-max(3, y.size // 10):]))
    if not abs(yf - y0) > 0.2 * span or span == 0:
        return None
    s = (ys - y0) / (yf - y0)
    after = np.nonzero((t > t_step) & (s >= level))[0]
    return float(t[after[0]] - t_step) if after.size else None


def _as_logged(trace, w):
    """The model's speed ``w`` at the trace's samples as the trace's speed was obtained:
    as it is where a speed was logged; from the angle it turns, by the same estimate
    as the data's (over the same window, which the counted angle's quantum sets),
    where the speed was estimated from a counted angle (whose window slows the rise the
    data show)."""
    if trace.speed_logged or trace.position is None:
        return w
    t = np.asarray(trace.time, dtype=float)
    w = np.asarray(w, dtype=float)
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
    read = np.isfinite(trace.position)
    return speed_estimate(t, np.where(read, angle, np.nan),
                          speed_window(t, trace.position))


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


def _logged_speeds(model, k, tr, w, sigma, quantum, rng):
    """Replicates of the trace's speed as logged (rows): the model's speed plus noise
    through the speed sensor, or its angle plus noise counted by the encoder and
    differenced as the data's speed was."""
    if tr.speed_logged or tr.position is None:
        for block in replicates(w, sigma, rng, quantum=quantum, origin=float(tr.speed[0])):
            yield from block
        return
    t, ok = np.asarray(tr.time, float), np.isfinite(tr.position)
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))])
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
    s0 = {c.name: c.s0 for c in model.channels}
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
        tests += _no_load_test(model, p, out, s0)
    rises = {}
    for k, (tr, (ia, w)) in enumerate(zip(session.traces, preds, strict=True)):
        ia, w = np.asarray(ia, float), np.asarray(w, float)
        if rise_eligible(tr):
            tests += _rise_test(model, k, tr, w, noise_sd, s0, rng, rises)
        if tr.current is not None:
            tests += _peak_test(tr, ia, noise_sd, s0, rng)
    out["rise_time"] = rises
    return out, found, tests


def plausibility_checks(model, fit, preds, rng=None) -> tuple[dict, list]:
    """:func:`plausibility_tests` judged as a family of their own: the figures and the
    findings."""
    out, found, tests = plausibility_tests(model, fit, preds, rng)
    return out, found + _judged(tests)


def _rise_test(model, k, tr, w, noise_sd, s0, rng, rises) -> list:
    """The time to 63 % of the speed's change after the step, on the data against its
    distribution on replicates of the MAP through the speed's sensor path; the sample
    interval bounds its resolution (the data's step may fall anywhere within one)."""
    from .calibrate import logged_quantum

    t_step = step_time(tr)
    obs, mod = rise_time(tr.time, tr.speed, t_step), rise_time(tr.time, _as_logged(tr, w),
                                                                t_step)
    if obs is None or mod is None or not (obs > 0 and mod > 0):
        return []
    name = f"{tr.name}: {'speed' if tr.speed_logged or tr.position is None else 'position'}"
    sigma = float(noise_sd.get(name, s0.get(name, 0.0)))
    quantum = logged_quantum(tr.speed) if tr.speed_logged else 0.0
    reps = [rise_time(tr.time, row, t_step) for row in
            _logged_speeds(model, k, tr, w, sigma, quantum, rng)]
    reps = np.log([x for x in reps if x is not None and x > 0])
    dt = float(np.median(np.diff(tr.time)))
    pv = tail_p(np.log(obs), reps, side="two", floor=dt / (np.sqrt(6.0) * mod))
    rises[tr.name] = {"observed": obs, "model": mod, "ratio": mod / obs, "p_value": pv}
    return [Test(Finding("plausibility", f"{tr.name}: speed", "fail", f"x{mod / obs:.2g}",
                         f"the model rises to 63 % in {_g(mod)} s where the data take "
                         f"{_g(obs)} s"), pv)]


def _peak_test(tr, ia, noise_sd, s0, rng) -> list:
    """The largest logged |current| against its distribution on replicates of the MAP:
    a model whose current peaks where the data's never reach (one-sided); a sample's
    change at the model's peak bounds the resolution."""
    from .calibrate import logged_quantum

    name = f"{tr.name}: current"
    sigma = float(noise_sd.get(name, s0.get(name, 0.0)))
    quantum = logged_quantum(tr.current)
    obs, peak = float(np.max(np.abs(tr.current))), float(np.max(np.abs(ia)))
    if not (obs > 0 and peak > 0):
        return []
    reps = np.concatenate([np.log(np.max(np.abs(b), axis=1)) for b in
                           replicates(ia, sigma, rng, quantum=quantum,
                                      origin=float(tr.current[0]))])
    j = int(np.argmax(np.abs(ia)))
    step = float(np.max(np.abs(np.diff(np.abs(ia[max(j - 1, 0):j + 2]))), initial=0.0))
    pv = tail_p(np.log(obs), reps, side="lower", floor=step / (np.sqrt(6.0) * peak))
    return [Test(Finding("plausibility", name, "fail", f"x{peak / obs:.2g}",
                         f"the model's current peaks at {_g(peak)} A but the logged current "
                         f"never passes {_g(obs)} A"), pv, peak > obs)]


def _no_load_test(model, p, out, s0) -> list:
    """The model's steady speed at the session's largest settled unloaded voltage
    against the speed logged there, in the level's noise (a trace's end: its speed's
    model-free noise over the samples averaged; a steady reading: the noise scale of
    the steady readings); two-sided."""
    rows, names = unloaded_levels(model.session)
    if not rows.size:
        return []
    j = int(np.argmax(np.abs(rows[:, 0])))
    v, w_obs, _ = rows[j]
    _, w_mod = motor.steady_state(p["Ra"], p["K"], p["B"], float(v), 0.0,
                                  p.get("Tc") if model.coulomb else None)
    w_mod = float(w_mod)
    out["no_load_speed"].update(logged_voltage=float(v), logged_speed=float(w_obs),
                                model_at_logged_voltage=w_mod)
    if names[j] is None:
        se = s0.get("steady: speed", 0.0)
    else:
        tr = next(t for t in model.session.traces if t.name == names[j])
        se = s0.get(f"{tr.name}: speed", 0.0) / np.sqrt(max(3, tr.n // 10))
    if w_obs == 0 or w_mod * w_obs <= 0:
        pv = 0.0
    else:
        pv = float(2 * norm.sf(abs(np.log(w_mod / w_obs)) / max(se / abs(w_obs), 1e-12)))
    out["no_load_speed"]["p_value"] = pv
    return [Test(Finding("plausibility", "no-load speed", "fail",
                         f"x{w_mod / w_obs:.2g}" if w_obs else "logged 0",
                         f"the model's no-load speed at {_g(float(v))} V is {_g(w_mod)} rad/s "
                         f"where the session settles at {_g(float(w_obs))} rad/s"), pv)]


def search_checks(fit) -> list:
    """Optima the global search found close to the MAP: a second optimum within
    :data:`COMPETING` log-posterior units holds posterior mass that the Laplace
    intervals and a sampler started at the MAP may miss.  Optima far below the MAP are
    local ones the search escaped; the fit's message counts them."""
    close = [g for g in fit.mode_gaps if g < COMPETING]
    if not close:
        return []
    return [Finding("global search", "MAP", "warn", f"{len(close) + 1} optima",
                    f"the starts reached {len(close)} other optimum/optima within "
                    f"{min(close):.2g} log-posterior units of the MAP: the posterior may "
                    "have more than one mode")]

