"""The MAP's optimiser: optimistix's Levenberg–Marquardt on the exact log-posterior, one
compiled step driven from the host.

:class:`ExactCurvature` is an optimistix quasi-Newton minimiser whose Hessian is not
built up from gradients (as BFGS's is) but is the model's own Gauss–Newton curvature at
each accepted point (:func:`.curvature.gauss_newton`, with the noise levels' term where
the result stays positive definite).  With a damped Newton descent and optimistix's
classical trust region that is Levenberg–Marquardt on the negative log-posterior
itself, each channel's noise integrated out: a step is accepted only when the exact
log-posterior rises, so the fixed point is the exact MAP.  A trial point costs one
forward pass of the model; the gradient and curvature are computed at accepted points
only.  The descent (:class:`MarquardtDescent`) is optimistix's damped Newton step with
Marquardt's scaling, the damping proportional to each parameter's own curvature where
optimistix's ``DampedNewtonDescent`` adds ``λ·I``: with ``λ·I`` the fits took up to
twice the steps and stopped short on curved ridges (``reports/benchmarks.md``, "The MAP
on optimistix").

:class:`Stepper` compiles optimistix's ``step`` and ``terminate`` (its interactive
stepping: ``init`` once, then ``step`` and ``terminate`` from the host) once per session
structure, as a function of arrays (the solver's state flattened), which :mod:`.cache`
keeps in memory and on disk: every start of a fit, and every fit of a session of the
same shapes, runs the same program.  A start steps ``y = θ − θ_0`` from its own
``θ_0``, so that one initial state (``y = 0``) serves them all.
"""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

from ..._x64 import to_device, x64
from .curvature import Terms, gauss_newton

__all__ = ["ExactCurvature", "MarquardtDescent", "Stepper", "Step"]

# The trust region grows after a step that gains this share of its prediction: the
# textbook 3/4 (optimistix's default, 0.99, seldom let the damping fall from where it
# started).
EXPAND = 0.75
DAMPING0 = 1e-3  # the first damping, relative to each curvature (Marquardt's and Nielsen's)
ATOL = 1e-9  # optimistix's own test: an accepted step moving θ and f by less has converged


class _DescentState(eqx.Module):
    f_info: optx.FunctionInfo.EvalGradHessian


class MarquardtDescent(optx.AbstractDescent):
    """The damped Newton descent with Marquardt's scaling: a step of size ``t`` solves
    ``(H + (μ0/t)·diag H) δ = −g``, so that the damping weighs each parameter by its
    own curvature at the current point (``diag H`` floored at 10⁻¹² of its largest)."""

    def init(self, y, f_info_struct):
        return _DescentState(jax.tree_util.tree_map(lambda s: jnp.zeros(s.shape, s.dtype),
                                                    f_info_struct))

    def query(self, y, f_info, state):
        return _DescentState(f_info)

    def step(self, step_size, state):
        H = state.f_info.hessian.as_matrix()
        d = jnp.diag(H)
        d = jnp.maximum(d, 1e-12 * jnp.max(d))
        tiny = step_size <= jnp.finfo(step_size.dtype).eps
        lam = jnp.where(tiny, jnp.finfo(step_size.dtype).max, 1.0 / jnp.where(tiny, 1.0,
                                                                              step_size))
        operator = lx.MatrixLinearOperator(H + jnp.diag(lam * DAMPING0 * d),
                                           lx.positive_semidefinite_tag)
        sol = lx.linear_solve(operator, state.f_info.grad, lx.Cholesky(), throw=False)
        return -sol.value, optx.RESULTS.promote(sol.result)


class ExactCurvature(optx.AbstractQuasiNewton):
    """Levenberg–Marquardt (:class:`MarquardtDescent` in optimistix's classical trust
    region) on a scalar objective whose Hessian at each accepted point is given.

    ``curvature(y)`` returns ``(grad, hessian, extras)``: the gradient and Hessian of the
    objective at ``y`` and any arrays to keep with the accepted point (the state's
    ``hessian_update_state``); ``extras0`` is a pytree of zeros of their shapes."""

    rtol: float
    atol: float
    norm: Callable
    use_inverse: bool
    descent: MarquardtDescent
    search: optx.ClassicalTrustRegion
    verbose: Callable
    curvature: Callable
    extras0: object

    def __init__(self, curvature: Callable, extras0, *, atol: float = ATOL):
        self.rtol, self.atol, self.norm = 0.0, atol, optx.max_norm
        self.use_inverse = False
        self.descent = MarquardtDescent()
        self.search = optx.ClassicalTrustRegion(high_cutoff=EXPAND)
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
    """Where a start is after a step: its origin ``theta0`` and ``y`` (the last accepted
    point less ``theta0``), the solver's ``state`` (its arrays), the :class:`Terms`
    there and the ``curvature`` the solver steps with from there (the Hessian of its
    objective), whether the solver ``terminated`` and its ``result`` in optimistix's
    words ("" when successful)."""

    theta0: np.ndarray
    y: np.ndarray
    state: list
    terms: Terms | None
    curvature: np.ndarray | None = None
    terminated: bool = False
    result: str = ""

    @property
    def decrement(self) -> float:
        """½·gᵀH⁻¹g at the accepted point: how much a full Newton step would still
        gain, with the solver's own curvature ``H``."""
        g, H = self.terms.grad, self.curvature
        try:
            x = np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            x = np.linalg.lstsq(H, g, rcond=None)[0]
        return 0.5 * float(g @ x)


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

    def on(self, data) -> Stepper:
        """The same compiled step on other ``data`` of the same shapes."""
        out = copy.copy(self)
        out.data = data
        return out

    def start(self, theta) -> Step:
        """The first step from ``θ``: it evaluates the objective and its curvature there,
        and moves nowhere."""
        theta = np.asarray(theta, dtype=float)
        return self.step(Step(theta, np.zeros_like(theta), self._state0, None))

    @x64
    def step(self, at: Step) -> Step:
        """One optimistix step of the start at ``at`` (one evaluation of the objective)."""
        y, leaves, done, result = self._step(to_device(at.y), at.state,
                                             to_device(at.theta0), self.data)
        state = jax.tree_util.tree_unflatten(self._treedef, leaves)
        lp, grad, H, H_noise, ss, G = (np.asarray(x) for x in state.hessian_update_state)
        y = np.asarray(y)
        lp = float(lp) if np.isfinite(lp) else -np.inf
        code = int(result)
        terms = Terms(at.theta0 + y, lp, grad, H, H_noise, ss, G)
        curvature = np.asarray(state.f_info.hessian.as_matrix())
        return Step(at.theta0, y, leaves, terms, curvature, bool(done),
                    "" if code == 0 else _words(code))

    def terms(self, theta) -> Terms:
        """The log-posterior, gradient, curvatures and per-channel sums of squares at
        ``θ`` (in 64 bits, whoever calls it)."""
        return self.start(theta).terms


def _step_program(value, terms, extras0, treedef):
    """optimistix's ``step`` and ``terminate`` as one function of arrays: ``(y, state's
    leaves, θ0, data) → (y, state's leaves, terminated, result code)``."""

    def step(y, leaves, theta0, data):
        def curvature(y_eval):
            out = terms(theta0 + y_eval, data)
            _, grad, H, H_noise, _, _ = out
            positive = jnp.all(jnp.isfinite(jnp.linalg.cholesky(H_noise)))
            return -grad, jnp.where(positive, H_noise, H), out

        solver = ExactCurvature(curvature, extras0)
        fn = _objective(value)
        state = jax.tree_util.tree_unflatten(treedef, leaves)
        args = (theta0, data)
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
        # as the step returns them (on its device, none weakly typed): one trace
        device = jax.devices()[0]
        leaves = [jax.device_put(np.asarray(x), device) for x in leaves]
    return extras0, leaves, treedef


def _objective(value):
    """optimistix's ``fn(y, (θ0, data))``: the negative log-posterior at ``θ0 + y`` (+∞
    where it is not finite).  Its own derivative is never taken: the gradient comes with
    the curvature, so ``y`` enters through ``stop_gradient`` and a trial costs one
    forward pass."""

    def fn(y, args):
        theta0, data = args
        lp = value(theta0 + jax.lax.stop_gradient(y), data)
        return jnp.where(jnp.isfinite(lp), -lp, jnp.inf), None

    return fn


def _words(code: int) -> str:
    """optimistix's message for its ``RESULTS`` item of integer value ``code``."""
    shape = jax.tree_util.tree_structure(optx.RESULTS.successful)
    return optx.RESULTS[jax.tree_util.tree_unflatten(shape, [np.asarray(code, np.int32)])]
