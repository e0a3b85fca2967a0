"""The coordinates the posterior sampler moves in.

The fit works in θ, where a positive quantity is its logarithm.  The sampler moves in
φ: either θ itself, or every positive quantity in value, whichever the posterior is
closer to Gaussian in around the MAP (:meth:`Coordinates.for_fit`).  Which one depends
on the ridge the data leave: where they trade two parameters' sum (viscous against
Coulomb friction: ``B·ω + Tc``) the ridge is straight in value
and curved in log, and in log the lognormal priors' tail towards zero adds a long arm
to it; where they trade a product (a current limit against the torque constant:
``K·Imax``) it is straight in log.  On a fuzzed session of the first kind the
autocorrelation time was 230 steps in log and 9 in value; on ``data/bench``, of the
second kind, 20 in log and 140 in value.

The density in φ is the posterior in θ times ``|dθ/dφ| = 1/φ`` for each coordinate in
value, so the draws, mapped back, are draws of the same posterior.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["PROBE", "CLEARLY", "Coordinates", "Laplace"]

PROBE = 2.0  # the Laplace sds either side of the MAP at which the coordinates are compared
CLEARLY = 1.0  # value's summed misprediction must be this much smaller (log-density units)


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
    def for_fit(cls, registry, fit, log_prob) -> Coordinates:
        """θ, or every log-transformed parameter of ``registry`` in value: whichever
        ``fit``'s Laplace approximation (carried to them) predicts the log-posterior
        ``log_prob`` (of θ, vectorised) better along each positive parameter's
        regression line (the parameters moved by their Laplace regression on it, to
        :data:`PROBE` sds either side of the MAP, where a Gaussian falls by PROBE²/2):
        the summed misprediction is compared; θ unless value's is smaller by
        :data:`CLEARLY`."""
        logs = np.array([s.transform == "log" for s in registry.specs])
        if not logs.any():
            return cls(logs)
        theta, value = cls(np.zeros_like(logs)), cls(logs)
        better = value._misfit(fit, log_prob, logs) + CLEARLY < \
            theta._misfit(fit, log_prob, logs)
        return value if better else theta

    def _misfit(self, fit, log_prob, along) -> float:
        """Σ |log-density − its Laplace prediction| in these coordinates at ±PROBE sd
        along the regression line of each parameter in ``along`` (∞ where a point
        leaves the parameters' range)."""
        centre, cov = self.laplace(fit)
        sd = np.sqrt(np.diag(cov))
        lines = [cov[:, i] / cov[i, i] * sd[i] * PROBE * side
                 for i in np.flatnonzero(along) for side in (-1.0, 1.0)]
        density = self.log_prob(log_prob)
        drop = density(centre[None] + np.array(lines)) - density(centre[None])[0]
        return float(np.sum(np.abs(drop + 0.5 * PROBE**2)))

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
