"""Coordinates of the motor itself, for the ridges a step of the speed leaves.

A step of the speed fixes the motor's response ``ω/V = G/(a₂·s² + a₁·s + 1)`` (equation
(7) divided by ``S = Ra·B + K²``): the steady gain ``G = K/S`` and the coefficients
``a₁ = (Ra·J + La·B)/S`` and ``a₂ = La·J/S``.  Without a current those three are all
the data say about Ra, La, K, B and J, and with a fine encoder they say it to a part in
10⁶ or better, so the posterior is a thin ridge along which the rest trade, curved in
θ.  :class:`MotorConstants` straightens it where the electrical time constant does not
matter (``a₂`` and ``La·B/S`` negligible); :class:`MotorResponse` wherever it does, by
moving in the response's own coefficients.  Both leave every other parameter as θ has
it.  :meth:`.coordinates.Coordinates.for_fit` chooses among them and θ.
"""

from __future__ import annotations

import numpy as np

from .coordinates import CoordinateMap

__all__ = ["MotorConstants", "MotorResponse", "motor_maps"]


def _indices(registry, names) -> list[int] | None:
    """The indices of ``names`` in ``registry``, or None unless each is there in log."""
    known = list(registry.names)
    if not all(n in known and registry.specs[known.index(n)].transform == "log"
               for n in names):
        return None
    return [known.index(n) for n in names]


class MotorConstants(CoordinateMap):
    """θ with ``log K``, ``log B`` and ``log J`` replaced by the logarithms of the motor's
    steady gain ``G = K/S`` and mechanical time constant ``τ = J·Ra/S``, ``S = Ra·B + K²``
    (equations (8)–(9)), what a step of the speed fixes, and ``u = log(Ra·B/K²)``, how
    the friction and the back-emf share S, which the data may leave to the priors.  Back
    from φ: ``K = 1/(G·(1 + eᵘ))``, ``B = eᵘ·K²/Ra``, ``J = τ·S/Ra``: every φ is a
    motor, and ``|dφ/dθ| = 1``."""

    kind = "motor constants"
    NAMES = ("Ra", "K", "B", "J")

    def __init__(self, registry):
        self.ra, self.k, self.b, self.j = _indices(registry, self.NAMES)

    @classmethod
    def fits(cls, registry) -> bool:
        """Whether ``registry`` has Ra, K, B and J, each in log."""
        return _indices(registry, cls.NAMES) is not None

    def from_theta(self, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        ra, k, b, j = (theta[..., i] for i in (self.ra, self.k, self.b, self.j))
        log_s = np.logaddexp(ra + b, 2 * k)
        phi = theta.copy()
        phi[..., self.k] = k - log_s
        phi[..., self.b] = ra + b - 2 * k
        phi[..., self.j] = j + ra - log_s
        return phi

    def to_theta(self, phi) -> np.ndarray:
        phi = np.asarray(phi, dtype=float)
        ra, g, u, tau = (phi[..., i] for i in (self.ra, self.k, self.b, self.j))
        k = -g - np.logaddexp(0.0, u)
        theta = phi.copy()
        theta[..., self.k] = k
        theta[..., self.b] = u + 2 * k - ra
        theta[..., self.j] = tau + k - g - ra
        return theta

    def log_jacobian(self, theta) -> np.ndarray:
        return np.zeros(np.shape(theta)[:-1])


class MotorResponse(CoordinateMap):
    """θ with ``log La``, ``log K``, ``log B`` and ``log J`` replaced by the logarithms of
    the response's coefficients ``G = K/S``, ``a₁ = (Ra·J + La·B)/S``, ``a₂ = La·J/S``
    and of ``c = La·B/S``, the friction's share of ``a₁`` (``S = Ra·B + K²``); Ra stays.
    With Coulomb friction ``log Tc`` is replaced too, by the log of the steady speed it
    costs, ``d = Ra·Tc/S`` (``ω = G·V − d``).  What the data leave free is then Ra and
    c, each bounded by its prior (Ra's bench value, B's), and the ridge is straight.
    Back from φ: ``La = Ra·a₂/(a₁ − c)``, ``S = (1 − Ra·c/La)/G²``, ``K = G·S``,
    ``B = c·S/La``, ``J = a₂·S/La``, ``Tc = d·S/Ra``; a φ with ``c ≥ a₁`` or ``S ≤ 0``
    is no motor (NaN)."""

    kind = "motor response"
    NAMES = ("Ra", "La", "K", "B", "J")

    def __init__(self, registry):
        self.ra, self.la, self.k, self.b, self.j = _indices(registry, self.NAMES)
        tc = _indices(registry, ("Tc",))
        self.tc = None if tc is None else tc[0]

    @classmethod
    def fits(cls, registry) -> bool:
        """Whether ``registry`` has Ra, La, K, B and J, each in log."""
        return _indices(registry, cls.NAMES) is not None

    def _logs(self, theta):
        """``(log S, log(Ra·J + La·B))`` and the five logs, of θ ``(..., P)``."""
        ra, la, k, b, j = (theta[..., i] for i in (self.ra, self.la, self.k, self.b, self.j))
        return np.logaddexp(ra + b, 2 * k), np.logaddexp(ra + j, la + b), (ra, la, k, b, j)

    def from_theta(self, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=float)
        log_s, log_a1s, (_, la, k, b, j) = self._logs(theta)
        phi = theta.copy()
        phi[..., self.la] = k - log_s
        phi[..., self.k] = log_a1s - log_s
        phi[..., self.b] = la + j - log_s
        phi[..., self.j] = la + b - log_s
        if self.tc is not None:
            phi[..., self.tc] = theta[..., self.ra] + theta[..., self.tc] - log_s
        return phi

    def to_theta(self, phi) -> np.ndarray:
        phi = np.asarray(phi, dtype=float)
        ra = np.exp(phi[..., self.ra])
        g, a1, a2, c = (np.exp(phi[..., i]) for i in (self.la, self.k, self.b, self.j))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            la = ra * a2 / (a1 - c)
            s = (1.0 - ra * c / la) / g**2
            motor = (a1 > c) & (s > 0.0) & np.isfinite(la) & np.isfinite(s)
            la, s = np.where(motor, la, 1.0), np.where(motor, s, 1.0)
            theta = phi.copy()
            for i, value in ((self.la, la), (self.k, g * s), (self.b, c * s / la),
                             (self.j, a2 * s / la)):
                theta[..., i] = np.where(motor, np.log(value), np.nan)
            if self.tc is not None:
                theta[..., self.tc] = phi[..., self.tc] + np.log(s) - phi[..., self.ra]
        return theta

    def log_jacobian(self, theta) -> np.ndarray:
        """``−log|dφ/dθ|``: the determinant of the derivatives of ``(log G, log a₁,
        log a₂, log c)`` in ``(log La, log K, log B, log J)`` (Ra's row is the identity,
        and log d's column has a 1 in its own row only: neither changes the
        determinant)."""
        theta = np.asarray(theta, dtype=float)
        log_s, log_a1s, (ra, la, k, b, j) = self._logs(theta)
        q = np.exp(ra + b - log_s)  # Ra·B/S: ∂log S/∂log B; 2(1 − q) = ∂log S/∂log K
        m = np.exp(la + b - log_a1s)  # La·B/(Ra·J + La·B)
        zero, one, dk = np.zeros_like(q), np.ones_like(q), -2.0 * (1.0 - q)
        rows = [(zero, 1.0 + dk, -q, zero),        # log G = log K − log S
                (m, dk, m - q, 1.0 - m),           # log a₁
                (one, dk, -q, one),                # log a₂ = log La + log J − log S
                (one, dk, 1.0 - q, zero)]          # log c = log La + log B − log S
        det = np.linalg.det(np.stack([np.stack(r, axis=-1) for r in rows], axis=-2))
        return -np.log(np.abs(det))


def motor_maps(registry) -> list[CoordinateMap]:
    """The motor's coordinate systems that ``registry`` has the parameters for."""
    return [cls(registry) for cls in (MotorConstants, MotorResponse) if cls.fits(registry)]
