"""The rotor's angle from the exact solution: exact against a fine quadrature of the
speed for any piecewise-constant input, where Coulomb friction stops and reverses the
motor too, continuous as a stop crosses a sample, and consistent with the dead time's
shifted inputs."""

import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes.physics.angle import since_first_sample
from pmdc_bayes.physics.experiment import stack_experiments
from pmdc_bayes.physics.solution import Params, simulate_padded

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

P = Params(8.5, 0.0056, 0.062, 4.5e-5, 5.9e-4, 0.0025)


def _angle(t, schedules, coulomb, tau_shift=0.0):
    specs = [(t, vt, vv, lt, lv, init) for vt, vv, lt, lv, init in schedules]
    exp = stack_experiments(specs)
    if tau_shift:
        exp = exp.delayed(jnp.full(len(schedules), tau_shift))
    ia, w, angle = simulate_padded(P, exp, coulomb=coulomb, with_angle=True)
    start = np.concatenate([np.arange(t.size) == 0] * len(schedules))
    theta = since_first_sample(exp, angle, jnp.asarray(start))
    return np.asarray(theta).reshape(len(schedules), -1), np.asarray(exp.unpad(w)).reshape(
        len(schedules), -1)


SCHEDULES = [([0.0, 0.1, 1.2], [0.0, 12.0, -6.0], [0.0, 0.5], [0.0, 0.002], "rest"),
             ([0.0, 0.3], [5.0, 9.0], None, None, "steady")]


def _reference(coulomb):
    tf = np.linspace(0.0, 2.0, 400001)
    _, wf = _angle(tf, SCHEDULES, coulomb)
    ref = np.concatenate([np.zeros((2, 1)),
                          np.cumsum(0.5 * (wf[:, 1:] + wf[:, :-1]) * np.diff(tf), axis=1)], 1)
    return tf, ref


@pytest.mark.parametrize("coulomb, tol", [(False, 1e-8), (True, 1e-7)])
def test_angle_between_coarse_samples_matches_a_fine_quadrature(coulomb, tol):
    tf, ref = _reference(coulomb)
    # samples 10 ms apart that straddle every breakpoint (0.1, 0.3, 0.5, 1.2 s)
    tc = np.concatenate([[0.0], np.arange(0.0013, 2.0, 0.01), [2.0]])
    theta, _ = _angle(tc, SCHEDULES, coulomb)
    expected = np.stack([np.interp(tc, tf, r) for r in ref])
    assert np.max(np.abs(theta - expected)) < tol
    assert np.max(np.abs(expected)) > 100.0  # it turned a long way: the test has teeth


def test_a_naive_trapezoid_of_the_samples_is_not_what_is_computed():
    tf, ref = _reference(False)
    tc = np.concatenate([[0.0], np.arange(0.0013, 2.0, 0.01), [2.0]])
    _, w = _angle(tc, SCHEDULES, False)
    trap = np.concatenate([[0.0], np.cumsum(0.5 * (w[0, 1:] + w[0, :-1]) * np.diff(tc))])
    assert np.max(np.abs(trap - np.interp(tc, tf, ref[0]))) > 1e-3


def test_a_dead_time_is_the_inputs_moved_later():
    t = np.arange(0.0, 1.0, 0.002)
    delay = 0.0137
    moved = [([0.0, 0.1 + delay], [0.0, 12.0], None, None, "rest")]
    theta_moved, _ = _angle(t, moved, False)
    delayed = [([0.0, 0.1], [0.0, 12.0], None, None, "rest")]
    theta_delayed, _ = _angle(t, delayed, False, tau_shift=delay)
    np.testing.assert_allclose(theta_delayed, theta_moved, atol=1e-9)
    assert theta_moved[0, -1] > 20.0
