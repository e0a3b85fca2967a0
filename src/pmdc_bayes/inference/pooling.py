"""What the population stage tells the tester: each motor's pooled values, the motors the
population makes improbable (outliers), and the lot's record ready for JSON.

**Pooled values.**  For each population draw ``(μ, σ)`` one draw of each motor given it:
its own draws resampled with the population's weights, or the product of its Gaussian
likelihood and the population's Gaussian.  A motor measured poorly is pulled toward the
lot; a well-measured one keeps its own values.

**Outliers.**  Per motor, a posterior predictive p-value against the population fitted
*without it* (each population draw weighted by the inverse of the motor's likelihood
there, truncated at ``√N`` times the mean weight, as truncated importance sampling
does): the chance that a motor of the lot measured as well as it was lies further from
the population than it does, ``P(χ²_P > d²)`` with ``d² = rᵀ(diag(σ²) + C)⁻¹r``, ``r``
its own estimate less ``μ`` and ``C`` its own covariance.  The lot's p-values are
corrected together by Holm's method at :data:`OUTLIER_ALPHA` (the chance that any motor
of an in-population lot is flagged).
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .population import Population, fit_population

__all__ = ["pooled_draws", "outlier_p_values", "holm", "lot_record", "analyse_lot",
           "OUTLIER_ALPHA", "INTERVAL"]

OUTLIER_ALPHA = 0.05  # family-wise: the chance that an in-population lot flags any motor
INTERVAL = 0.90  # central interval reported


def pooled_draws(pop: Population, seed: int = 0) -> list[np.ndarray]:
    """Per motor, draws ``(N, P)`` of its log-values under the population, one per
    population draw."""
    rng = np.random.default_rng(seed)
    mu, var = pop.mu, pop.sigma**2
    out = []
    for m, gaussian in zip(pop.motors, pop.gaussian, strict=True):
        if gaussian:
            lam_l = np.linalg.inv(m.cov_likelihood)
            lam = lam_l[None] + (1.0 / var)[:, :, None] * np.eye(mu.shape[1])
            cov = np.linalg.inv(lam)
            mean = np.einsum("nij,nj->ni", cov, (lam_l @ m.mean)[None] + mu / var)
            chol = np.linalg.cholesky(0.5 * (cov + np.swapaxes(cov, 1, 2)))
            out.append(mean + np.einsum("nij,nj->ni", chol, rng.standard_normal(mu.shape)))
            continue
        z = (m.draws[None] - mu[:, None, :]) / pop.sigma[:, None, :]
        lw = -0.5 * np.sum(z * z, axis=2) - m.log_prior[None]
        w = np.exp(lw - lw.max(axis=1, keepdims=True))
        cdf = np.cumsum(w, axis=1)
        pick = (cdf < rng.uniform(size=(mu.shape[0], 1)) * cdf[:, -1:]).sum(axis=1)
        out.append(m.draws[np.minimum(pick, len(m.draws) - 1)])
    return out


def outlier_p_values(pop: Population) -> np.ndarray:
    """Per motor, its posterior predictive p-value against the lot without it."""
    loglik = pop.log_likelihoods()
    n = pop.mu.shape[0]
    p = np.empty(len(pop.motors))
    for j, m in enumerate(pop.motors):
        lw = -loglik[j]
        w = np.exp(lw - lw.max())
        w = np.minimum(w, np.sqrt(n) * w.mean())
        w /= w.sum()
        r = m.post_mean[None, :] - pop.mu
        c = m.post_cov[None] + (pop.sigma**2)[:, :, None] * np.eye(r.shape[1])
        d2 = np.einsum("ni,ni->n", r, np.linalg.solve(c, r[..., None])[..., 0])
        p[j] = float(np.sum(w * stats.chi2.sf(d2, df=r.shape[1])))
    return p


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


def analyse_lot(motors, *, seed: int = 0) -> tuple[dict, Population]:
    """The lot's record (:func:`lot_record`) and population: the outliers flagged among
    every motor, then the population fitted again without them, which the other motors
    are pooled toward (an outlier keeps its own values only)."""
    motors = tuple(motors)
    pop = fit_population(motors, seed=seed)
    p = outlier_p_values(pop)
    flagged = holm(p) if len(motors) > 2 else np.zeros(len(motors), bool)
    if flagged.any():
        pop = fit_population([m for m, f in zip(motors, flagged, strict=True) if not f],
                             seed=seed)
    pooled = iter(pooled_draws(pop, seed))
    draws = [None if f else next(pooled) for f in flagged]
    return lot_record(pop, motors, draws, p, flagged), pop


def lot_record(pop: Population, motors, pooled, p, flagged) -> dict:
    """The lot's population, and each of ``motors``' own and pooled values (None for a
    motor left out of the population), its p-value and flag, as JSON (SI; spreads as
    relative sds, the sd of the log)."""
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
        rows.append({"motor": m.name, "p_value": float(p[j]), "outlier": bool(flagged[j]),
                     "in_population": k is not None,
                     "reweighted": k is not None and not pop.gaussian[k],
                     "effective_draws": ess, "values": values})
    return {"parameters": list(pop.names), "population": population, "motors": rows,
            "outlier_test": {"method": "posterior predictive p-value against the lot "
                             "without the motor, Holm-corrected", "alpha": OUTLIER_ALPHA},
            "interval": INTERVAL, "draws": int(pop.mu.shape[0]),
            "acceptance": pop.acceptance}
