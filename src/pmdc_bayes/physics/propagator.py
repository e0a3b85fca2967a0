"""The motor's 2×2 propagator ``expm(A·τ)`` in closed form, for the exact solution.

By Cayley–Hamilton, ``expm(A·τ) = α(τ)·I + β(τ)·A`` for the motor matrix A of
equations (11)–(14); α and β follow from A's two eigenvalues (real, complex or nearly
repeated), computed here without cancellation so that the stiff motor (La/Ra ≪ J/B)
keeps its digits.  Parameters are any record with fields Ra, La, K, B, J
(:class:`~pmdc_bayes.physics.solution.Params`).
"""

from __future__ import annotations

import jax.numpy as jnp

from . import motor

__all__ = ["real_modes", "coefficients", "coefficients_real", "apply_alpha_beta", "eigen"]


def eigen(p):
    """Mean m, discriminant z, determinant of A: eigenvalues m ± sqrt(z)."""
    a11, a22 = -p.Ra / p.La, -p.B / p.J
    m = 0.5 * (a11 + a22)
    det = (p.Ra * p.B + p.K * p.K) / (p.La * p.J)
    z = (0.5 * (a11 - a22)) ** 2 - p.K * p.K / (p.La * p.J)
    return m, z, det


def real_modes(p):
    """True where A's eigenvalues are real and far enough apart for :func:`coefficients_real`."""
    m, z, _ = eigen(p)
    return z > (1e-3 * m) ** 2


def coefficients_real(p, tau):
    """(α, β) with ``expm(A·τ) = α·I + β·A``, for real, well-separated eigenvalues.

    The fast eigenvalue is formed without cancellation and the slow one from the
    product of the two (det), so neither loses digits.
    """
    m, z, det = eigen(p)
    s = jnp.sqrt(jnp.where(z > 0, z, 1.0))
    lf = m - s
    ls = det / lf
    e_s, e_f = jnp.exp(ls * tau), jnp.exp(lf * tau)
    gap = ls - lf
    return (ls * e_f - lf * e_s) / gap, (e_s - e_f) / gap


def coefficients(p, tau):
    """(α, β) with ``expm(A·τ) = α·I + β·A`` for any eigenvalues of the 2×2 motor matrix."""
    m, z, det = eigen(p)
    zt2 = z * tau * tau
    small = jnp.abs(zt2) < 1e-4
    alpha_r, beta_r = coefficients_real(p, tau)
    # Complex pair m ± iw.
    w = jnp.sqrt(jnp.where(z < 0, -z, 1.0))
    em = jnp.exp(m * tau)
    sinc = jnp.sin(w * tau) / w
    beta_c = em * sinc
    alpha_c = em * (jnp.cos(w * tau) - m * sinc)
    # Nearly repeated eigenvalues: series in z·τ².
    beta_0 = tau * em * (1.0 + zt2 / 6.0 + zt2 * zt2 / 120.0)
    alpha_0 = em * (1.0 + zt2 / 2.0 + zt2 * zt2 / 24.0) - m * beta_0
    alpha = jnp.where(small, alpha_0, jnp.where(z > 0, alpha_r, alpha_c))
    beta = jnp.where(small, beta_0, jnp.where(z > 0, beta_r, beta_c))
    return alpha, beta


def apply_alpha_beta(p, alpha, beta, d):
    """``(α·I + β·A)·d`` for d = (d_ia, d_ω) (arrays broadcast)."""
    di, dw = d
    ai, aw = motor.derivatives(p.Ra, p.La, p.K, p.B, p.J, di, dw)
    return alpha * di + beta * ai, alpha * dw + beta * aw
