"""The model's derivatives a step of the MAP fit reads: the log-posterior, its gradient
and its Gauss–Newton curvature at one θ, from the forward-mode Jacobian of the
residuals.

With each channel's noise integrated out the log-posterior is not a sum of squares,
but its gradient and curvature are those of the channels' residuals weighted by their
current ``1/σ_c²``: :func:`gauss_newton` gives both, and the per-channel sums of squares
and their gradients that the Laplace approximation and the adequacy checks read.  The
optimiser (:mod:`.optimiser`) takes this curvature as its Hessian.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..model.channels import entry_weights
from ..model.noise import NU0, integrated_log_likelihood, noise_weights

__all__ = ["gauss_newton", "transform_curvature", "invert_curvature", "Terms"]


def gauss_newton(model, theta, *, data=None):
    """The Gauss–Newton terms of ``model``'s log-posterior at ``θ`` (pure JAX).

    Returns ``(lp, grad, H, H_noise, ss, G)``: the log-posterior, its gradient in θ,
    the Gauss–Newton matrix ``H = Σ_c w_c·J_cᵀJ_c + J_pᵀJ_p`` with ``w_c = (n_c +
    ν0)/(ν0·s0_c² + SS_c)``, the same less the curvature given up by not knowing the
    noise levels (``H_noise``, the Laplace approximation's Hessian), the sums of squares
    ``SS_c`` and ``G_c = J_cᵀr_c`` per channel (so ``∇SS_c = 2·G_c``).

    Notes
    -----
    A channel contributes ``−(n_c + ν0)/2 · log(ν0·s0_c² + SS_c)``, whose gradient is
    ``−w_c·J_cᵀr_c`` and whose Gauss–Newton Hessian is ``w_c·J_cᵀJ_c − w_c²/(2(n_c +
    ν0))·∇SS_c ∇SS_cᵀ``: the second term matters where channels pull against each
    other, and a step that ignored it would be too short (iteratively reweighted least
    squares, converging only linearly).  The prior's standardised residuals ``p`` add
    ``−J_pᵀp`` and the log-Jacobian's constant gradient.
    """
    d = model.data if data is None else data
    n_ch = len(model.channels)

    def residual_vector(t):
        parts = model._parts(t, d)
        r = jnp.concatenate([jnp.where(m, r, 0.0).reshape(-1) for r, m, _ in parts])
        return r, r

    jac, r = jax.jacfwd(residual_vector, has_aux=True)(theta)
    cid = jnp.concatenate([
        jnp.broadcast_to(entry_weights(jnp.arange(n_ch), ch, m), jnp.shape(m)).reshape(-1)
        for b in model.blocks for m, ch in b.layout(d[b.key])])
    ss = jax.ops.segment_sum(r * r, cid, num_segments=n_ch)
    G = jax.ops.segment_sum(jac * r[:, None], cid, num_segments=n_ch)
    n, s0 = d["n_obs"], d["s0"]
    w = noise_weights(ss, n, s0)
    sw = jnp.sqrt(w)[cid]
    jw = jac * sw[:, None]

    def prior_residuals(t):
        return model.prior_residuals(t, data=d)

    jp = jax.jacfwd(prior_residuals)(theta)
    log_prior = model.log_prior(theta, data=d)
    grad_prior = jax.grad(lambda t: model.log_prior(t, data=d))(theta)
    lp = log_prior + jnp.sum(integrated_log_likelihood(ss, n, s0))
    grad = grad_prior - w @ G
    H = jw.T @ jw + jp.T @ jp
    # the curvature given up by not knowing each channel's noise level (see fit.laplace)
    coef = jnp.where(n > 0, w * w / (2.0 * (n + NU0)), 0.0)
    g = 2.0 * G
    H_noise = H - (g.T * coef) @ g
    return lp, grad, H, H_noise, ss, G


def invert_curvature(H) -> np.ndarray:
    """The covariance of a curvature matrix ``H`` (its inverse), computed in the scale of
    its diagonal: parameters held to very different precisions (a dead time in seconds,
    a drop near zero in log) have curvatures twenty decades apart, so the matrix is
    rescaled to unit diagonal, where its eigenvalues reach about n·ε of the largest, and
    only eigenvalues below that (rounding, not curvature) are floored there; a direction
    along which the curvature is zero comes out very wide, not singular."""
    H = np.asarray(H, dtype=float)
    diag = np.diag(H)
    d = np.sqrt(np.where(diag > 0, diag, 1.0))
    vals, vecs = np.linalg.eigh(0.5 * (H + H.T) / np.outer(d, d))
    floor = len(vals) * np.finfo(float).eps
    vals = np.clip(vals, floor * max(vals.max(), 1e-300), None)
    return (vecs / vals) @ vecs.T / np.outer(d, d)


def transform_curvature(model) -> np.ndarray:
    """Per parameter, the curvature of the negative log-posterior at its MAP that the
    Gauss–Newton matrix leaves out through the log transform of a parameter whose
    prior is Gaussian in value (NumPy, added on the diagonal): 1 for each such
    parameter switched on, 0 for every other.

    For ``θ = log v`` a residual's second derivative holds ``v·∂r/∂v = ∂r/∂θ`` besides
    ``v²·∂²r/∂v²``, so the exact Hessian adds ``Σ r·∂r/∂θ``: the parameter's gradient of
    the terms that read it in value (the channels and its prior).  At the MAP that
    gradient balances the log-Jacobian's, so it is 1: beside the data's curvature of a
    well-measured Ra nothing, but the whole curvature of a half-normal quantity the data
    hold near zero (a voltage drop they do not see).  It is taken at that value, not
    evaluated: a fit stops a hair from the stationary point, and along a direction the
    data hold to 1e-7 in log (curvature 1e15) that hair is a gradient of 1e6.  Under a
    log-normal prior (Gaussian in θ) the term is the prior's pull at the MAP, which
    matters only for a parameter pressed far below its prior, where the posterior is
    one-sided and the bound checks judge it; it is left out there."""
    in_value = np.array([s.prior.in_value and s.transform == "log"
                         for s in model.registry.specs])
    return np.where(in_value & ~np.asarray(model.data["off"]), 1.0, 0.0)


@dataclass(frozen=True)
class Terms:
    """The Gauss–Newton terms at one θ (NumPy): see :func:`gauss_newton`."""

    theta: np.ndarray
    lp: float
    grad: np.ndarray
    H: np.ndarray
    H_noise: np.ndarray
    ss: np.ndarray
    G: np.ndarray

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.lp) and np.all(np.isfinite(self.grad))
                    and np.all(np.isfinite(self.H)))
