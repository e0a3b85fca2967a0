"""The coordinates the posterior sampler moves in.

The fit works in θ, where a positive quantity is its logarithm.  The sampler moves in
φ: θ itself, every positive quantity in value, or θ with the motor's parameters
replaced by what a step of the speed fixes (:mod:`.motor_coordinates`), whichever the
posterior is closest to Gaussian in around the MAP (:meth:`Coordinates.for_fit`).
Which one depends on the ridge the data leave: where they trade two parameters' sum
(viscous against Coulomb friction: ``B·ω + Tc``) the ridge is straight in value and
curved in log, and in log the lognormal priors' tail towards zero adds a long arm to
it; where they trade a product (a current limit against the torque constant:
``K·Imax``) it is straight in log; where a speed-only step fixes only the motor's
response, K, B and J (and La) lie on a curve in either, straight in the motor's own.
On a fuzzed session of the first kind the autocorrelation time was 230 steps in log
and 9 in value; on ``data/bench``, of the second kind, 20 in log and 140 in value.

The density in φ is the posterior in θ times ``|dθ/dφ|`` (``1/φ`` for each coordinate
in value), so the draws, mapped back, are draws of the same posterior.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["PROBE", "CLEARLY", "CoordinateMap", "Coordinates", "Laplace", "exact_laplace"]

PROBE = 2.0  # the Laplace sds either side of the MAP at which the coordinates are compared
CLEARLY = 1.0  # another's summed misprediction must be this much smaller than θ's (log-density)
NO_MASS = 20.0  # a log-density this far below the Laplace prediction: no mass, however far
QUADRATIC = 0.1  # how far twice the steps may move the differenced curvature, in its own metric


class Laplace(NamedTuple):
    """The Laplace approximation in the sampler's coordinates: its centre ``theta`` and
    covariance ``cov_log`` (named as a fit's, which the moves read)."""

    theta: np.ndarray
    cov_log: np.ndarray


def exact_laplace(fit, log_prob) -> Laplace:
    """The Laplace approximation at ``fit``'s MAP from the log-posterior's own curvature
    (central differences of ``log_prob``, of θ and vectorised, in steps of a thousandth
    of each Laplace sd): the fit's is Gauss–Newton's, which leaves out the residuals'
    curvature and so, along a curved ridge the data leave, can be several times too wide.
    The fit's own (the MAP's, where the fit's spans several optima) where the differences
    do not give a maximum (a Hessian not negative definite), or where steps twice as
    long give a curvature that differs by more than :data:`QUADRATIC` of the curvature
    itself (in its own metric): the steps then reach past the region where the
    log-posterior is quadratic, as across a ridge a part in 10⁶ of its length wide, and
    measure its walls, not its curvature."""
    theta = np.asarray(fit.theta, dtype=float)
    h = 1e-3 * np.minimum(np.sqrt(np.abs(np.diag(np.asarray(fit.cov_log, dtype=float)))), 1.0)
    own = getattr(fit, "cov_map", None)  # the MAP's own, where cov_log spans several optima
    cov = np.asarray(fit.cov_log if own is None else own, dtype=float)
    hess, longer = (_differences(theta, step, log_prob) for step in (h, 2.0 * h))
    if not (np.all(np.isfinite(hess)) and np.all(np.isfinite(longer))):
        return Laplace(theta, cov)
    eig, vec = np.linalg.eigh(-hess)
    if eig[0] <= 0:
        return Laplace(theta, cov)
    scale = vec / np.sqrt(eig)  # (−H)^(-1/2): the curvature's own metric
    if np.max(np.abs(np.linalg.eigvalsh(scale.T @ (longer - hess) @ scale))) > QUADRATIC:
        return Laplace(theta, cov)
    return Laplace(theta, np.linalg.inv(-hess))


def _differences(theta, h, log_prob) -> np.ndarray:
    """The Hessian of ``log_prob`` at ``theta`` by central differences in steps ``h``."""
    n = theta.size
    pairs = [(i, j) for i in range(n) for j in range(i, n)]
    signs = ((1, 1), (1, -1), (-1, 1), (-1, -1))
    points = np.repeat(theta[None], 4 * len(pairs), axis=0)
    for p, (i, j) in enumerate(pairs):
        for q, (a, b) in enumerate(signs):
            points[4 * p + q, i] += a * h[i]
            points[4 * p + q, j] += b * h[j]
    v = np.asarray(log_prob(points), dtype=float).reshape(len(pairs), 4)
    hess = np.zeros((n, n))
    for p, (i, j) in enumerate(pairs):
        hess[i, j] = hess[j, i] = (v[p, 0] - v[p, 1] - v[p, 2] + v[p, 3]) / (4 * h[i] * h[j])
    return hess


class CoordinateMap:
    """What every system of coordinates shares, given its ``to_theta(phi)``,
    ``from_theta(theta)`` and ``log_jacobian(theta)`` (``log|dθ/dφ|``): the Laplace
    approximation carried to φ, the density in φ and how close to Gaussian it is around
    the MAP."""

    kind = "theta"

    def jacobian(self, theta) -> np.ndarray:
        """``dφ/dθ`` at ``theta`` (central differences)."""
        theta = np.asarray(theta, dtype=float)
        h = 1e-6 * np.maximum(1.0, np.abs(theta))
        cols = [(self.from_theta(theta + h[i] * e) - self.from_theta(theta - h[i] * e))
                / (2 * h[i]) for i, e in enumerate(np.eye(theta.size))]
        return np.stack(cols, axis=1)

    def laplace(self, fit) -> Laplace:
        """``fit``'s Laplace approximation carried to φ (to first order)."""
        theta = np.asarray(fit.theta, dtype=float)
        jac = self.jacobian(theta)
        return Laplace(self.from_theta(theta), jac @ np.asarray(fit.cov_log) @ jac.T)

    def log_prob(self, log_prob):
        """``log_prob`` (of θ, vectorised) as the density of φ; -inf where φ maps to no
        θ (a value coordinate that is not positive)."""
        def in_phi(phi):
            theta = self.to_theta(np.atleast_2d(phi))
            ok = np.all(np.isfinite(theta), axis=1)
            out = np.full(theta.shape[0], -np.inf)
            if ok.any():
                out[ok] = log_prob(theta[ok]) + self.log_jacobian(theta[ok])
            return out
        return in_phi

    def _misfit(self, fit, log_prob, along) -> float:
        """Σ |log-density − its Laplace prediction| in these coordinates at ±PROBE sd
        along the regression line of each parameter in ``along``, each term at most
        :data:`NO_MASS` (a point that leaves the parameters' range, or where the density
        has fallen by that much more than predicted, holds no mass either way)."""
        centre, cov = self.laplace(fit)
        sd = np.sqrt(np.diag(cov))
        lines = [cov[:, i] / cov[i, i] * sd[i] * PROBE * side
                 for i in np.flatnonzero(along) for side in (-1.0, 1.0)]
        density = self.log_prob(log_prob)
        drop = density(centre[None] + np.array(lines)) - density(centre[None])[0]
        return float(np.sum(np.minimum(np.abs(drop + 0.5 * PROBE**2), NO_MASS)))

    def in_value(self, names) -> list[str]:
        """The parameters moved in value rather than in log."""
        return []


class Coordinates(CoordinateMap):
    """The map between θ and the sampler's φ: ``linear[i]`` where φ_i = exp(θ_i)."""

    def __init__(self, linear):
        self.linear = np.asarray(linear, dtype=bool)
        self.kind = "value" if self.linear.any() else "theta"

    @classmethod
    def for_fit(cls, registry, fit, log_prob, others=()) -> CoordinateMap:
        """θ, every log-transformed parameter of ``registry`` in value, or one of
        ``others`` (the motor's own coordinates, :func:`.motor_coordinates.motor_maps`):
        whichever ``fit``'s Laplace approximation (carried to them) predicts the
        log-posterior ``log_prob`` (of θ, vectorised) best along each positive parameter's
        regression line (the parameters moved by their Laplace regression on it, to
        :data:`PROBE` sds either side of the MAP, where a Gaussian falls by PROBE²/2):
        the summed misprediction is compared; θ unless another's is smaller by
        :data:`CLEARLY`."""
        logs = np.array([s.transform == "log" for s in registry.specs])
        theta = cls(np.zeros_like(logs))
        if not logs.any():
            return theta
        others = [cls(logs), *others]
        misfit = {c: c._misfit(fit, log_prob, logs) for c in [theta, *others]}
        best = min(others, key=misfit.get)
        return best if misfit[best] + CLEARLY < misfit[theta] else theta

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

    def jacobian(self, theta) -> np.ndarray:
        return np.diag(np.where(self.linear, np.exp(np.asarray(theta, dtype=float)), 1.0))

    def in_value(self, names) -> list[str]:
        return [n for n, v in zip(names, self.linear, strict=True) if v]
