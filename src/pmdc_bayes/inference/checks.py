"""Adequacy checks that look at parameters rather than residuals (bench conflict,
physical plausibility against what the session measured, the global search), and one
that looks at where in a trace the residuals lie (the start of each step)."""

from __future__ import annotations

import numpy as np

from ..io._position import speed_estimate, speed_window
from ..physics import motor
from .adequacy import BENCH_FAIL_Z, BENCH_WARN_Z, PEAK_RATIO, RISE_RATIO, Finding, _g
from .levels import unloaded_levels

__all__ = ["bench_checks", "plausibility_checks", "search_checks", "rise_time", "step_time",
           "step_start_check"]

COLLAPSE = 0.1  # a bench quantity fitted below this fraction of its bench value
PRIOR_PULL = 3.0  # a seeded parameter this many prior widths (log) from its seed
NO_LOAD_RATIO = 1.2  # model's steady speed against the logged one, either way
COMPETING = 5.0  # another optimum within this many log-posterior units of the MAP
START_SAMPLES = (2, 10)  # the window around a voltage step: samples before, after
START_ENERGY = 30.0  # its sum of squared residuals against the noise's expectation
START_SHARE = 0.5  # and at least this share of the channel's misfit beyond its noise
START_COVER = 0.25  # the windows may cover at most this share of the samples


def step_start_check(tr, what: str, y, yhat, s0: float) -> list:
    """A fail when the residuals of a channel concentrate at the starts of its voltage
    steps: within a few samples of each change of more than a fifth of the voltage's
    range the squared residuals sum to :data:`START_ENERGY` × what the channel's
    noise gives, and that is most of the channel's misfit.  A step placed late or early
    (a logged voltage column knows a change only to a sample interval; a dead time; a
    driver's delay) does this, which a fit can otherwise hide in a wrong La."""
    t, r = np.asarray(tr.time, float), np.asarray(y, float) - np.asarray(yhat, float)
    v = tr.voltage
    if v.values.size < 2 or not s0 > 0 or r.size < 20:
        return []
    big = np.abs(np.diff(v.values)) > 0.2 * np.ptp(v.values)
    window = np.zeros(r.size, bool)
    for tc in v.times[1:][big]:
        k = int(np.searchsorted(t, tc))
        window[max(k - START_SAMPLES[0], 0):k + START_SAMPLES[1]] = True
    n = int(window.sum())
    if n == 0 or n > START_COVER * r.size:
        return []
    energy = float(np.sum(r[window] ** 2))
    excess, total = energy - n * s0**2, float(np.sum(r**2)) - r.size * s0**2
    ratio = energy / (n * s0**2)
    if ratio < START_ENERGY or total <= 0 or excess < START_SHARE * total:
        return []
    return [Finding("step start", f"{tr.name}: {what}", "fail", f"x{ratio:.3g} the noise",
                    f"the model misses the start of the voltage steps ({100 * excess / total:.0f}"
                    f" % of the misfit in {n} samples around them; x{ratio:.3g} the noise "
                    "there): the step is earlier or later than the model takes it (a logged "
                    "voltage column knows a change only to a sample interval: --add "
                    f"dead-time, which may come out negative), or the {what} sensor lags "
                    f"(--add {what}-lag)")]


def bench_checks(model, fit) -> tuple[dict, list]:
    """Each bench-measured parameter's MAP against its bench value, in bench sd."""
    out, found = {}, []
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
        if value < COLLAPSE * bench:
            found.append(Finding("plausibility", spec.name, "fail", size,
                                 f"{spec.description or spec.name} collapses toward zero "
                                 f"({size})"))
        elif abs(z) > BENCH_FAIL_Z:
            found.append(Finding("bench conflict", spec.name, "fail", f"{z:+.1f} bench sd",
                                 f"the fit puts {spec.name} {abs(z):.0f} bench sd "
                                 f"{'above' if z > 0 else 'below'} the bench value ({size})"))
        elif abs(z) > BENCH_WARN_Z:
            found.append(Finding("bench conflict", spec.name, "warn", f"{z:+.1f} bench sd",
                                 f"{spec.name} is {abs(z):.1f} bench sd from the bench value"))
    for spec in model.registry.specs:
        if spec.prior.source == "bench" or spec.prior.kind != "lognormal":
            continue
        pull = (np.log(fit.values[spec.name]) - np.log(spec.prior.centre)) / spec.prior.scale
        if abs(pull) > PRIOR_PULL:
            found.append(Finding("plausibility", spec.name, "warn", f"{pull:+.1f} prior widths",
                                 f"{spec.name} ended a factor "
                                 f"{np.exp(abs(pull) * spec.prior.scale):.3g} from its seed, "
                                 "far outside the range its prior expects"))
    return out, found


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


def plausibility_checks(model, fit, preds) -> tuple[dict, list]:
    """Derived quantities against the session's own measurements."""
    session = model.session
    p = fit.values
    out, found = {}, []
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
        found += _no_load_check(model, p, out)
    rises = {}
    for tr, (ia, w) in zip(session.traces, preds, strict=True):
        t_step = step_time(tr)
        obs, mod = rise_time(tr.time, tr.speed, t_step), rise_time(tr.time, _as_logged(tr, w),
                                                                    t_step)
        if obs is not None and mod is not None and obs > 0 and mod > 0:
            ratio = mod / obs
            rises[tr.name] = {"observed": obs, "model": mod, "ratio": ratio}
            if not 1 / RISE_RATIO < ratio < RISE_RATIO:
                found.append(Finding("plausibility", f"{tr.name}: speed", "fail",
                                     f"x{ratio:.2g}",
                                     f"the model rises to 63 % in {_g(mod)} s where the data "
                                     f"take {_g(obs)} s"))
        if tr.current is not None:
            noise = model.channels[[c.name for c in model.channels].index(
                f"{tr.name}: current")].s0
            peak_obs = float(np.max(np.abs(tr.current))) + 3 * noise
            peak_mod = float(np.max(np.abs(ia)))
            if peak_mod > PEAK_RATIO * peak_obs:
                found.append(Finding(
                    "plausibility", f"{tr.name}: current", "fail",
                    f"x{peak_mod / peak_obs:.2g}",
                    f"the model's current peaks at {_g(peak_mod)} A (stall current "
                    f"{_g(out['stall_current']['value'])} A) but the logged current never "
                    f"passes {_g(peak_obs - 3 * noise)} A"))
    out["rise_time"] = rises
    return out, found


def _no_load_check(model, p, out) -> list:
    """The model's steady speed at the session's largest settled unloaded voltage
    against the speed logged there."""
    rows, _ = unloaded_levels(model.session)
    if not rows.size:
        return []
    v, w_obs, _ = rows[int(np.argmax(np.abs(rows[:, 0])))]
    _, w_mod = motor.steady_state(p["Ra"], p["K"], p["B"], float(v), 0.0,
                                  p.get("Tc") if model.coulomb else None)
    w_mod = float(w_mod)
    out["no_load_speed"].update(logged_voltage=float(v), logged_speed=float(w_obs),
                                model_at_logged_voltage=w_mod)
    if w_obs == 0 or not 1 / NO_LOAD_RATIO < w_mod / w_obs < NO_LOAD_RATIO:
        return [Finding("plausibility", "no-load speed", "fail",
                        f"x{w_mod / w_obs:.2g}" if w_obs else "logged 0",
                        f"the model's no-load speed at {_g(float(v))} V is {_g(w_mod)} rad/s "
                        f"where the session settles at {_g(float(w_obs))} rad/s")]
    return []


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

