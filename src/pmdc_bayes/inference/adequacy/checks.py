"""Adequacy checks that look at parameters rather than residuals (bench conflict,
physical plausibility against what the session measured, the global search), and one
that looks at where in a trace the residuals lie (the start of each step).  Each
statistical one is a :class:`~.calibrate.Test` with its p-value under the fitted model;
:func:`~.adequacy.verdict` corrects them as one family."""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ...io.channel import ChannelId
from .calibrate import Test, judged_alone, replicates, tail_p
from .findings import Check, Finding, Severity, sig3

__all__ = ["bench_checks", "search_checks", "step_start_check", "step_start_test"]

BENCH_WARN_Z = 3.0  # a bench quantity this many bench sd away is worth a warning
COLLAPSE = 0.1  # a bench quantity fitted below this fraction of its bench value
PRIOR_PULL = 3.0  # a seeded parameter this many prior widths (log) from its seed
COMPETING = 5.0  # another optimum within this many log-posterior units of the MAP
START_SAMPLES = (2, 10)  # the window around a voltage step: samples before, after
START_SHARE = 0.5  # the window holds at least this share of the channel's misfit
START_COVER = 0.25  # the windows may cover at most this share of the samples


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
                    rng=None, quantum: float = 0.0, rho: float = 0.0) -> list:
    """Whether the residuals of a channel concentrate at the starts of its voltage
    steps (within a few samples of each change of more than a fifth of the voltage's
    range): their mean square there against elsewhere, calibrated by the bootstrap at
    the MAP; material when the window holds most (:data:`START_SHARE`) of the
    channel's misfit beyond its noise ``s0``.  A step placed late or early (a logged
    voltage column knows a change only to a sample interval; a dead time; a driver's
    delay) does this, which a fit can otherwise hide in a wrong La.  ``rho``: the lag-1
    correlation of the channel's noise (:mod:`.coloured`).  Returns a list of
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
                           replicates(yhat, sigma, rng, quantum=quantum, origin=float(y[0]),
                                      rho=rho)])
    n = int(window.sum())
    excess, total = float(np.sum(r[window] ** 2)) - n * s0**2, float(np.sum(r**2)) - r.size * s0**2
    share = excess / total if total > 0 else 0.0
    finding = Finding(Check.STEP_START, ChannelId(tr.name, what), Severity.FAIL,
                      f"x{ratio:.3g} elsewhere",
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
    return judged_alone(step_start_test(tr, what, y, yhat, s0, **kw))


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
        size = f"{sig3(value)} {spec.unit} fitted against {sig3(bench)} ± {sig3(sd)} on the bench"
        p = float(2 * norm.sf(abs(z)))
        if value < COLLAPSE * bench:
            tests.append(Test(Finding(Check.PLAUSIBILITY, spec.name, Severity.FAIL, size,
                                      f"{spec.description or spec.name} collapses toward "
                                      f"zero ({size})"), p))
            continue
        tests.append(Test(Finding(Check.BENCH_CONFLICT, spec.name, Severity.FAIL,
                                  f"{z:+.1f} bench sd",
                                  f"the fit puts {spec.name} {abs(z):.0f} bench sd "
                                  f"{'above' if z > 0 else 'below'} the bench value ({size})"),
                          p))
        if abs(z) > BENCH_WARN_Z:
            found.append(Finding(Check.BENCH_CONFLICT, spec.name, Severity.WARN,
                                 f"{z:+.1f} bench sd",
                                 f"{spec.name} is {abs(z):.1f} bench sd from the bench value",
                                 p_value=p))
    for spec in model.registry.specs:
        if spec.prior.source == "bench" or spec.prior.kind != "lognormal":
            continue
        pull = (np.log(fit.values[spec.name]) - np.log(spec.prior.centre)) / spec.prior.scale
        if abs(pull) > PRIOR_PULL:
            found.append(Finding(Check.PLAUSIBILITY, spec.name, Severity.WARN,
                                 f"{pull:+.1f} prior widths",
                                 f"{spec.name} ended a factor "
                                 f"{np.exp(abs(pull) * spec.prior.scale):.3g} from its seed, "
                                 "far outside the range its prior expects"))
    return out, found, tests


def search_checks(fit) -> list:
    """Optima the global search found close to the MAP: a second optimum within
    :data:`COMPETING` log-posterior units holds posterior mass that the Laplace
    intervals and a sampler started at the MAP may miss.  Optima far below the MAP are
    local ones the search escaped; the fit's message counts them."""
    close = [g for g in fit.mode_gaps if g < COMPETING]
    if not close:
        return []
    return [Finding(Check.GLOBAL_SEARCH, "MAP", Severity.WARN, f"{len(close) + 1} optima",
                    f"the starts reached {len(close)} other optimum/optima within "
                    f"{min(close):.2g} log-posterior units of the MAP: the posterior may "
                    "have more than one mode")]

