"""A lot of motors as a population: the second stage of a hierarchical fit.

Each motor's parameters (in log: K, B, J, Ra, and Tc or La where every motor has them)
are drawn from a log-normal population, ``log x_m ~ N(μ, diag(σ²))``: ``exp(μ)`` the
lot's median and ``σ`` its spread (a relative sd).  The first stage is each motor's
own fit (:mod:`.motor_evidence` reads it); this one combines them without fitting a
motor again.  A motor's likelihood of ``(μ, σ)`` is its posterior draws reweighted from
its own prior to the population (``mean_s N(x_s | μ, σ) / π_m(x_s)``), or, where its
draws are too few to carry that (fewer than :data:`MIN_ESS` effective draws at the
population's posterior mean) or it has only a MAP, the Gaussian that its posterior
over its prior leaves (exact for a Gaussian posterior).  ``(μ, log σ)`` are sampled
with emcee (a flat prior on μ, a half-normal of scale :data:`SPREAD_SCALE` on σ).
"""

from __future__ import annotations

from dataclasses import dataclass

import emcee
import numpy as np

from .motor_evidence import MotorEvidence

__all__ = ["Population", "fit_population", "MIN_ESS", "SPREAD_SCALE"]

MIN_ESS = 25.0  # effective reweighted draws a motor needs at the population's mean
SPREAD_SCALE = 1.0  # half-normal scale of a parameter's spread (log units)
WALKERS = 32
BURN, KEEP = 1000, 1000  # steps: burn-in, then kept (thinned to THIN)
THIN = 10
_LOG_2PI = float(np.log(2 * np.pi))


@dataclass(frozen=True)
class Population:
    """The lot's population posterior.

    Attributes
    ----------
    names : the pooled parameters (SI names).
    mu, sigma : draws ``(N, P)`` of the log-median and the spread (log sd).
    motors : the motors' evidence, in the order given.
    gaussian : per motor, whether its Gaussian stood in for its reweighted draws.
    ess : per motor, the effective reweighted draws at the population's mean (where
        it fell back to its Gaussian, the number that made it; NaN for a motor with a
        MAP only).
    acceptance : the ensemble's mean acceptance fraction.
    """

    names: tuple
    mu: np.ndarray
    sigma: np.ndarray
    motors: tuple
    gaussian: tuple
    ess: tuple
    acceptance: float

    def log_likelihoods(self) -> np.ndarray:
        """``(M, N)``: each motor's log-likelihood at each population draw."""
        return np.stack([_motor_loglik(m, g, self.mu, self.sigma)
                         for m, g in zip(self.motors, self.gaussian, strict=True)])


def _normal_logpdf(x, mu, sigma):
    """Σ over the last axis of the Gaussian log-density."""
    z = (x - mu) / sigma
    return -0.5 * np.sum(z * z, axis=-1) - np.sum(np.log(sigma), axis=-1) \
        - 0.5 * x.shape[-1] * _LOG_2PI


def _motor_loglik(m: MotorEvidence, gaussian: bool, mu, sigma) -> np.ndarray:
    """A motor's log-likelihood of ``(μ, σ)`` for each of the ``W`` rows of ``mu`` and
    ``sigma``: its draws reweighted, or its Gaussian's marginal."""
    if gaussian:
        return _gaussian_loglik(m.mean[None], m.cov_likelihood[None], mu, sigma)[:, 0]
    return _reweighted_loglik(m.draws[None], m.log_prior[None], mu, sigma)[:, 0]


def _reweighted_loglik(draws, log_prior, mu, sigma) -> np.ndarray:
    """``(W, M)``: ``log mean_s N(x_s | μ, σ)/π(x_s)`` of motors' draws ``(M, S, P)``
    with their prior densities ``(M, S)``, at each of ``W`` population points (the
    squared distances expanded into matrix products)."""
    m, s, p = draws.shape
    x = draws.reshape(m * s, p)
    prec = 1.0 / sigma**2
    quad = (x * x) @ prec.T - 2.0 * x @ (mu * prec).T + np.sum(mu * mu * prec, axis=1)
    norm = -np.sum(np.log(sigma), axis=1) - 0.5 * p * _LOG_2PI
    lp = (-0.5 * quad + norm).reshape(m, s, -1) - log_prior[:, :, None]
    top = lp.max(axis=1, keepdims=True)
    return (top[:, 0, :] + np.log(np.mean(np.exp(lp - top), axis=1))).T


def _gaussian_loglik(mean, cov, mu, sigma) -> np.ndarray:
    """``(W, M)``: ``log N(mean_m | μ, diag(σ²) + cov_m)`` of Gaussians ``(M, P)``,
    ``(M, P, P)`` at each of ``W`` population points."""
    p = mean.shape[-1]
    c = cov[None] + (sigma[:, None, :, None] ** 2) * np.eye(p)
    sign, logdet = np.linalg.slogdet(c)
    r = mean[None] - mu[:, None, :]
    quad = np.einsum("wmi,wmi->wm", r, np.linalg.solve(c, r[..., None])[..., 0])
    return np.where(sign > 0, -0.5 * (quad + logdet + p * _LOG_2PI), -np.inf)


def _log_posterior(motors, gaussian):
    drawn = [m for m, g in zip(motors, gaussian, strict=True) if not g]
    normal = [m for m, g in zip(motors, gaussian, strict=True) if g]
    draws = np.stack([m.draws for m in drawn]) if drawn else None
    log_prior = np.stack([m.log_prior for m in drawn]) if drawn else None
    means = np.stack([m.mean for m in normal]) if normal else None
    covs = np.stack([m.cov_likelihood for m in normal]) if normal else None

    def fn(params):
        params = np.atleast_2d(params)
        p = params.shape[1] // 2
        mu, log_sigma = params[:, :p], params[:, p:]
        sigma = np.exp(log_sigma)
        # half-normal on σ, sampled in log σ (its Jacobian)
        lp = np.sum(-0.5 * (sigma / SPREAD_SCALE) ** 2 + log_sigma, axis=1)
        if draws is not None:
            lp = lp + _reweighted_loglik(draws, log_prior, mu, sigma).sum(axis=1)
        if means is not None:
            lp = lp + _gaussian_loglik(means, covs, mu, sigma).sum(axis=1)
        return np.where(np.isfinite(lp), lp, -np.inf)

    return fn


def _start(motors, rng) -> np.ndarray:
    centres = np.array([m.mean for m in motors])
    mu0 = np.median(centres, axis=0)
    spread = np.std(centres, axis=0) if len(motors) > 1 else np.full(mu0.size, 0.1)
    log_s0 = np.log(np.clip(spread, 1e-3, SPREAD_SCALE))
    base = np.concatenate([mu0, log_s0])
    scale = np.concatenate([np.maximum(spread, 1e-3) / np.sqrt(len(motors)),
                            np.full(mu0.size, 0.1)])
    return base + rng.standard_normal((WALKERS, base.size)) * scale


def _sample(motors, gaussian, seed: int):
    rng = np.random.default_rng(seed)
    p = motors[0].mean.size
    sampler = emcee.EnsembleSampler(WALKERS, 2 * p, _log_posterior(motors, gaussian),
                                    vectorize=True,
                                    moves=[(emcee.moves.DEMove(), 0.8),
                                           (emcee.moves.DESnookerMove(), 0.2)])
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    sampler.run_mcmc(_start(motors, rng), BURN + KEEP, progress=False)
    chain = sampler.get_chain(discard=BURN, thin=THIN, flat=True)
    return chain[:, :p], np.exp(chain[:, p:]), float(np.mean(sampler.acceptance_fraction))


def _ess(m: MotorEvidence, mu, sigma) -> float:
    """Effective draws of ``m``'s reweighting at one population point."""
    lw = _normal_logpdf(m.draws, mu, sigma) - m.log_prior
    w = np.exp(lw - lw.max())
    return float(w.sum() ** 2 / np.sum(w * w))


def fit_population(motors, *, seed: int = 0) -> Population:
    """The population posterior of ``motors`` (:class:`MotorEvidence` of one parameter
    list), each motor reweighted where its draws carry it and a Gaussian elsewhere."""
    motors = tuple(motors)
    if not motors:
        raise ValueError("a population needs at least one motor")
    names = motors[0].names
    if any(m.names != names for m in motors):
        raise ValueError("every motor of a population must have the same parameters")
    gaussian = [m.draws is None for m in motors]
    ess = [np.nan] * len(motors)
    for _ in range(2):
        mu, sigma, acc = _sample(motors, gaussian, seed)
        centre, spread = mu.mean(axis=0), np.exp(np.log(sigma).mean(axis=0))
        ess = [e if g else _ess(m, centre, spread) for m, g, e in zip(motors, gaussian, ess,
                                                                      strict=True)]
        thin = [not g and e < MIN_ESS for g, e in zip(gaussian, ess, strict=True)]
        if not any(thin):
            break
        gaussian = [g or t for g, t in zip(gaussian, thin, strict=True)]
    return Population(names, mu, sigma, motors, tuple(gaussian), tuple(ess), acc)
