"""Levenberg–Marquardt on the exact log-posterior: one compiled Gauss–Newton kernel,
driven from the host.

The kernel (:func:`gauss_newton`) returns, at one θ, everything a step needs: the
log-posterior itself (each channel's noise integrated out), its gradient, the
Gauss–Newton matrix with each channel weighted by its current ``1/σ_c²``, and the
per-channel sums of squares and their gradients (which the Laplace approximation of
:mod:`.fit` also reads).  It is the only compiled program of a fit, built once per
session structure from the forward-mode Jacobian of the residuals, so a session of
a new shape compiles in seconds: a solver loop traced whole (optimistix's
Levenberg–Marquardt, the starts ``vmap``-ped through its ``while_loop``) took 20 s to
compile on the demo and over 3 minutes on the current-limited bench, against 6 s and
15 s for this kernel.

:func:`levenberg_marquardt` moves several starts on the host, a round at a time, the
starts of a round side by side in threads (one per core), each by its own damped
steps (Marquardt's scaling, Nielsen's update of the damping), each step accepted only
when the exact log-posterior rises.  Each start ends with a typed :class:`Outcome`
(as optimistix's ``RESULTS``): converged, stalled, abandoned, not finite, or at its
step limit; the best start, the MAP's candidate, is given a larger limit while it
still improves, and one that ends at it says so rather than passing for an optimum.
A round's starts depend only on their own state and the round before, never on which
thread finishes first.  With the weights re-evaluated at every point, a
Gauss–Newton step of the weighted residuals is a step of the integrated likelihood
itself, so the fixed point is the exact MAP.
"""

from __future__ import annotations

import enum
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from .._cores import usable_cores
from .._x64 import x64
from .channels import entry_weights
from .objective import NU0, integrated_log_likelihood, noise_weights

__all__ = ["gauss_newton", "GaussNewton", "Terms", "levenberg_marquardt", "Start", "Outcome"]

MAX_STEPS = 200        # steps a start may take ...
BEST_MAX_STEPS = 2000  # ... and the best start, while it still improves
DECREMENT_TOL = 1e-8   # converged: ½·gᵀH⁻¹g below this (log-posterior units)
STALL_TOL = 1e-4       # ... or no step can improve while ½·gᵀH⁻¹g is below this
DAMPING_MAX = 1e14     # the damping beyond which no step can improve any more
RESOLUTION = 0.05      # per parameter: a gap in log-posterior too small to matter
WINDOW = 20            # accepted steps over which a crawl's progress is measured


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
        return model.registry.prior_residuals(t, d["prior_centre"], d["prior_scale"])

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


class GaussNewton:
    """The compiled kernel of a model: ``terms(θ)`` evaluates :func:`gauss_newton`,
    compiled on first use, once per session structure.

    The kernel takes the general propagator (complex and nearly repeated modes too)
    rather than choosing between it and the real-mode one per point: the fast one is
    about three times quicker to run but a second program to compile, and the starts
    spread over the prior's range reach complex modes, so a fit would compile both;
    the fit's few hundred evaluations cost less than that compilation."""

    def __init__(self, model):
        self.model = model
        self._fn = model.compiled("gauss-newton", lambda: jax.jit(
            lambda t, d: gauss_newton(model, t, data=d)))

    @x64
    def terms(self, theta) -> Terms:
        """The kernel's log-posterior, gradient, curvatures, sums of squares and weighted
        Jacobian at ``theta`` (in 64 bits, whoever calls it)."""
        theta = np.asarray(theta, dtype=float)
        out = self._fn(jnp.asarray(theta), self.model.data)
        lp, grad, H, H_noise, ss, G = (np.asarray(x) for x in out)
        lp = float(lp) if np.isfinite(lp) else -np.inf
        return Terms(theta, lp, grad, H, H_noise, ss, G)


class Outcome(enum.Enum):
    """How a start ended, in words."""

    RUNNING = ""
    CONVERGED = "converged"
    RESOLVED = "converged to within the posterior's resolution (a slow, curved ridge)"
    STALLED = "no step improves the log-posterior"
    MAX_STEPS = "step limit"
    ABANDONED = "far below the best"
    NONFINITE = "the model is not finite at the start"

    @property
    def converged(self) -> bool:
        return self in (Outcome.CONVERGED, Outcome.RESOLVED)


@dataclass
class Start:
    """One start's progress: where it is, its terms there, its damping, its steps (every
    evaluation counts), its step ``limit`` and how it ended (``outcome``);
    ``accepted_at`` the step of its last accepted step, ``history`` the log-posterior
    after each."""

    terms: Terms
    damping: float = 1e-3
    nu: float = 2.0
    steps: int = 0
    limit: int = MAX_STEPS
    outcome: Outcome = Outcome.RUNNING
    accepted_at: int = 0
    history: list = field(default_factory=list)

    theta = property(lambda self: self.terms.theta)
    lp = property(lambda self: self.terms.lp)
    done = property(lambda self: self.outcome is not Outcome.RUNNING)
    converged = property(lambda self: self.outcome.converged)
    stopped = property(lambda self: self.outcome.value, doc="how it ended, in words")
    improving = property(lambda self: bool(self.history) and self.steps - self.accepted_at
                         < WINDOW, doc="whether it accepted a step in its last WINDOW steps")


def _hessian(t: Terms) -> np.ndarray:
    """The quadratic model's Hessian: ``H_noise`` where it is positive definite (Newton's
    rate of convergence), else the Gauss–Newton ``H``."""
    try:
        np.linalg.cholesky(t.H_noise)
        return t.H_noise
    except np.linalg.LinAlgError:
        return t.H


def _decrement(t: Terms) -> float:
    """½·gᵀH⁻¹g: how much a full Newton step would still gain."""
    H = _hessian(t)
    try:
        x = np.linalg.solve(H, t.grad)
    except np.linalg.LinAlgError:
        x = np.linalg.lstsq(H, t.grad, rcond=None)[0]
    return 0.5 * float(t.grad @ x)


def _resolved(s: Start, decrement: float) -> bool:
    """Whether ``s`` crawls along a curved ridge close enough to its top to stop: the
    last :data:`WINDOW` accepted steps gained, and a full Newton step would still gain,
    less than :data:`RESOLUTION` log-posterior units per parameter.  The posterior's
    typical draws lie about P/2 units below its mode, so such a gap does not move the
    Laplace approximation or the sampler's start in any way that matters."""
    tol = RESOLUTION * s.terms.theta.size
    h = s.history
    return len(h) > WINDOW and h[-1] - h[-1 - WINDOW] < tol and decrement < tol


def _step(s: Start, evaluate) -> None:
    """One accepted step of ``s``, raising its damping until a step is accepted, or the
    end of ``s`` (converged, stalled or out of steps).  Every evaluation counts as a
    step."""
    t = s.terms
    decrement = _decrement(t)
    if decrement < DECREMENT_TOL:
        s.outcome = Outcome.CONVERGED
        return
    if _resolved(s, decrement):
        s.outcome = Outcome.RESOLVED
        return
    H = _hessian(t)
    diag = np.diag(t.H)
    scale = np.maximum(diag, 1e-12 * max(float(np.max(diag)), 1e-300))
    while True:
        if s.steps >= s.limit:
            s.outcome = Outcome.MAX_STEPS
            return
        s.steps += 1
        A = H + s.damping * np.diag(scale)
        try:
            delta = np.linalg.solve(A, t.grad)
        except np.linalg.LinAlgError:
            delta = np.linalg.lstsq(A, t.grad, rcond=None)[0]
        predicted = float(delta @ t.grad - 0.5 * delta @ H @ delta)
        trial = evaluate(t.theta + delta) if np.all(np.isfinite(delta)) else None
        gain = (trial.lp - t.lp) if trial is not None and trial.finite else -np.inf
        if np.isfinite(gain) and gain > 0.0 and predicted > 0.0:
            rho = gain / predicted
            s.terms = trial
            s.history.append(trial.lp)
            s.accepted_at = s.steps
            s.damping *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            s.nu = 2.0
            return
        s.damping *= s.nu
        s.nu *= 2.0
        if s.damping > DAMPING_MAX:
            s.outcome = Outcome.CONVERGED if _decrement(t) < STALL_TOL else Outcome.STALLED
            return


def levenberg_marquardt(evaluate, starts, *, abandon=None, max_steps: int = MAX_STEPS,
                        best_max_steps: int = BEST_MAX_STEPS) -> list[Start]:
    """Levenberg–Marquardt from each of ``starts`` (θ rows), a step of each per round.

    ``evaluate(θ)`` returns the :class:`Terms` at θ.  ``abandon(start, best_lp)``,
    checked after each round of steps, stops a start that is not worth finishing (a
    poor local optimum far below the best); it is then not ``converged``.  A start
    ends at ``max_steps`` steps, except the best one (the MAP's candidate) while it
    still improves (:attr:`Start.improving`): its limit doubles, up to
    ``best_max_steps``; one that ends at its limit has the outcome
    :attr:`Outcome.MAX_STEPS`.
    """
    with ThreadPoolExecutor(min(len(starts), usable_cores()) or 1) as pool:
        states = list(pool.map(x64(lambda th: Start(evaluate(np.asarray(th, dtype=float)),
                                                    limit=max_steps)), starts))
        for s in states:
            if not s.terms.finite:
                s.outcome = Outcome.NONFINITE
        while True:
            lps = [s.lp for s in states if np.isfinite(s.lp)]
            best = max(lps) if lps else -np.inf
            for s in states:  # the MAP's candidate goes on while it still improves
                if s.outcome is Outcome.MAX_STEPS and s.lp == best and s.improving \
                        and s.limit < best_max_steps:
                    s.limit, s.outcome = min(2 * s.limit, best_max_steps), Outcome.RUNNING
            active = [s for s in states if not s.done]
            if not active:
                return states
            # the starts are independent: each thread steps one (the compiled kernel
            # runs outside Python's lock, so on several cores they run side by side)
            for _ in pool.map(x64(lambda s: _step(s, evaluate)), active):
                pass
            if abandon is not None:
                lps = [s.lp for s in states if np.isfinite(s.lp)]
                best = max(lps) if lps else -np.inf
                for s in states:
                    if not s.done and abandon(s, best):
                        s.outcome = Outcome.ABANDONED
