"""What one motor's own fit tells the population stage (:mod:`.population`): its
posterior of the pooled parameters in log, as draws with their prior density, and as
the Gaussian likelihood its posterior over its prior leaves."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MotorEvidence", "motor_evidence", "from_run", "subset", "MAX_DRAWS"]

MAX_DRAWS = 200  # draws a motor keeps for the reweighting (evenly thinned)
_LOG_2PI = float(np.log(2 * np.pi))


@dataclass(frozen=True)
class MotorEvidence:
    """One motor's evidence about the pooled parameters ``names`` (all in log).

    Attributes
    ----------
    name : the motor (its session's name).
    names, priors : the parameters and their priors ``(kind, centre, scale)``.
    draws : posterior draws ``(S, P)`` of the logs, or None for a MAP-only fit.
    log_prior : the motor's own prior density of each draw, in log space ``(S,)``.
    post_mean, post_cov : its own posterior's mean and covariance (the draws', or the
        Laplace approximation's).
    mean, cov_likelihood : the Gaussian likelihood the posterior leaves over the prior
        (a direction the data do not determine gets a very wide variance).
    """

    name: str
    names: tuple
    priors: tuple
    draws: np.ndarray | None
    log_prior: np.ndarray | None
    post_mean: np.ndarray
    post_cov: np.ndarray
    mean: np.ndarray
    cov_likelihood: np.ndarray


def _log_prior(x, priors) -> np.ndarray:
    """The priors' density of log-values ``x`` ``(S, P)`` in log space: a log-normal is
    Gaussian there; a Gaussian in value carries the Jacobian ``exp(x)``."""
    out = np.zeros(x.shape[0])
    for k, (kind, centre, scale) in enumerate(priors):
        if kind == "lognormal":
            z = (x[:, k] - np.log(centre)) / scale
            out += -0.5 * z * z - np.log(scale) - 0.5 * _LOG_2PI
        else:
            z = (np.exp(x[:, k]) - centre) / scale
            out += -0.5 * z * z - np.log(scale) - 0.5 * _LOG_2PI + x[:, k]
    return out


def _prior_gaussian(priors):
    """The priors as a Gaussian in log space (a Gaussian in value linearised at its
    centre): centres and precisions."""
    centre = np.array([np.log(c) for _, c, _ in priors])
    sd = np.array([s if kind == "lognormal" else s / abs(c) for kind, c, s in priors])
    return centre, 1.0 / sd**2


def motor_evidence(name: str, names, priors, *, draws=None, theta=None, cov=None
                   ) -> MotorEvidence:
    """A motor's evidence from posterior draws of the log-values ``(S, P)``, or from a
    MAP ``theta`` and its Laplace ``cov`` (log); ``priors`` per parameter ``(kind,
    centre, scale)`` as :class:`~.params.Prior` states them."""
    if draws is not None:
        draws = np.asarray(draws, dtype=float)
        if draws.shape[0] > MAX_DRAWS:
            draws = draws[np.linspace(0, draws.shape[0] - 1, MAX_DRAWS).astype(int)]
        post_mean, post_cov = draws.mean(axis=0), np.atleast_2d(np.cov(draws, rowvar=False))
        log_prior = _log_prior(draws, priors)
    else:
        post_mean, post_cov = np.asarray(theta, dtype=float), np.asarray(cov, dtype=float)
        log_prior = None
    centre, prec = _prior_gaussian(priors)
    vals, vecs = np.linalg.eigh(0.5 * (post_cov + post_cov.T))
    lam_post = (vecs / np.clip(vals, 1e-300, None)) @ vecs.T
    lam = lam_post - np.diag(prec)
    vals, vecs = np.linalg.eigh(0.5 * (lam + lam.T))
    vals = np.clip(vals, 1e-9 * max(float(np.max(np.diag(lam_post))), 1e-300), None)
    cov_l = (vecs / vals) @ vecs.T
    mean = cov_l @ (lam_post @ post_mean - prec * centre)
    return MotorEvidence(name, tuple(names), tuple(priors), draws, log_prior, post_mean,
                         post_cov, mean, cov_l)


def subset(m: MotorEvidence, names) -> MotorEvidence:
    """``m``'s evidence about ``names`` alone (a subset of its parameters)."""
    idx = [m.names.index(n) for n in names]
    priors = [m.priors[k] for k in idx]
    if m.draws is not None:
        return motor_evidence(m.name, names, priors, draws=m.draws[:, idx])
    return motor_evidence(m.name, names, priors, theta=m.post_mean[idx],
                          cov=m.post_cov[np.ix_(idx, idx)])


def from_run(result, names) -> MotorEvidence:
    """The evidence of a :class:`~pmdc_bayes.run.RunResult` about ``names``: its posterior draws
    when it has them, else its MAP and Laplace covariance (from the summary for a run
    read back from disk)."""
    reg = result.model.registry
    idx = [reg.index(n) for n in names]
    priors = [(reg[n].prior.kind, reg[n].prior.centre, reg[n].prior.scale) for n in names]
    name = result.summary.get("session", {}).get("name") or result.session.name
    if result.draws is not None:
        return motor_evidence(name, names, priors, draws=np.log(result.draws[:, idx]))
    if result.fit is not None:
        theta, cov = np.asarray(result.fit.theta), np.asarray(result.fit.cov_log)
    else:
        params, fit = result.summary["parameters"], result.summary["fit"]
        order = list(fit["names"])
        values = np.array([params[n]["map"] for n in order])
        sd_log = np.array([params[n]["map_sd"] for n in order]) / np.abs(values)
        theta = np.log(np.abs(values))
        cov = np.asarray(fit["correlation"]) * np.outer(sd_log, sd_log)
        idx = [order.index(n) for n in names]
    return motor_evidence(name, names, priors, theta=theta[idx], cov=cov[np.ix_(idx, idx)])
