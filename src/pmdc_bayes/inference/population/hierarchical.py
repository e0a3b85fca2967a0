"""A lot of motors as a population: the second stage of a hierarchical fit.

Each motor's parameters (in log: K, B, J, Ra, and Tc or La where every motor has them)
are drawn from a log-normal population, ``log x_m ~ N(μ, Σ)`` with
``Σ = diag(σ)·R·diag(σ)``: ``exp(μ)`` the lot's median, ``σ`` its spread (a relative
sd) and ``R`` the correlation of the parameters across the lot (the identity for the
independent population; an LKJ prior, :mod:`.correlation`, for the correlated one).
The first stage is each motor's own fit (:mod:`.evidence` reads it); this one
combines them without fitting a motor again.  A motor's likelihood of the population
is its posterior draws reweighted from its own prior to the population
(``mean_s N(x_s | μ, Σ) / π_m(x_s)``), or, where its draws are too few to carry that
(fewer than :data:`MIN_ESS` effective draws at the population's posterior mean) or it
has only a MAP, the Gaussian that its posterior over its prior leaves (exact for a
Gaussian posterior).  ``(μ, log σ[, R])`` are sampled with emcee (a flat prior on μ, a
half-normal of scale :data:`SPREAD_SCALE` on σ).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import emcee
import numpy as np

from ..model.correlation import cholesky_corr, lkj_log_prior, n_pairs
from .evidence import MotorEvidence

__all__ = ["Population", "fit_population", "MIN_ESS", "SPREAD_SCALE"]

MIN_ESS = 25.0  # effective reweighted draws a motor needs at the population's mean
SPREAD_SCALE = 1.0  # half-normal scale of a parameter's spread (log units)
WALKERS = 32  # at least; twice the dimension and two more where that is larger
BURN, KEEP = 1000, 1000  # steps: burn-in, then kept (thinned to THIN)
THIN = 10


def _moves():
    """Fresh move objects for a sampler: differential evolution, with a stretch move in
    one step of five.  emcee's snooker move is left out: alone, it left the population's
    median about 30 % narrower than the exact posterior (reports/benchmarks.md, "A
    production lot")."""
    return [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]
_LOG_2PI = float(np.log(2 * np.pi))


@dataclass(frozen=True)
class Population:
    """The lot's population posterior.

    Attributes
    ----------
    names : the pooled parameters (SI names).
    mu, sigma : draws ``(N, P)`` of the log-median and the spread (log sd).
    chol : draws ``(N, P, P)`` of the Cholesky factor of the parameters' correlation
        across the lot (the identity where ``correlated`` is False).
    correlated : whether the population's correlation was fitted.
    motors : the motors' evidence, in the order given.
    gaussian : per motor, whether its Gaussian stood in for its reweighted draws.
    ess : per motor, the effective reweighted draws at the population's mean (where
        it fell back to its Gaussian, the number that made it; NaN for a motor with a
        MAP only).
    acceptance : the ensemble's mean acceptance fraction.
    walkers : the ensemble's size (draws are ordered step by step, walker fastest).
    """

    names: tuple
    mu: np.ndarray
    sigma: np.ndarray
    chol: np.ndarray
    correlated: bool
    motors: tuple
    gaussian: tuple
    ess: tuple
    acceptance: float
    walkers: int

    def scale(self) -> np.ndarray:
        """``(N, P, P)``: the Cholesky factors of the population covariances Σ."""
        return self.sigma[:, :, None] * self.chol

    def covariance(self) -> np.ndarray:
        """``(N, P, P)``: the population covariances Σ."""
        s = self.scale()
        return s @ np.swapaxes(s, 1, 2)

    @cached_property
    def log_likelihoods(self) -> np.ndarray:
        """``(M, N)``: each motor's log-likelihood at each population draw (computed
        once: the outlier test and the LOO comparison both read it)."""
        scale = self.scale()
        return np.stack([_motor_loglik(m, g, self.mu, scale)
                         for m, g in zip(self.motors, self.gaussian, strict=True)])


def _motor_loglik(m: MotorEvidence, gaussian: bool, mu, scale) -> np.ndarray:
    """A motor's log-likelihood of the population at each of the ``W`` rows of ``mu``
    and ``scale`` (Cholesky factors of Σ): its draws reweighted, or its Gaussian's
    marginal."""
    if gaussian:
        return _gaussian_loglik(m.mean[None], m.cov_likelihood[None], mu, scale)[:, 0]
    return _reweighted_loglik(m.draws[None], m.log_prior[None], mu, scale)[:, 0]


def _precision(scale):
    """``(W, P, P)`` precisions and ``(W,)`` ``−½·log det Σ`` of Cholesky factors."""
    inv = np.linalg.inv(scale)
    half_logdet = np.sum(np.log(np.abs(np.diagonal(scale, axis1=1, axis2=2))), axis=1)
    return np.swapaxes(inv, 1, 2) @ inv, -half_logdet


def outer_rows(x) -> np.ndarray:
    """``(N, P·P)``: each point's outer product with itself, flattened (what
    :func:`log_density` multiplies the precisions by)."""
    x = np.atleast_2d(x)
    return np.einsum("ni,nj->nij", x, x).reshape(len(x), -1)


def log_density(x, mu, scale, xx=None) -> np.ndarray:
    """``(W, N)``: the population's log-density of points ``x`` ``(N, P)`` at each of
    ``W`` population points (the quadratic form expanded into matrix products; ``xx``
    the points' :func:`outer_rows` when already at hand)."""
    x = np.atleast_2d(x)
    w, p = mu.shape
    prec, norm = _precision(scale)
    xx = outer_rows(x) if xx is None else xx
    quad = (xx @ prec.reshape(w, -1).T).T
    pm = np.einsum("wij,wj->wi", prec, mu)
    quad = quad - 2.0 * pm @ x.T + np.einsum("wi,wi->w", pm, mu)[:, None]
    return -0.5 * quad + (norm - 0.5 * p * _LOG_2PI)[:, None]


def _reweighted_loglik(draws, log_prior, mu, scale, xx=None) -> np.ndarray:
    """``(W, M)``: ``log mean_s N(x_s | μ, Σ)/π(x_s)`` of motors' draws ``(M, S, P)``
    with their prior densities ``(M, S)``, at each of ``W`` population points (``xx``:
    the draws' :func:`outer_rows`, when at hand)."""
    m, s, p = draws.shape
    lp = log_density(draws.reshape(m * s, p), mu, scale, xx).reshape(-1, m, s) \
        - log_prior[None]
    top = lp.max(axis=2, keepdims=True)
    return top[:, :, 0] + np.log(np.mean(np.exp(lp - top), axis=2))


def _gaussian_loglik(mean, cov, mu, scale) -> np.ndarray:
    """``(W, M)``: ``log N(mean_m | μ, Σ + cov_m)`` of Gaussians ``(M, P)``,
    ``(M, P, P)`` at each of ``W`` population points."""
    p = mean.shape[-1]
    c = cov[None] + (scale @ np.swapaxes(scale, 1, 2))[:, None]
    sign, logdet = np.linalg.slogdet(c)
    r = mean[None] - mu[:, None, :]
    quad = np.einsum("wmi,wmi->wm", r, np.linalg.solve(c, r[..., None])[..., 0])
    return np.where(sign > 0, -0.5 * (quad + logdet + p * _LOG_2PI), -np.inf)


def _unpack(params, p: int, correlated: bool):
    """``(μ, σ, chol, log σ)`` of the sampler's rows ``(μ, log σ[, y])``."""
    mu, log_sigma = params[:, :p], params[:, p:2 * p]
    chol = (cholesky_corr(params[:, 2 * p:], p) if correlated
            else np.broadcast_to(np.eye(p), (len(params), p, p)))
    return mu, np.exp(log_sigma), chol, log_sigma


def _log_posterior(motors, gaussian, correlated: bool):
    drawn = [m for m, g in zip(motors, gaussian, strict=True) if not g]
    normal = [m for m, g in zip(motors, gaussian, strict=True) if g]
    draws = np.stack([m.draws for m in drawn]) if drawn else None
    log_prior = np.stack([m.log_prior for m in drawn]) if drawn else None
    xx = outer_rows(draws.reshape(-1, draws.shape[-1])) if drawn else None  # once, not per step
    means = np.stack([m.mean for m in normal]) if normal else None
    covs = np.stack([m.cov_likelihood for m in normal]) if normal else None
    p = motors[0].mean.size

    def fn(params):
        params = np.atleast_2d(params)
        mu, sigma, chol, log_sigma = _unpack(params, p, correlated)
        scale = sigma[:, :, None] * chol
        # half-normal on σ, sampled in log σ (its Jacobian); LKJ on the correlation
        lp = np.sum(-0.5 * (sigma / SPREAD_SCALE) ** 2 + log_sigma, axis=1)
        if correlated:
            lp = lp + lkj_log_prior(params[:, 2 * p:], p)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if draws is not None:
                lp = lp + _reweighted_loglik(draws, log_prior, mu, scale, xx).sum(axis=1)
            if means is not None:
                lp = lp + _gaussian_loglik(means, covs, mu, scale).sum(axis=1)
        return np.where(np.isfinite(lp), lp, -np.inf)

    return fn


def _start(motors, rng, walkers: int, correlated: bool) -> np.ndarray:
    centres = np.array([m.mean for m in motors])
    mu0 = np.median(centres, axis=0)
    spread = np.std(centres, axis=0) if len(motors) > 1 else np.full(mu0.size, 0.1)
    log_s0 = np.log(np.clip(spread, 1e-3, SPREAD_SCALE))
    pairs = n_pairs(mu0.size) if correlated else 0
    base = np.concatenate([mu0, log_s0, np.zeros(pairs)])
    scale = np.concatenate([np.maximum(spread, 1e-3) / np.sqrt(len(motors)),
                            np.full(mu0.size + pairs, 0.1)])
    return base + rng.standard_normal((walkers, base.size)) * scale


def _sample(motors, gaussian, seed: int, correlated: bool):
    rng = np.random.default_rng(seed)
    p = motors[0].mean.size
    dim = 2 * p + (n_pairs(p) if correlated else 0)
    walkers = max(WALKERS, 2 * dim + 2)
    sampler = emcee.EnsembleSampler(walkers, dim, _log_posterior(motors, gaussian, correlated),
                                    vectorize=True,
                                    moves=_moves())
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    sampler.run_mcmc(_start(motors, rng, walkers, correlated), BURN + KEEP, progress=False)
    chain = sampler.get_chain(discard=BURN, thin=THIN, flat=True)
    mu, sigma, chol, _ = _unpack(chain, p, correlated)
    return mu, sigma, np.array(chol), float(np.mean(sampler.acceptance_fraction)), walkers


def _ess(m: MotorEvidence, mu, scale) -> float:
    """Effective draws of ``m``'s reweighting at one population point."""
    lw = log_density(m.draws, mu[None], scale[None])[0] - m.log_prior
    w = np.exp(lw - lw.max())
    return float(w.sum() ** 2 / np.sum(w * w))


def fit_population(motors, *, seed: int = 0, correlated: bool = False) -> Population:
    """The population posterior of ``motors`` (:class:`MotorEvidence` of one parameter
    list), each motor reweighted where its draws carry it and a Gaussian elsewhere;
    with ``correlated``, the parameters' correlation across the lot fitted too."""
    motors = tuple(motors)
    if not motors:
        raise ValueError("a population needs at least one motor")
    names = motors[0].names
    if any(m.names != names for m in motors):
        raise ValueError("every motor of a population must have the same parameters")
    gaussian = [m.draws is None for m in motors]
    ess = [np.nan] * len(motors)
    for _ in range(2):
        mu, sigma, chol, acc, walkers = _sample(motors, gaussian, seed, correlated)
        centre = mu.mean(axis=0)
        spread = np.exp(np.log(sigma).mean(axis=0))
        scale = spread[:, None] * np.linalg.cholesky(np.mean(chol @ np.swapaxes(chol, 1, 2),
                                                             axis=0))
        ess = [e if g else _ess(m, centre, scale) for m, g, e in zip(motors, gaussian, ess,
                                                                     strict=True)]
        thin = [not g and e < MIN_ESS for g, e in zip(gaussian, ess, strict=True)]
        if not any(thin):
            break
        gaussian = [g or t for g, t in zip(gaussian, thin, strict=True)]
    return Population(names, mu, sigma, chol, correlated, motors, tuple(gaussian),
                      tuple(ess), acc, walkers)
