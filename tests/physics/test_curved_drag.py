"""A known load that is not affine in the speed (a fan's quadratic drag, a measured brake
curve), carried by the exact solution through its tangent on short segments, against
the independent bench integrator (SciPy LSODA on the curve itself): with Coulomb
friction through a reversal, a current limit, a voltage drop, a sensor lag and a dead
time; the angle it integrates; a steady start under the curve; the derivatives against
finite differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.io.session import Drag
from pmdc_bayes.physics.experiment import stack_experiments
from pmdc_bayes.physics.load import (
    curve_arrays,
    curve_tangent,
    curve_torque,
    drag_cuts,
    linearisation_cuts,
    with_drags,
)
from pmdc_bayes.physics.solution import Params, simulate_padded
from pmdc_bayes.simulate.bench import BenchMotor, integrate, steady_point

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

MOTOR = dict(Ra=8.5, La=5.6e-3, K=0.062, B=4.5e-5, J=5.9e-4)
FAN = Drag(quadratic=1e-6, curve=((0.0, 0.0), (100.0, 3e-3), (300.0, 1.5e-2)))
T = np.arange(0.0, 2.5, 1e-3)
VT, VV = np.array([0.0, 0.1, 1.5]), np.array([0.0, 12.0, -6.0])


def _reference(tc=0.0, limit=None, drop=0.0, lag=0.0, delay=0.0, drag=FAN, t=T, vt=VT,
               vv=VV):
    bench = BenchMotor(**MOTOR, Tc=tc, current_limit=limit, voltage_drop=drop,
                       speed_lag=lag, extra_load={"t": drag})
    starts = vt + delay
    starts[0] = 0.0
    ends = np.append(starts[1:], t[-1])
    segments = list(zip(starts, ends, vv, np.zeros(vt.size), strict=True))
    return integrate(bench, "t", t, segments, np.zeros(5), w_eps=1e-5, i_eps=1e-7,
                     max_step=1e-3)


@x64
def _exact(ref_speed, tc=0.0, limit=None, drop=None, lag=None, delay=0.0, drag=FAN, t=T,
           vt=VT, vv=VV):
    cuts = drag_cuts(drag, t, vt, ref_speed)
    exp = with_drags(stack_experiments([(t, vt, vv, None, None, "rest", cuts)]), [drag])
    if delay:
        exp = exp.delayed(jnp.array([delay]))
    ia, w = simulate_padded(Params(**MOTOR, Tc=tc), exp, coulomb=tc > 0, limit=limit,
                            drop=drop, lags=None if lag is None else (None, lag))
    return np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w)), int(exp.seg_t0.shape[0])


def test_the_curve_is_odd_piecewise_linear_plus_quadratic_with_its_tangent():
    q, kw, kt = (a[0] for a in curve_arrays([FAN]))
    w = np.array([-400.0, -50.0, 0.0, 50.0, 200.0, 400.0])
    want = np.sign(w) * (1e-6 * w**2 + np.interp(np.abs(w), [0, 100, 300, 1e9],
                                                 [0, 3e-3, 1.5e-2, 1.5e-2 + 6e-5 * (1e9 - 300)]))
    np.testing.assert_allclose(curve_torque(w, q, kw, kt), want, rtol=1e-12, atol=1e-15)
    b, t0 = curve_tangent(150.0, q, kw, kt)
    assert b == pytest.approx(2 * 1e-6 * 150 + 6e-5)
    assert t0 + b * 150.0 == pytest.approx(float(curve_torque(150.0, q, kw, kt)))


@pytest.mark.parametrize(("tc", "limit", "drop", "lag", "delay"), [
    (0.0, None, None, None, 0.0),          # the viscous motor
    (2.5e-3, 1e200, None, None, 0.0),      # Coulomb friction through the reversal
    (2.5e-3, 1.0, None, None, 0.0),        # and a current limit
    (0.0, None, 0.8, None, 0.0),           # a voltage drop
    (2.5e-3, 1e200, None, 0.02, 0.0),      # a tachometer's lag
    (0.0, None, None, None, 0.0123),       # a dead time
])
def test_the_tangent_solution_follows_the_curved_load(tc, limit, drop, lag, delay):
    ref = _reference(tc, limit, drop or 0.0, lag or 0.0, delay)
    w_ref = ref[2] if lag else ref[1]
    ia, w, segments = _exact(ref[1], tc, limit, drop, lag, delay)
    span = np.abs(w_ref).max()
    assert segments < 600  # a few hundred tangents, not one per sample
    assert np.abs(w - w_ref).max() < 1e-6 * span, np.abs(w - w_ref).max()
    assert np.abs(ia - ref[0]).max() < 1e-6 * np.abs(ref[0]).max()
    # the curve matters: the motor without it runs far from the loaded one
    _, w_free, _ = _exact(ref[1], tc, limit, drop, lag, delay, drag=Drag())
    assert np.abs(w_free - w_ref).max() > 0.05 * span


@x64
def test_the_angle_under_a_curve_does_not_drift():
    """The tangent leaves out the curve's quadratic part over each segment, with one sign
    all along a rise; its mean over the segment is put back, or the speed's small error
    adds up in the angle (8.5e-4 rad over this trace without it; 2.7e-5 rad without the
    cuts where the speed crosses the curve's kink at 100 rad/s)."""
    ref = _reference(2.5e-3, 1e200)
    cuts = drag_cuts(FAN, T, VT, ref[1])
    exp = with_drags(stack_experiments([(T, VT, VV, None, None, "rest", cuts)]), [FAN])
    _, _, angle = simulate_padded(Params(**MOTOR, Tc=2.5e-3), exp, coulomb=True, limit=1e200,
                                  with_angle=True)
    assert np.abs(np.asarray(exp.unpad(angle)) - ref[3]).max() < 1e-5  # rad


def test_a_steady_start_under_a_curve_stays_steady():
    t = np.arange(0.0, 0.5, 1e-3)
    exp = with_drags(stack_experiments([(t, [0.0], [12.0], None, None, "steady",
                                         linearisation_cuts(t, [0.0]))]), [FAN])
    ia, w = x64(simulate_padded)(Params(**MOTOR, Tc=2.5e-3), exp, coulomb=True)
    ia_ss, w_ss = steady_point(BenchMotor(**MOTOR, Tc=2.5e-3), 12.0, drag=FAN)
    np.testing.assert_allclose(np.asarray(exp.unpad(w)), w_ss, rtol=1e-9)
    np.testing.assert_allclose(np.asarray(exp.unpad(ia)), ia_ss, rtol=1e-8)
    # the steady state balances the curve's torque
    q, kw, kt = (a[0] for a in curve_arrays([FAN]))
    drag = float(curve_torque(w_ss, q, kw, kt))
    assert MOTOR["K"] * ia_ss == pytest.approx(MOTOR["B"] * w_ss + 2.5e-3 + drag, rel=1e-9)


@x64
def test_the_derivatives_under_a_curve_match_finite_differences():
    t = np.arange(0.0, 0.8, 2e-3)
    vt, vv = np.array([0.0, 0.05, 0.5]), np.array([0.0, 12.0, 4.0])
    cuts = linearisation_cuts(t, vt)
    exp = with_drags(stack_experiments([(t, vt, vv, None, None, "rest", cuts)]), [FAN])

    @jax.jit
    def loss(q):
        ia, w = simulate_padded(Params(*q, Tc=2.5e-3), exp, coulomb=True)
        return jnp.sum(ia**2) + 1e-4 * jnp.sum(w**2)

    q = jnp.array(list(MOTOR.values()))
    grad = jax.grad(loss)(q)
    steps = 1e-6 * q
    fd = jax.vmap(lambda e: (loss(q + e) - loss(q - e)) / (2 * jnp.sum(e)))(jnp.diag(steps))
    np.testing.assert_allclose(np.asarray(grad), np.asarray(fd), rtol=2e-5)
