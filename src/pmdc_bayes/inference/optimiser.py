"""The MAP's optimiser: optimistix's Levenberg–Marquardt on the exact log-posterior, one
compiled step driven from the host.

:class:`ExactCurvature` is an optimistix quasi-Newton minimiser whose Hessian is not
built up from gradients (as BFGS's is) but is the model's own Gauss–Newton curvature at
each accepted point (:func:`.curvature.gauss_newton`, with the noise levels' term
where the result stays positive definite).  With optimistix's damped Newton descent and
classical trust region that is Levenberg–Marquardt on the negative log-posterior itself,
each channel's noise integrated out: a step is accepted only when the exact
log-posterior rises, so the fixed point is the exact MAP.  A trial point costs one
forward pass of the model; the gradient and curvature are computed at accepted points
only.

:class:`Stepper` compiles optimistix's ``step`` (its interactive stepping: ``init`` once,
then ``step`` and ``terminate`` from the host) once per session structure, as a function
of arrays (the solver's state flattened), which :mod:`.cache` keeps in memory and on
disk; every start of a fit, and every fit of a session of the same shapes, runs the
same program.  A start runs in coordinates ``y = (θ − θ_0)·s`` scaled by the curvature
at its start (``s_i = √H_ii``, Marquardt's scaling held for the start), so that the
trust region's damping weighs every parameter alike.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

from .._x64 import x64
from .curvature import Terms, gauss_newton

__all__ = ["ExactCurvature", "Stepper", "Step"]

RTOL = 0.0
ATOL = 1e-9  # converged: an accepted step under 1e-9 scaled units changing f by less


class ExactCurvature(optx.AbstractQuasiNewton):
    """Levenberg–Marquardt (optimistix's damped Newton descent and classical trust
    region) on a scalar objective whose Hessian at each accepted point is given.

    ``curvature(y)`` returns ``(grad, hessian, extras)``: the gradient and Hessian of the
    objective ``fn`` at ``y`` and any arrays to keep with the accepted point (the state's
    ``hessian_update_state``); ``extras0`` is a pytree of zeros of their shapes."""

    rtol: float
    atol: float
    norm: Callable
    use_inverse: bool
    descent: optx.DampedNewtonDescent
    search: optx.ClassicalTrustRegion
    verbose: Callable
    curvature: Callable
    extras0: object

    def __init__(self, curvature: Callable, extras0, *, rtol: float = RTOL,
                 atol: float = ATOL):
        self.rtol, self.atol, self.norm = rtol, atol, optx.max_norm
        self.use_inverse = False
        self.descent = optx.DampedNewtonDescent()
        self.search = optx.ClassicalTrustRegion()
        self.verbose = _quiet
        self.curvature, self.extras0 = curvature, extras0

    def init_hessian(self, y, f, grad):
        n = y.size
        hessian = lx.MatrixLinearOperator(jnp.zeros((n, n), y.dtype),
                                          lx.positive_semidefinite_tag)
        return optx.FunctionInfo.EvalGradHessian(f, grad, hessian), self.extras0

    def update_hessian(self, y, y_eval, f_info, f_eval_info, hessian_update_state):
        grad, hessian, extras = self.curvature(y_eval)
        operator = lx.MatrixLinearOperator(hessian, lx.positive_semidefinite_tag)
        return optx.FunctionInfo.EvalGradHessian(f_eval_info.f, grad, operator), extras


def _quiet(**_) -> None:
    return None


@dataclass(frozen=True)
class Step:
    """Where a start is after a step: ``y`` (the last accepted point, scaled), the
    solver's ``state`` (its arrays), the :class:`Terms` at ``y``, whether the solver
    ``terminated`` and its ``result`` in optimistix's words ("" when successful)."""

    y: np.ndarray
    state: list
    terms: Terms | None
    terminated: bool = False
    result: str = ""


class Stepper:
    """The compiled optimistix step of one objective.

    ``value(θ, data)`` is its log-posterior (a forward pass) and ``terms(θ, data)`` the
    tuple ``(lp, grad, H, H_noise, ss, G)`` of :func:`.curvature.gauss_newton`, both
    pure JAX; ``n_channels`` the length of ``ss``; ``compiled(name, build)`` keeps the
    built program (a session model's cache; by default a plain ``jax.jit``)."""

    def __init__(self, value, terms, data, n_params: int, n_channels: int, compiled=None):
        self.data = data
        extras0, self._state0, self._treedef = _initial(n_params, n_channels)

        def build():
            return jax.jit(_step_program(value, terms, extras0, self._treedef))

        self._step = build() if compiled is None else compiled("optimistix-step", build)

    @classmethod
    def of(cls, model) -> Stepper:
        """The stepper of a :class:`~.objective.SessionModel`, compiled once per session
        structure."""
        return cls(lambda t, d: model.log_posterior(t, data=d),
                   lambda t, d: gauss_newton(model, t, data=d), model.data,
                   len(model.names), len(model.channels), model.compiled)

    @x64
    def start(self, theta0, scale=None) -> Step:
        """The first step from ``θ0`` (scaled by ``scale``, default 1): it evaluates the
        objective and its curvature there, and moves nowhere."""
        theta0 = np.asarray(theta0, dtype=float)
        scale = np.ones_like(theta0) if scale is None else np.asarray(scale, dtype=float)
        return self.step(Step(np.zeros_like(theta0), self._state0, None), theta0, scale)

    @x64
    def step(self, at: Step, theta0, scale) -> Step:
        """One optimistix step of the start at ``at`` (one evaluation of the objective)."""
        y, leaves, done, result = self._step(jnp.asarray(at.y), at.state, jnp.asarray(theta0),
                                             jnp.asarray(scale), self.data)
        state = jax.tree_util.tree_unflatten(self._treedef, leaves)
        lp, grad, H, H_noise, ss, G = (np.asarray(x) for x in state.hessian_update_state)
        y = np.asarray(y)
        lp = float(lp) if np.isfinite(lp) else -np.inf
        terms = Terms(np.asarray(theta0) + y / np.asarray(scale), lp, grad, H, H_noise, ss, G)
        code = int(result)
        return Step(y, leaves, terms, bool(done), "" if code == 0 else _words(code))

    def terms(self, theta) -> Terms:
        """The log-posterior, gradient, curvatures and per-channel sums of squares at
        ``θ`` (in 64 bits, whoever calls it)."""
        return self.start(theta).terms


def _step_program(value, terms, extras0, treedef):
    """optimistix's ``step`` and ``terminate`` as one function of arrays: ``(y, state's
    leaves, θ0, s, data) → (y, state's leaves, terminated, result code)``."""

    def step(y, leaves, theta0, scale, data):
        def curvature(y_eval):
            out = terms(theta0 + y_eval / scale, data)
            _, grad, H, H_noise, _, _ = out
            positive = jnp.all(jnp.isfinite(jnp.linalg.cholesky(H_noise)))
            hessian = jnp.where(positive, H_noise, H) / jnp.outer(scale, scale)
            return -grad / scale, hessian, out

        solver = ExactCurvature(curvature, extras0)
        fn, args = _objective(value), (theta0, scale, data)
        state = jax.tree_util.tree_unflatten(treedef, leaves)
        y, state, _ = solver.step(fn, y, args, {}, state, frozenset())
        done, result = solver.terminate(fn, y, args, {}, state, frozenset())
        return y, jax.tree_util.tree_leaves(state), done, result._value

    return step


@functools.lru_cache(maxsize=64)
def _initial(n_params: int, n_channels: int):
    """``(extras0, leaves, treedef)``: the zeros of the terms a state keeps, and
    optimistix's initial state (flattened), the same for every start of a structure."""
    with jax.enable_x64(True):
        extras0 = tuple(jnp.zeros(shape, jnp.float64) for shape in (
            (), (n_params,), (n_params, n_params), (n_params, n_params), (n_channels,),
            (n_channels, n_params)))
        state = ExactCurvature(None, extras0).init(
            _objective(None), jnp.zeros(n_params, jnp.float64), None, {},
            jax.ShapeDtypeStruct((), jnp.float64), None, frozenset())
        leaves, treedef = jax.tree_util.tree_flatten(state)
        leaves = [jnp.asarray(x) for x in leaves]  # as the step returns them: one signature
    return extras0, leaves, treedef


def _objective(value):
    """optimistix's ``fn(y, (θ0, s, data))``: the negative log-posterior at ``θ0 + y/s``
    (+∞ where it is not finite).  Its own derivative is never taken: the gradient comes
    with the curvature, so ``y`` enters through ``stop_gradient`` and a trial costs one
    forward pass."""

    def fn(y, args):
        theta0, scale, data = args
        lp = value(theta0 + jax.lax.stop_gradient(y) / scale, data)
        return jnp.where(jnp.isfinite(lp), -lp, jnp.inf), None

    return fn


def _words(code: int) -> str:
    """optimistix's message for its ``RESULTS`` item of integer value ``code``."""
    shape = jax.tree_util.tree_structure(optx.RESULTS.successful)
    return optx.RESULTS[jax.tree_util.tree_unflatten(shape, [np.asarray(code, np.int32)])]
