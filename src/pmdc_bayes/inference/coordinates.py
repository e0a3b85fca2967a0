"""The coordinates the posterior sampler moves in.

The fit works in θ, where a positive quantity is its logarithm.  The sampler moves in
φ: the value itself for a positive quantity the fit already knows to better than a
factor e (its Laplace sd in log space below :data:`LINEAR_BELOW`), θ otherwise.  The
model is linear in the motor's parameters where they enter its equations (the
armature's ``Ra·i + La·di/dt``, the shaft's ``J·dω/dt + B·ω + Tc``), so where the data
trade two of them (viscous against Coulomb friction on a speed-only session) the
posterior's ridge is straight in value and curved in log: in log, with the lognormal
priors' tail towards zero at one end, the ensemble's moves cross it slowly (on a fuzzed
session with a weakly identified Coulomb torque, an autocorrelation time of 230 steps
in log against 9 in value).  A quantity known only within decades keeps its log, where
its posterior is closer to Gaussian.

The density in φ is the posterior in θ times ``|dθ/dφ| = 1/φ`` for each coordinate in
value, so the draws, mapped back, are draws of the same posterior.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["LINEAR_BELOW", "Coordinates", "Laplace"]

LINEAR_BELOW = 1.0  # a positive quantity's Laplace sd in log below which φ is its value


class Laplace(NamedTuple):
    """The Laplace approximation in the sampler's coordinates: its centre ``theta`` and
    covariance ``cov_log`` (named as a fit's, which the moves read)."""

    theta: np.ndarray
    cov_log: np.ndarray


class Coordinates:
    """The map between θ and the sampler's φ: ``linear[i]`` where φ_i = exp(θ_i)."""

    def __init__(self, linear):
        self.linear = np.asarray(linear, dtype=bool)

    @classmethod
    def for_fit(cls, registry, fit) -> Coordinates:
        """Value coordinates for the log-transformed parameters of ``registry`` whose
        Laplace sd in ``fit`` is below :data:`LINEAR_BELOW`."""
        sd = np.sqrt(np.clip(np.diag(np.asarray(fit.cov_log, dtype=float)), 0.0, None))
        logs = np.array([s.transform == "log" for s in registry.specs])
        return cls(logs & (sd < LINEAR_BELOW))

    def to_theta(self, phi) -> np.ndarray:
        """θ of ``phi`` ``(..., P)``; NaN where a value coordinate is not positive."""
        theta = np.array(phi, dtype=float)
        v = theta[..., self.linear]
        theta[..., self.linear] = np.log(np.where(v > 0.0, v, np.nan))
        return theta

    def from_theta(self, theta) -> np.ndarray:
        phi = np.array(theta, dtype=float)
        phi[..., self.linear] = np.exp(phi[..., self.linear])
        return phi

    def log_jacobian(self, theta) -> np.ndarray:
        """``log|dθ/dφ|`` at ``theta`` ``(..., P)``: the density in φ is the density in θ
        plus this."""
        return -np.sum(np.asarray(theta)[..., self.linear], axis=-1)

    def laplace(self, fit) -> Laplace:
        """``fit``'s Laplace approximation carried to φ (to first order)."""
        theta = np.asarray(fit.theta, dtype=float)
        d = np.where(self.linear, np.exp(theta), 1.0)
        return Laplace(self.from_theta(theta), np.asarray(fit.cov_log) * np.outer(d, d))

    def log_prob(self, log_prob):
        """``log_prob`` (of θ, vectorised) as the density of φ; -inf where a value
        coordinate is not positive."""
        def in_phi(phi):
            theta = self.to_theta(np.atleast_2d(phi))
            ok = np.all(np.isfinite(theta), axis=1)
            out = np.full(theta.shape[0], -np.inf)
            if ok.any():
                out[ok] = log_prob(theta[ok]) + self.log_jacobian(theta[ok])
            return out
        return in_phi
