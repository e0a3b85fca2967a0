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

from .._x64 import x64
from ..physics.solution import Params, real_modes
from .objective import NU0, SessionModel

__all__ = ["FitResult", "fit_map", "laplace"]

N_STARTS = 8
START_SPREAD = 0.3
REWEIGHT_ITERATIONS = 40
ROUND_STEPS = 64  # LM steps per reweighting round: a start still moving goes on next round
RELEVANT = 10.0
SAME_OPTIMUM = 0.05  # log-posterior units: nearby finals closer than this are one optimum
WIDE_SPREAD = 1.0  # least log spread of the starts over the prior's range


@dataclass(frozen=True)
class FitResult:
    """The MAP and its Laplace approximation.

    Attributes
    ----------
    theta : MAP in log space.
    values, sd : MAP and Laplace standard deviation per parameter (SI).
    cov_log : Laplace covariance in log space; ``corr`` its correlation matrix.
    status : ``"converged"`` or ``"failed"``; ``message`` says why in words.
    starts : per start, where it began, its final log-posterior and whether it agreed
        with the best.
    n_modes : how many distinct optima the starts reached (the best is the MAP);
        ``mode_gaps`` how far below the MAP's log-posterior each of the others is.
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
    n_modes: int = 1
    mode_gaps: tuple = ()

    @property
    def ok(self) -> bool:
        return self.status == "converged"


def _solver():
    return optx.LevenbergMarquardt(rtol=1e-8, atol=1e-8)


def _make_solve(model: SessionModel, *, fast: bool):
    """Batched Levenberg–Marquardt at fixed weights, plus the weight update: compiled
    once per session structure (data travel as an argument).

    The starts are solved together, so a call lasts as long as its slowest start: each
    call stops at :data:`ROUND_STEPS` steps, and a start still moving goes on from
    where it stopped in the next reweighting round (the rounds end once the starts near
    the best have settled; a start far below them that never converged is not counted
    as an optimum)."""

    def build():
        def residuals(theta, args):
            weights, data = args
            return model.weighted_residuals(theta, weights, fast=fast, data=data)

        def solve_one(theta0, weights, data):
            sol = optx.least_squares(residuals, _solver(), theta0, args=(weights, data),
                                     max_steps=ROUND_STEPS, throw=False)
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


def _starts(model: SessionModel, theta0, n: int, rng: np.random.Generator, alternatives=()):
    """``(starts, origins)``: ``theta0``; the ``alternatives`` (other seeds); then half of
    the rest within ``START_SPREAD`` (log) of ``theta0`` and half drawn over the prior's
    plausible range (its centre ± one prior width, at least ``WIDE_SPREAD`` in log, clipped
    at two), so that a better
    optimum away from the seed is found rather than assumed away."""
    theta0 = np.asarray(theta0, dtype=float)
    rows, origins = [theta0], ["seed"]
    for alt in alternatives:
        if len(rows) < n:
            rows.append(np.asarray(alt, dtype=float))
            origins.append("alternative seed")
    rest = n - len(rows)
    n_near = rest - rest // 2
    width = np.asarray(model.prior_sd, dtype=float)
    is_log = model.registry.is_log()  # untransformed parameters spread by their prior sd
    near_sd = np.where(is_log, np.minimum(width, START_SPREAD), START_SPREAD * width)
    wide_sd = np.where(is_log, np.maximum(width, WIDE_SPREAD), width)
    near = theta0 + rng.standard_normal((n_near, theta0.size)) * near_sd
    centre = np.asarray(model.registry.seed_theta(), dtype=float)
    wide = centre + np.clip(rng.standard_normal((rest - n_near, theta0.size)), -2.0, 2.0) \
        * wide_sd
    rows += list(near) + list(wide)
    origins += ["near the seed"] * n_near + ["over the prior's range"] * (rest - n_near)
    return np.asarray(rows), origins


def _real_modes(model: SessionModel, theta) -> bool:
    """:func:`pmdc_bayes.physics.solution.real_modes` at θ, evaluated in NumPy."""
    if model.session.unknown_load_traces():  # a trace's drag moves its modes
        return False
    v = dict(zip(model.names, model.registry.to_values(theta)))
    return bool(real_modes(Params(v["Ra"], v["La"], v["K"], v["B"], v["J"])))


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
            solve=None, alternatives=()) -> FitResult:
    """Maximise the log-posterior from the closed-form seed and perturbed copies of it.

    Parameters
    ----------
    model : the session objective.
    theta0 : starting point in log space (default: the closed-form seed).
    n_starts : number of starts solved together (the first is ``theta0`` itself).
    seed : seed of the perturbations.
    solve : a compiled step from a previous call with the same session shapes.
    alternatives : other starting points in θ space (e.g. a seed from the data when
        ``theta0`` is the closed form's), solved together with the rest.
    """
    theta0 = np.asarray(model.theta_seed() if theta0 is None else theta0, dtype=float)
    rng = np.random.default_rng(seed)
    starts, origins = _starts(model, theta0, n_starts, rng, alternatives)
    fast = _real_modes(model, theta0)
    result = _solve_starts(model, starts, fast=fast, solve=solve)
    if fast and not _real_modes(model, result[0]):
        # The optimum left the region where the fast propagator is valid: redo it with
        # the general one.
        result = _solve_starts(model, starts, fast=False, solve=None)
    return _finish(model, *result, origins=origins)


def _settled(logp, prev) -> bool:
    """Whether the reweighting has settled for every start that matters: those within
    ``RELEVANT`` log-posterior units of the best (a start stuck far below it is a poor
    local optimum whose weights need not settle for the MAP to be exact)."""
    logp, prev = np.asarray(logp), np.asarray(prev)
    finite = np.isfinite(logp)
    if not finite.any():
        return False
    top = float(np.max(logp[finite]))
    near = finite & (logp >= top - max(RELEVANT, 1e-3 * abs(top)))
    return bool(np.all(np.abs(logp[near] - prev[near]) <= 1e-9 * np.abs(logp[near]) + 1e-9))


def _far_below(logp, round_: int) -> np.ndarray:
    """Starts that, from the second round on, lie far below the best (more than
    :data:`RELEVANT` log-posterior units and 1 % of its size) or at a non-finite
    value: a poor local optimum or a slow crawl, no longer worth holding the batch."""
    finite = np.isfinite(logp)
    if round_ < 2 or not finite.any():
        return np.zeros(logp.shape, dtype=bool)
    top = float(np.max(logp[finite]))
    return ~finite | (logp < top - max(RELEVANT, 1e-2 * abs(top)))


def _solve_starts(model: SessionModel, starts, *, fast: bool, solve=None):
    solve = _make_solve(model, fast=fast) if solve is None else solve
    # Device arrays from the start, like the outputs fed back in later rounds, so the
    # compiled step is traced once.
    thetas = jnp.asarray(starts)
    weights = jnp.asarray(_initial_weights(model, starts.shape[0]))
    logp_prev = None
    settled = False
    frozen: dict[int, tuple] = {}  # start -> (θ, ok, log-posterior, weights) where it stopped
    for it in range(1, REWEIGHT_ITERATIONS + 1):
        thetas, ok, steps, weights, logp = solve(thetas, weights)
        logp = np.array(logp)
        for i in frozen:
            logp[i] = frozen[i][2]
        if logp_prev is not None and _settled(logp, logp_prev):
            settled = True
            break
        logp_prev = logp
        # A start far below the best stops here; its slot follows the best start, whose
        # few steps then bound the round's length.
        new = [int(i) for i in np.flatnonzero(_far_below(logp, it)) if int(i) not in frozen]
        if new:
            best = int(np.nanargmax(np.where(np.isfinite(logp), logp, np.nan)))
            for i in new:
                frozen[i] = (np.asarray(thetas[i]), bool(ok[i]), float(logp[i]),
                             np.asarray(weights[i]))
            idx = jnp.asarray(new)
            thetas = thetas.at[idx].set(thetas[best])
            weights = weights.at[idx].set(weights[best])
    thetas, ok, weights = np.array(thetas), np.array(ok), np.array(weights)
    for i, (theta_i, ok_i, logp_i, w_i) in frozen.items():
        thetas[i], ok[i], logp[i], weights[i] = theta_i, ok_i, logp_i, w_i
    logp = np.where(np.isfinite(logp), logp, -np.inf)
    best = int(np.argmax(logp))
    return thetas[best], thetas, logp, ok, weights, settled, it


def _modes(thetas, logp, ok) -> list[int]:
    """Indices of the distinct optima the starts reached (best first): two finals are
    the same optimum when they lie within 1e-3 in θ (0.1 % in a log parameter) with
    log-posteriors within 1e-6 (relative), or within 0.1 in θ with log-posteriors within
    :data:`SAME_OPTIMUM` (one optimum where the solver stopped early along a flat
    direction)."""
    order = [int(i) for i in np.argsort(-logp) if np.isfinite(logp[i]) and ok[i]]
    modes: list[int] = []

    def same(i, j):
        gap, dlp = np.max(np.abs(thetas[i] - thetas[j])), abs(logp[i] - logp[j])
        return ((gap < 1e-3 and dlp < 1e-6 * max(1.0, abs(logp[j])))
                or (gap < 0.1 and dlp < SAME_OPTIMUM))

    for i in order:
        if not any(same(i, j) for j in modes):
            modes.append(i)
    return modes


def _finish(model, theta, thetas, logp, ok, weights, settled, it, origins=None) -> FitResult:
    best = int(np.argmax(logp))
    thetas = np.asarray(thetas)
    origins = origins or ["seed"] + ["near the seed"] * (len(logp) - 1)
    agree = np.all(np.abs(thetas - theta) < 1e-4, axis=1) & (
        np.abs(logp - logp[best]) < 1e-6 * max(1.0, abs(logp[best])))
    modes = _modes(thetas, logp, np.asarray(ok))
    starts = [{"start": i, "origin": origins[i], "log_posterior": float(logp[i]),
               "agrees": bool(agree[i]), "solver_ok": bool(ok[i])} for i in range(len(logp))]
    w = np.asarray(weights[best])
    cov, _ = laplace(model, jnp.asarray(theta), jnp.asarray(w))
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(sd_log, sd_log)
    vals = model.registry.to_values(theta)
    values = dict(zip(model.names, map(float, vals)))
    sd = dict(zip(model.names, map(float, model.registry.sd_values(theta, sd_log))))
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
    n_wide = sum(o == "over the prior's range" for o in origins)
    found = (f"{len(modes)} distinct optimum" if len(modes) == 1
             else f"{len(modes)} distinct optima, the best chosen")
    message = "; ".join(reasons) if reasons else (
        f"converged in {it} reweighting rounds; {n_agree} of {len(logp)} starts agree "
        f"({n_wide} started over the prior's range; {found})")
    return FitResult(tuple(model.names), theta, values, sd, cov, corr, float(logp[best]),
                     status, message, starts, w, noise, it, len(modes),
                     tuple(float(logp[best] - logp[i]) for i in modes[1:]))
