"""The MAP fit's optimiser: the curvature its compiled optimistix step reads, against
the model's own log-posterior and JAX's gradient, and the starts moved from the host
on problems with a known optimum (a curved valley, a start where the model is not
finite)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.fit import multistart as ms
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.fit.optimiser import Stepper
from pmdc_bayes.inference.model.objective import NU0, build_model
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.paper.closed_form import closed_form


@pytest.fixture(scope="module")
def demo_model():
    s = load_session("demo")
    return build_model(s, closed_form(s))


@x64
def test_the_kernel_is_the_models_log_posterior_its_gradient_and_curvature(demo_model):
    model = demo_model
    theta = np.asarray(model.theta_seed()) + 0.01 * np.arange(len(model.names))
    t = Stepper.of(model).terms(theta)
    lp = float(model.log_posterior(jnp.asarray(theta)))
    grad = np.asarray(jax.grad(lambda x: model.log_posterior(x))(jnp.asarray(theta)))
    assert t.lp == pytest.approx(lp, rel=1e-12)
    np.testing.assert_allclose(t.grad, grad, rtol=1e-7, atol=1e-9 * np.abs(grad).max())
    ss = np.asarray(model.sums_of_squares(jnp.asarray(theta)))
    np.testing.assert_allclose(t.ss, ss, rtol=1e-12)
    # the Gauss–Newton matrix is JᵀWJ of the weighted residuals at the weights of θ
    w = np.where(model.n_obs > 0, (model.n_obs + NU0) / (NU0 * model.s0**2 + ss), 0.0)
    jac = np.asarray(jax.jacfwd(lambda x: model.weighted_residuals(x, jnp.asarray(w)))(
        jnp.asarray(theta)))
    np.testing.assert_allclose(t.H, jac.T @ jac, rtol=1e-9, atol=1e-12 * np.abs(t.H).max())
    # the noise term lowers the curvature along each channel's ∇SS, never raises it
    assert np.all(np.linalg.eigvalsh(t.H - t.H_noise) >= -1e-9 * np.abs(t.H).max())


def test_the_kernel_computes_in_64_bits_for_a_caller_in_32(demo_model):
    """Called with JAX's 64-bit mode off (the caller's setting, left as it is), the
    kernel still computes in 64 bits: no truncation warning (an error in this suite) and
    the same log-posterior as inside the package's 64-bit context."""
    theta = np.asarray(x64(demo_model.theta_seed)())
    inside = x64(Stepper.of(demo_model).terms)(theta)
    with jax.enable_x64(False):  # a caller's setting, whatever the suite's
        t = Stepper.of(demo_model).terms(theta)
        assert not jax.config.jax_enable_x64
    assert t.H.dtype == np.float64 and t.lp == inside.lp


def _rosenbrock(a: float = 10.0, finite_from: float = -np.inf) -> Stepper:
    """lp = −½(a²(y − x²)² + (1 − x)²) as residuals r = (a(y − x²), 1 − x): a curved
    valley with its top at (1, 1); not finite where x < ``finite_from``.  ``a`` and the
    bound are data: every valley runs the same compiled step."""

    with jax.enable_x64(True):
        data = {"a": jnp.asarray(a), "finite_from": jnp.asarray(finite_from)}
    return Stepper(lambda t, d: _valley_terms(t, d)[0], _valley_terms, data, 2, 1,
                   _once)


def _valley(theta, d):
    x, y = theta[0], theta[1]
    r = jnp.stack([d["a"] * (y - x * x), 1.0 - x])
    return jnp.where(x >= d["finite_from"], -0.5 * r @ r, -jnp.inf), r


def _valley_terms(theta, d):
    """The valley's ``(lp, grad, H, H_noise, ss, G)``, as :func:`gauss_newton`'s."""
    lp, r = _valley(theta, d)
    jac = jax.jacfwd(lambda t: _valley(t, d)[1])(theta)
    H = jac.T @ jac
    return lp, -jac.T @ r, H, H, jnp.stack([r @ r]), jnp.zeros((1, 2))


_ROSENBROCK: dict = {}


def _once(name, build):
    """One compiled step for every valley."""
    if name not in _ROSENBROCK:
        _ROSENBROCK[name] = build()
    return _ROSENBROCK[name]


def test_the_host_loop_climbs_a_curved_valley_to_its_top():
    (s,) = ms.maximise(_rosenbrock(), [np.array([-1.2, 1.0])])
    assert s.converged and s.stopped == "converged"
    # converged means a Newton step would gain under DECREMENT_TOL: at the top (lp 0) to
    # within that, and so within sqrt(2·tol/λ_min) ≈ 3e-4 of (1, 1)
    assert -ms.DECREMENT_TOL <= s.lp <= 0.0
    np.testing.assert_allclose(s.theta, [1.0, 1.0], atol=1e-3)
    assert s.steps < ms.MAX_STEPS


def test_a_start_where_the_model_is_not_finite_stops_without_a_step():
    a, b = ms.maximise(_rosenbrock(finite_from=-5.0),
                       [np.array([-9.0, 0.0]), np.array([0.0, 0.0])])
    assert not a.converged and a.steps == 0 and "not finite" in a.stopped
    assert b.converged


def test_a_start_far_below_the_best_is_abandoned():
    states = ms.maximise(
        _rosenbrock(a=100.0), [np.array([1.0, 1.0]), np.array([-3.0, 0.0])],
        abandon=lambda s, best: s.steps >= 1 and s.lp < best - 10.0)
    assert states[0].converged
    assert states[1].stopped == "far below the best" and not states[1].converged


@x64
def test_the_map_is_where_the_log_posterior_gradient_vanishes(demo_model):
    fit = fit_map(demo_model)
    assert fit.ok, fit.message
    grad = np.asarray(jax.grad(lambda x: demo_model.log_posterior(x))(jnp.asarray(fit.theta)))
    # in units of each parameter's Laplace sd (θ space), the gradient is negligible
    sd_log = np.sqrt(np.diag(fit.cov_log))
    assert np.max(np.abs(grad * sd_log)) < 1e-3


def test_a_crawl_along_a_narrow_curved_valley_stops_within_the_resolution():
    """Rosenbrock's banana (a = 100): however the start ends, converged or stopped as a
    slow crawl, it is within RESOLUTION per parameter of the top in log-posterior."""
    (s,) = ms.maximise(_rosenbrock(a=100.0), [np.array([-1.2, 1.0])])
    assert s.converged, s.stopped
    assert s.lp >= -ms.RESOLUTION * 2
    assert s.steps < ms.MAX_STEPS


def test_two_finals_are_one_optimum_unless_a_valley_separates_them():
    from types import SimpleNamespace

    from pmdc_bayes.inference.fit.optima import distinct_optima

    cov = np.diag([1e-4, 1e-4])  # narrow Laplace widths: the finals are many sds apart
    thetas = np.array([[1.0, 0.0], [-1.0, 0.0]])
    ok = np.array([True, True])

    def well(theta):  # a double well: optima at x = ±1, a dip of 50 at x = 0
        return SimpleNamespace(lp=-50.0 * (theta[0] ** 2 - 1.0) ** 2)

    def ridge(theta):  # flat along x: the two finals lie on one ridge
        return SimpleNamespace(lp=-50.0 * theta[1] ** 2)

    logp = np.array([0.0, -0.1])
    modes, label = distinct_optima(thetas, logp, ok, cov, well)
    assert modes == [0, 1] and label == [0, 1]
    modes, label = distinct_optima(thetas, logp, ok, cov, ridge)
    assert modes == [0] and label == [0, 0]
    # a start that did not converge belongs to no optimum
    modes, label = distinct_optima(thetas, logp, np.array([True, False]), cov, well)
    assert modes == [0] and label == [0, -1]
    # one that stalled where a converged one ended (a kink) reached that optimum
    near = np.array([[1.0, 0.0], [1.0 + 5e-3, 0.0], [1.0 + 5e-2, 0.0]])
    modes, label = distinct_optima(near, np.array([0.0, -0.05, -0.05]),
                                   np.array([True, False, False]), cov, well)
    assert modes == [0] and label == [0, 0, -1]  # the last lies 5 sds away


# The step limit: a typed outcome, the best start continued while it improves


def test_a_start_at_its_step_limit_ends_with_that_outcome_not_as_converged():
    """A badly scaled banana (a = 10⁴) from far up its valley needs over a thousand
    steps: held to 200, the start ends with the outcome MAX_STEPS, far below the top."""
    (s,) = ms.maximise(_rosenbrock(a=1e4), [np.array([-5.0, 25.0])],
                                  best_max_steps=ms.MAX_STEPS)
    assert s.outcome is ms.Outcome.MAX_STEPS and not s.converged
    assert s.stopped == "step limit" and s.steps == ms.MAX_STEPS and s.improving
    assert s.lp < -1.0


def test_the_best_start_still_improving_is_continued_and_the_others_are_not():
    """Both starts reach the 200-step limit; the better one, still rising, is given more
    steps and ends within the resolution of the top, the other ends at the limit."""
    best, other = ms.maximise(
        _rosenbrock(a=1e4), [np.array([-1.2, 1.0]), np.array([-5.0, 25.0])])
    assert best.converged, best.stopped
    assert ms.MAX_STEPS < best.steps <= ms.BEST_MAX_STEPS and best.limit > ms.MAX_STEPS
    assert best.lp >= -ms.RESOLUTION * 2
    assert other.outcome is ms.Outcome.MAX_STEPS and other.steps == ms.MAX_STEPS


def test_a_map_whose_start_ends_at_its_step_limit_fails_and_says_so_first(demo_model,
                                                                           monkeypatch):
    """With an artificially low limit the MAP's start ends at it: the fit fails, its
    message opens with why, and its outcome is typed; let the best start go on, and the
    same fit converges."""
    import functools

    from pmdc_bayes.inference.fit import joint as fit_module

    low = functools.partial(ms.maximise, max_steps=3, best_max_steps=3)
    monkeypatch.setattr(fit_module, "maximise", low)
    fit = fit_map(demo_model)
    assert fit.status == "failed" and fit.outcome is ms.Outcome.MAX_STEPS
    assert fit.message.startswith("the MAP is not an optimum: its Levenberg–Marquardt "
                                  "start stopped at its step limit (3 steps)"), fit.message
    assert {s["outcome"] for s in fit.starts} <= {"MAX_STEPS", "NONFINITE"}
    continued = functools.partial(ms.maximise, max_steps=3)
    monkeypatch.setattr(fit_module, "maximise", continued)
    fit = fit_map(demo_model)
    assert fit.ok and fit.outcome.converged, fit.message
    assert fit.iterations > 3


def test_the_starts_end_alike_whether_one_thread_or_many_steps_them(monkeypatch):
    """A round's starts depend only on their own state and the round before: with one
    thread or four (in whatever order they finish), every start ends at the same point
    after the same steps, with the same outcome, abandonment included."""
    starts = [np.array(x) for x in ([-1.2, 1.0], [-5.0, 25.0], [2.0, 0.0], [0.5, 3.0])]

    def run(threads):
        monkeypatch.setattr(ms, "usable_cores", lambda: threads)
        return ms.maximise(_rosenbrock(a=1e3), starts,
                                      abandon=lambda s, best: s.steps >= 20 and s.lp < best - 5)

    one, many = run(1), run(4)
    assert {s.outcome for s in one} >= {ms.Outcome.ABANDONED}
    for a, b in zip(one, many, strict=True):
        np.testing.assert_array_equal(a.theta, b.theta)
        assert (a.steps, a.outcome, a.history) == (b.steps, b.outcome, b.history)


# optimistix: the solver, its own driver, its results in words


def test_the_solver_is_an_optimistix_minimiser_that_its_own_driver_runs_to_the_top():
    """``ExactCurvature`` given to ``optimistix.minimise`` (optimistix's own loop, not the
    host's) climbs the valley to the same top as the starts stepped from the host."""
    import optimistix as optx

    from pmdc_bayes.inference.fit import optimiser

    stepper = _rosenbrock()
    (hosted,) = ms.maximise(stepper, [np.array([-1.2, 1.0])])
    with jax.enable_x64(True):
        def curvature(y):  # the origin θ0 = 0: y is θ
            out = _valley_terms(y, stepper.data)
            return -out[1], out[3], out

        solver = optimiser.ExactCurvature(curvature, optimiser._initial(2, 1)[0], atol=1e-12)
        sol = optx.minimise(optimiser._objective(lambda t, d: _valley_terms(t, d)[0]),
                            solver, jnp.array([-1.2, 1.0]),
                            args=(jnp.zeros(2), stepper.data),
                            has_aux=True, max_steps=500)
    assert sol.result == optx.RESULTS.successful
    np.testing.assert_allclose(np.asarray(sol.value), [1.0, 1.0], atol=1e-6)
    # the host stops once a Newton step would gain under DECREMENT_TOL (≈ 3e-4 from it)
    np.testing.assert_allclose(hosted.theta, np.asarray(sol.value), atol=1e-3)


def test_every_accepted_step_raises_the_exact_log_posterior(demo_model):
    theta = np.asarray(x64(demo_model.theta_seed)()) + 0.3
    (s,) = ms.maximise(Stepper.of(demo_model), [theta])
    assert s.converged, s.stopped
    assert len(s.history) > 3 and np.all(np.diff(s.history) > 0)
    assert s.lp == pytest.approx(float(x64(demo_model.log_posterior)(np.asarray(s.theta))),
                                 rel=1e-12)


def test_a_start_the_solver_stops_with_an_error_ends_in_optimistix_words(monkeypatch):
    """A result other than success from optimistix ends the start with the outcome
    SOLVER and optimistix's own message, not as converged."""
    import dataclasses

    import optimistix as optx

    from pmdc_bayes.inference.fit import optimiser

    code = int(np.asarray(optx.RESULTS.nonlinear_divergence._value))
    words = optx.RESULTS[optx.RESULTS.nonlinear_divergence]
    assert optimiser._words(code) == words
    stepper = _rosenbrock()
    real = stepper.step

    def diverging(at):
        return dataclasses.replace(real(at), result=words)

    monkeypatch.setattr(stepper, "step", diverging)
    (s,) = ms.maximise(stepper, [np.array([-1.2, 1.0])])
    assert s.outcome is ms.Outcome.SOLVER and not s.converged and s.steps == 1
    assert s.stopped == f"{ms.Outcome.SOLVER.value}: {words}"
