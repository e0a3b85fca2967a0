"""Joint MAP fit of a session (optimistix Levenberg–Marquardt), with Laplace uncertainty.

The MAP maximises :meth:`SessionModel.log_posterior`.  With each channel's noise
integrated out, its stationary point is a weighted least-squares problem whose
weights ``(n_c + ν0)/(ν0·s0_c² + SS_c)`` depend on the residuals themselves, so the
fit alternates Levenberg–Marquardt at fixed weights with a weight update until both
settle (iteratively reweighted least squares; the fixed point is the exact MAP).
Several perturbed seeds are solved at once (``vmap``), so a poor seed cannot leave
the fit in a local minimum unnoticed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..physics.solution import real_modes
from .objective import NU0, SessionModel
from .._x64 import x64

__all__ = ["FitResult", "fit_map", "laplace"]

N_STARTS = 8
START_SPREAD = 0.3
REWEIGHT_ITERATIONS = 40


@dataclass(frozen=True)
class FitResult:
    """The MAP and its Laplace approximation.

    Attributes
    ----------
    theta : MAP in log space.
    values, sd : MAP and Laplace standard deviation per parameter (SI).
    cov_log : Laplace covariance in log space; ``corr`` its correlation matrix.
    status : ``"converged"`` or ``"failed"``; ``message`` says why in words.
    starts : per start, its final log-posterior and whether it agreed with the best.
    weights : per-channel 1/σ² at the MAP; ``noise_sd`` the matching σ.
    """

    names: tuple
    theta: np.ndarray
    values: dict
    sd: dict
    cov_log: np.ndarray
    corr: np.ndarray
    log_posterior: float
    status: str
    message: str
    starts: list = field(default_factory=list)
    weights: np.ndarray | None = None
    noise_sd: dict = field(default_factory=dict)
    iterations: int = 0

    @property
    def ok(self) -> bool:
        return self.status == "converged"


def _solver():
    return optx.LevenbergMarquardt(rtol=1e-8, atol=1e-8)


def _make_solve(model: SessionModel, *, fast: bool):
    """Batched Levenberg–Marquardt at fixed weights, plus the weight update: compiled
    once per session structure (data travel as an argument)."""

    def build():
        def residuals(theta, args):
            weights, data = args
            return model.weighted_residuals(theta, weights, fast=fast, data=data)

        def solve_one(theta0, weights, data):
            sol = optx.least_squares(residuals, _solver(), theta0, args=(weights, data),
                                     max_steps=400, throw=False)
            ok = sol.result == optx.RESULTS.successful
            return sol.value, ok, sol.stats["num_steps"]

        def step(thetas, weights, data):
            values, ok, steps = jax.vmap(solve_one, in_axes=(0, 0, None))(thetas, weights, data)
            new_w = jax.vmap(lambda t: model.weights(t, data=data))(values)
            logp = jax.vmap(lambda t: model.log_posterior(t, data=data))(values)
            return values, ok, steps, new_w, logp

        return jax.jit(step)

    jitted = model.compiled(f"lm-fast={fast}", build)
    return lambda thetas, weights: jitted(thetas, weights, model.data)


def _starts(model: SessionModel, theta0, n: int, rng: np.random.Generator):
    theta0 = np.asarray(theta0, dtype=float)
    spread = np.minimum(model.prior_sd, START_SPREAD)
    pert = rng.standard_normal((n - 1, theta0.size)) * spread
    return np.concatenate([theta0[None, :], theta0[None, :] + pert])


def _real_modes(theta) -> bool:
    """NumPy twin of :func:`pmdc_bayes.physics.solution.real_modes` for a log-space θ."""
    Ra, La, K, B, J = np.exp(np.asarray(theta, dtype=float)[:5])
    a11, a22 = -Ra / La, -B / J
    m = 0.5 * (a11 + a22)
    z = (0.5 * (a11 - a22)) ** 2 - K * K / (La * J)
    return bool(z > (1e-3 * m) ** 2)


def _initial_weights(model: SessionModel, n: int) -> np.ndarray:
    """1/s0² per channel: the model-free noise estimates, before any residual exists."""
    return np.tile(1.0 / np.asarray(model.s0) ** 2, (n, 1))


@x64
def laplace(model: SessionModel, theta, weights):
    """Covariance in log space from the Gauss–Newton Hessian at ``theta``.

    Notes
    -----
    A channel contributes ``(n_c + ν0)/2 · log(A_c)`` with ``A_c = ν0·s0_c² + SS_c`` to the
    negative log-posterior (its noise integrated out).  With the Gauss–Newton
    approximation ``∇²SS_c ≈ 2·J_cᵀJ_c`` its Hessian is
    ``w_c·J_cᵀJ_c − w_c²/(2(n_c + ν0)) · g_c g_cᵀ``, ``w_c = (n_c + ν0)/A_c``,
    ``g_c = ∇SS_c``: the second term is the curvature given up by not knowing the
    noise level, which matters for channels with few observations.
    """
    jac_fn = model.compiled("jacobian", lambda: jax.jit(jax.jacfwd(
        lambda t, w, d: model.weighted_residuals(t, w, data=d))))
    grad_ss = model.compiled("ss_jacobian", lambda: jax.jit(jax.jacfwd(
        lambda t, d: model.sums_of_squares(t, data=d))))
    jac = np.asarray(jac_fn(theta, weights, model.data))
    g = np.asarray(grad_ss(theta, model.data))  # (channels, P)
    w = np.asarray(weights)
    n = np.asarray(model.n_obs)
    coef = np.where(n > 0, w * w / (2.0 * (n + NU0)), 0.0)
    H = jac.T @ jac - (g.T * coef) @ g
    vals, vecs = np.linalg.eigh(0.5 * (H + H.T))
    vals = np.clip(vals, 1e-12 * max(vals.max(), 1e-300), None)
    cov = (vecs / vals) @ vecs.T
    return cov, H


@x64
def fit_map(model: SessionModel, *, theta0=None, n_starts: int = N_STARTS, seed: int = 0,
            solve=None) -> FitResult:
    """Maximise the log-posterior from the closed-form seed and perturbed copies of it.

    Parameters
    ----------
    model : the session objective.
    theta0 : starting point in log space (default: the closed-form seed).
    n_starts : number of starts solved together (the first is ``theta0`` itself).
    seed : seed of the perturbations.
    solve : a compiled step from a previous call with the same session shapes.
    """
    theta0 = np.asarray(model.theta_seed() if theta0 is None else theta0, dtype=float)
    rng = np.random.default_rng(seed)
    starts = _starts(model, theta0, n_starts, rng)
    fast = _real_modes(theta0)
    result = _solve_starts(model, starts, fast=fast, solve=solve)
    if fast and not _real_modes(result[0]):
        # The optimum left the region where the fast propagator is valid: redo it with
        # the general one.
        result = _solve_starts(model, starts, fast=False, solve=None)
    return _finish(model, *result)


def _solve_starts(model: SessionModel, starts, *, fast: bool, solve=None):
    solve = _make_solve(model, fast=fast) if solve is None else solve
    # Device arrays from the start, like the outputs fed back in later rounds, so the
    # compiled step is traced once.
    thetas = jnp.asarray(starts)
    weights = jnp.asarray(_initial_weights(model, starts.shape[0]))
    logp_prev = None
    settled = False
    for it in range(1, REWEIGHT_ITERATIONS + 1):
        thetas, ok, steps, weights, logp = solve(thetas, weights)
        logp = np.asarray(logp)
        if logp_prev is not None and np.all(np.abs(logp - logp_prev) <= 1e-9 * np.abs(logp) + 1e-9):
            settled = True
            break
        logp_prev = logp
    ok = np.asarray(ok)
    logp = np.where(np.isfinite(logp), logp, -np.inf)
    best = int(np.argmax(logp))
    return np.asarray(thetas[best]), np.asarray(thetas), logp, ok, np.asarray(weights), \
        settled, it


def _finish(model, theta, thetas, logp, ok, weights, settled, it) -> FitResult:
    best = int(np.argmax(logp))
    agree = np.all(np.abs(np.asarray(thetas) - theta) < 1e-4, axis=1) & (
        np.abs(logp - logp[best]) < 1e-6 * max(1.0, abs(logp[best])))
    starts = [{"start": i, "log_posterior": float(logp[i]), "agrees": bool(agree[i]),
               "solver_ok": bool(ok[i])} for i in range(len(logp))]
    w = np.asarray(weights[best])
    cov, _ = laplace(model, jnp.asarray(theta), jnp.asarray(w))
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(sd_log, sd_log)
    vals = np.exp(theta)
    values = dict(zip(model.names, map(float, vals)))
    sd = dict(zip(model.names, map(float, vals * sd_log)))
    noise = {c.name: float(1.0 / np.sqrt(w[k])) for k, c in enumerate(model.channels) if c.n > 0}
    reasons = []
    if not np.isfinite(logp[best]):
        reasons.append("no start reached a finite log-posterior (the model cannot "
                       "reproduce the data with positive parameters)")
    if not ok[best]:
        reasons.append("Levenberg–Marquardt stopped before its tolerance (step limit) at "
                       "the best start")
    if not settled:
        reasons.append(f"the noise weights did not settle in {REWEIGHT_ITERATIONS} "
                       "reweighting rounds")
    if not np.all(np.isfinite(sd_log)):
        reasons.append("the curvature at the optimum is singular")
    status = "failed" if reasons else "converged"
    n_agree = int(agree.sum())
    message = "; ".join(reasons) if reasons else (
        f"converged in {it} reweighting rounds; {n_agree} of {len(logp)} starts agree")
    return FitResult(tuple(model.names), theta, values, sd, cov, corr, float(logp[best]),
                     status, message, starts, w, noise, it)
