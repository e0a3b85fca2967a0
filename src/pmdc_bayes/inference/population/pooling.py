"""What the population stage tells the tester: each motor's pooled values, the motors the
population makes improbable (outliers), and the lot's record ready for JSON.

**Pooled values.**  For each population draw ``(μ, σ)`` one draw of each motor given it:
its own draws resampled with the population's weights, or the product of its Gaussian
likelihood and the population's Gaussian.  A motor measured poorly is pulled toward the
lot; a well-measured one keeps its own values.

**Outliers.**  Per motor, a posterior predictive p-value against the population fitted
*without it* (each population draw weighted by the inverse of the motor's likelihood
there, truncated at ``√N`` times the mean weight, as truncated importance sampling
does; where those weights are too uneven to stand for the lot without the motor, its
Pareto k̂ above :data:`PARETO_K`, the population fitted again without it, for a far
motor would otherwise widen the spread it is judged by):
the chance that a motor of the lot measured as well as it was lies further from the
population than it does.  Two tests, the smaller p-value doubled (Bonferroni): the
joint one, ``P(χ²_P > d²)`` with ``d² = rᵀ(Σ + C)⁻¹r``, ``r`` its own estimate less
``μ`` and ``C`` its own covariance, which sees a motor off in several parameters or
off their correlation; and the most extreme single parameter's ``P(χ²_1 > r_k²/(Σ +
C)_kk)`` times ``P``, which sees a motor off in one (a weak magnet, a tight bearing)
that the joint test dilutes over the ``P`` degrees of freedom.  The lot's p-values are
corrected together by Holm's method at :data:`OUTLIER_ALPHA` (the chance that any motor
of an in-population lot is flagged).

**Correlation.**  The parameters' correlation across the lot is fitted where the data
support it: with more motors than parameters plus one, the independent and the
correlated population are compared by their leave-one-motor-out predictive density
(PSIS-LOO over the motors, Vehtari, Gelman & Gabry 2017), and the correlated one is
kept when it predicts a left-out motor better by more than :data:`CORRELATION_SE`
standard errors of the difference, over the motors neither flags as an outlier.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..model.correlation import correlations
from .hierarchical import Population, fit_population, log_density

__all__ = ["pooled_draws", "OutlierTest", "outlier_p_values", "holm", "lot_record", "analyse_lot",
           "compare_correlation", "OUTLIER_ALPHA", "PARETO_K", "MAX_REFITS", "INTERVAL",
           "CORRELATION_SE"]

OUTLIER_ALPHA = 0.05  # family-wise: the chance that an in-population lot flags any motor
PARETO_K = 0.7  # above it, importance weights do not stand for the lot without a motor
MAX_REFITS = 3  # motors at most judged against a population fitted again without them
INTERVAL = 0.90  # central interval reported
CORRELATION_SE = 2.0  # the correlated population's LOO gain, in its standard errors


def pooled_draws(pop: Population, seed: int = 0) -> list[np.ndarray]:
    """Per motor, draws ``(N, P)`` of its log-values under the population, one per
    population draw."""
    rng = np.random.default_rng(seed)
    mu, scale = pop.mu, pop.scale()
    prec = np.linalg.inv(pop.covariance())
    out = []
    for m, gaussian in zip(pop.motors, pop.gaussian, strict=True):
        if gaussian:
            lam_l = np.linalg.inv(m.cov_likelihood)
            cov = np.linalg.inv(lam_l[None] + prec)
            mean = np.einsum("nij,nj->ni", cov, (lam_l @ m.mean)[None]
                             + np.einsum("nij,nj->ni", prec, mu))
            chol = np.linalg.cholesky(0.5 * (cov + np.swapaxes(cov, 1, 2)))
            out.append(mean + np.einsum("nij,nj->ni", chol, rng.standard_normal(mu.shape)))
            continue
        lw = log_density(m.draws, mu, scale) - m.log_prior[None]
        w = np.exp(lw - lw.max(axis=1, keepdims=True))
        cdf = np.cumsum(w, axis=1)
        pick = (cdf < rng.uniform(size=(mu.shape[0], 1)) * cdf[:, -1:]).sum(axis=1)
        out.append(m.draws[np.minimum(pick, len(m.draws) - 1)])
    return out


@dataclass(frozen=True)
class OutlierTest:
    """The lot's outlier test: per motor its p-value (in the population's motor order),
    the motors judged against the population fitted again without them (their
    names), and those populations by the name left out, for the stage that fits the lot
    without its outliers to reuse."""

    p: np.ndarray
    refitted: tuple[str, ...] = ()
    without: dict = field(default_factory=dict, repr=False)


def outlier_p_values(pop: Population, *, seed: int = 0) -> OutlierTest:
    """Per motor, its posterior predictive p-value against the lot without it (module
    docstring): the population's draws reweighted by the inverse of the motor's
    likelihood, or, for a motor the reweighting cannot leave out (its weights too
    uneven, Pareto k̂ above :data:`PARETO_K`; the :data:`MAX_REFITS` of them with the
    smallest p-values), the population fitted again without it."""
    from ..sampling.arviz_import import az

    loglik = pop.log_likelihoods
    n = pop.mu.shape[0]
    cov = pop.covariance()
    with warnings.catch_warnings():  # k̂ is read here, not warned about
        warnings.simplefilter("ignore")
        _, khat = az.psislw(-loglik)
    p = np.empty(len(pop.motors))
    for j, m in enumerate(pop.motors):
        lw = -loglik[j]
        w = np.exp(lw - lw.max())
        w = np.minimum(w, np.sqrt(n) * w.mean())
        p[j] = _p_value(m, pop.mu, cov, w / w.sum())
    masked = [j for j in np.argsort(p) if khat[j] > PARETO_K][:MAX_REFITS]
    without = {}
    for j in masked if len(pop.motors) > 2 else ():
        motors = tuple(pop.motors)
        rest = fit_population(motors[:j] + motors[j + 1:], seed=seed,
                              correlated=pop.correlated)
        without[pop.motors[j].name] = rest
        p[j] = _p_value(pop.motors[j], rest.mu, rest.covariance(),
                        np.full(rest.mu.shape[0], 1.0 / rest.mu.shape[0]))
    return OutlierTest(p, tuple(without), without)


def _p_value(m, mu, cov, w) -> float:
    """Motor ``m``'s p-value over the population draws ``mu``, ``cov`` (weights ``w``):
    the smaller of the joint test's and the most extreme single parameter's (times the
    parameters' count), doubled; with one parameter, its test alone (module docstring)."""
    r = m.post_mean[None, :] - mu
    c = m.post_cov[None] + cov
    d2 = np.einsum("ni,ni->n", r, np.linalg.solve(c, r[..., None])[..., 0])
    joint = float(np.sum(w * stats.chi2.sf(d2, df=r.shape[1])))
    if r.shape[1] == 1:
        return joint
    z2 = r**2 / np.diagonal(c, axis1=1, axis2=2)
    single = float(np.min(w @ stats.chi2.sf(z2, df=1))) * r.shape[1]
    return min(1.0, 2.0 * min(joint, single))


def holm(p, alpha: float = OUTLIER_ALPHA) -> np.ndarray:
    """Which p-values Holm's step-down method rejects at family-wise level ``alpha``."""
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    reject = np.zeros(p.size, bool)
    for rank, k in enumerate(order):
        if p[k] > alpha / (p.size - rank):
            break
        reject[k] = True
    return reject


def _interval(x) -> list[float]:
    lo = (1.0 - INTERVAL) / 2
    return [float(v) for v in np.quantile(x, [lo, 1.0 - lo])]


def _loo(pop: Population) -> np.ndarray:
    """Per motor, its PSIS-LOO log predictive density under the population."""
    from ..sampling.arviz_import import az

    loglik = pop.log_likelihoods
    with warnings.catch_warnings():  # a poor tail only blurs the comparison
        warnings.simplefilter("ignore")
        lw, _ = az.psislw(-loglik)
    top = (lw + loglik).max(axis=1, keepdims=True)
    return top[:, 0] + np.log(np.sum(np.exp(lw + loglik - top), axis=1))


def compare_correlation(independent: Population, correlated: Population,
                        among=None) -> dict:
    """The correlated population's LOO gain over the independent one, summed over the
    motors ``among`` selects (all by default), with its standard error, and whether it
    is kept."""
    diff = _loo(correlated) - _loo(independent)
    if among is not None:
        diff = diff[np.asarray(among, bool)]
    gain, se = float(diff.sum()), float(np.sqrt(diff.size * np.var(diff)))
    return {"elpd_gain": gain, "se": se, "kept": bool(gain > CORRELATION_SE * se)}


def _flags(p) -> np.ndarray:
    return holm(p) if len(p) > 2 else np.zeros(len(p), bool)


def _population(motors, seed: int):
    """The population of ``motors``, correlated where the data support it (module
    docstring), its motors' p-values and flags, and the comparison that chose it.  The
    comparison is made over the motors neither population flags, so that one odd motor
    does not decide the lot's correlation."""
    pop = fit_population(motors, seed=seed)
    test = outlier_p_values(pop, seed=seed)
    flagged = _flags(test.p)
    n = len(pop.names)
    if n < 2 or len(motors) <= n + 1:
        return pop, test, flagged, {"considered": False, "kept": False}
    corr = fit_population(motors, seed=seed, correlated=True)
    test_c = outlier_p_values(corr, seed=seed)
    flagged_c = _flags(test_c.p)
    comparison = dict(compare_correlation(pop, corr, among=~(flagged | flagged_c)),
                      considered=True)
    if comparison["kept"]:
        return corr, test_c, flagged_c, comparison
    return pop, test, flagged, comparison


def analyse_lot(motors, *, seed: int = 0) -> tuple[dict, Population]:
    """The lot's record (:func:`lot_record`) and population: the outliers flagged among
    every motor, then the population fitted again without them, which the other motors
    are pooled toward (an outlier keeps its own values only)."""
    motors = tuple(motors)
    pop, test, flagged, comparison = _population(motors, seed)
    if flagged.any():
        out = [m.name for m, f in zip(motors, flagged, strict=True) if f]
        pop = test.without[out[0]] if len(out) == 1 and out[0] in test.without else (
            fit_population([m for m, f in zip(motors, flagged, strict=True) if not f],
                           seed=seed, correlated=pop.correlated))
    pooled = iter(pooled_draws(pop, seed))
    draws = [None if f else next(pooled) for f in flagged]
    record = lot_record(pop, motors, draws, test, flagged)
    record["correlation"] = _correlation_record(pop, comparison)
    return record, pop


def _correlation_record(pop: Population, comparison: dict) -> dict:
    """Whether the correlation was fitted, why, and each pair's with its interval (and
    whether that interval excludes 0)."""
    out = dict(comparison, fitted=pop.correlated)
    if pop.correlated:
        r = correlations(pop.chol)
        pairs = {}
        for i in range(len(pop.names)):
            for j in range(i):
                lo, hi = _interval(r[:, i, j])
                pairs[f"{pop.names[j]},{pop.names[i]}"] = {
                    "median": float(np.median(r[:, i, j])), "interval": [lo, hi],
                    "excludes_zero": bool(lo > 0 or hi < 0)}
        out["pairs"] = pairs
    return out


def lot_record(pop: Population, motors, pooled, test: OutlierTest, flagged) -> dict:
    """The lot's population, and each of ``motors``' own and pooled values (None for a
    motor left out of the population), its p-value, what it was judged against and its
    flag, as JSON (SI; spreads as relative sds, the sd of the log)."""
    population = {}
    for k, name in enumerate(pop.names):
        median = np.exp(pop.mu[:, k])
        population[name] = {
            "median": float(np.median(median)), "median_interval": _interval(median),
            "spread": float(np.median(pop.sigma[:, k])),
            "spread_interval": _interval(pop.sigma[:, k])}
    rows = []
    fitted = {m.name: k for k, m in enumerate(pop.motors)}
    z = stats.norm.ppf(0.5 + INTERVAL / 2)
    for j, m in enumerate(motors):
        own_sd = np.sqrt(np.diag(m.post_cov))
        values = {}
        for k, name in enumerate(pop.names):
            values[name] = {
                "own": float(np.exp(m.post_mean[k])),
                "own_interval": [float(np.exp(m.post_mean[k] - z * own_sd[k])),
                                 float(np.exp(m.post_mean[k] + z * own_sd[k]))],
                "pooled": None if pooled[j] is None
                else float(np.exp(np.median(pooled[j][:, k]))),
                "pooled_interval": None if pooled[j] is None
                else [float(np.exp(v)) for v in _interval(pooled[j][:, k])]}
        k = fitted.get(m.name)
        ess = None if k is None or np.isnan(pop.ess[k]) else float(pop.ess[k])
        rows.append({"motor": m.name, "p_value": float(test.p[j]),
                     "judged_against": "refit" if m.name in test.refitted else "reweighted",
                     "outlier": bool(flagged[j]),
                     "in_population": k is not None,
                     "reweighted": k is not None and not pop.gaussian[k],
                     "effective_draws": ess, "values": values})
    return {"parameters": list(pop.names), "population": population, "motors": rows,
            "outlier_test": {"method": "posterior predictive p-value against the lot "
                             "without the motor: the smaller of the joint test's over "
                             "every parameter and the most extreme parameter's (times "
                             "their count), doubled; Holm-corrected over the lot. "
                             "The lot without the motor is the population's draws "
                             "reweighted by the inverse of the motor's likelihood "
                             "('reweighted'), or, where those weights are too uneven "
                             f"(Pareto k above {PARETO_K}; at most {MAX_REFITS} motors, "
                             "those with the smallest p-values, in a lot of three or "
                             "more), the population fitted again without it ('refit')",
                             "alpha": OUTLIER_ALPHA},
            "interval": INTERVAL, "draws": int(pop.mu.shape[0]),
            "acceptance": pop.acceptance}
