"""A voltage drop that opposes the current (brushes, driver) in the exact solution,
against the independent bench integrator (SciPy LSODA, the drop's sign smoothed over a
band of 1e-7 A): braking at 0 V until the back-emf falls below the drop, then coasting
with no current, a reversal, with and without Coulomb friction and a current limit;
and the derivatives against finite differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.physics.solution import Params, make_experiment, simulate_padded
from pmdc_bayes.simulate.bench import BenchMotor, integrate

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

MOTOR = dict(Ra=2.0, La=2e-3, K=0.05, B=2e-5, J=2e-5)
T = np.arange(0.0, 0.6, 5e-4)
# 12 V, braked at 0 V, 6 V, then reversed to −3 V
VT, VV = np.array([0.0, 0.01, 0.15, 0.3, 0.45]), np.array([0.0, 12.0, 0.0, 6.0, -3.0])


@x64
def _exact(tc, limit, drop, lags=None):
    exp = make_experiment(T, VT, VV)
    ia, w = simulate_padded(Params(**MOTOR, Tc=tc), exp, coulomb=tc > 0, limit=limit,
                            drop=drop, lags=lags)
    return np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w))


@pytest.mark.parametrize(("tc", "limit", "drop"),
                         [(0.0, None, 1.5), (1e-3, None, 1.5), (1e-3, 2.0, 1.5), (0.0, 2.0, 0.8)])
def test_the_drop_follows_the_current_through_braking_coasting_and_reversal(tc, limit, drop):
    bench = BenchMotor(**MOTOR, Tc=tc, voltage_drop=drop, current_limit=limit)
    ends = np.append(VT[1:], T[-1])
    segments = list(zip(VT, ends, VV, np.zeros(VT.size), strict=True))
    ref = integrate(bench, "t", T, segments, np.zeros(5), w_eps=1e-4, i_eps=1e-7,
                    max_step=5e-4)
    ia, w = _exact(tc, limit, drop)
    assert np.abs(ia - ref[0]).max() < 1e-5
    assert np.abs(w - ref[1]).max() < 1e-6 * np.abs(ref[1]).max()
    # braked at 0 V: the current flows, stops once K·ω falls below the drop, and stays
    # at zero while the rotor coasts on
    braking = (T > 0.15) & (T < 0.3)
    assert ia[braking].min() < -1.0
    coasting = braking & (MOTOR["K"] * np.abs(w) < drop - 0.05)
    assert np.all(ia[coasting] == 0.0) and np.all(w[coasting] > 0.0)
    if limit is None:  # unlimited, the braking ends within the segment
        assert coasting.sum() > 20


@pytest.mark.compiles
def test_the_derivatives_through_the_zero_crossings_match_finite_differences():
    exp = make_experiment(T, VT, VV)

    def loss(q):
        ia, w = simulate_padded(Params(*q[:5], Tc=1e-3), exp, coulomb=True, limit=2.0,
                                drop=q[5], lags=(1e-4, 2e-3))
        return jnp.sum(ia**2) + 1e-4 * jnp.sum(w**2)

    q = jnp.array([*MOTOR.values(), 1.5])
    # forward mode, as the fit differentiates the model (reverse mode through the
    # located switching times: test_limited.py)
    grad = np.asarray(x64(jax.jit(jax.jacfwd(loss)))(q))
    eps = 1e-6
    both = x64(jax.jit(jax.vmap(loss)))  # every displaced θ in one compiled call
    up = both(jnp.stack([q.at[k].multiply(1 + eps) for k in range(q.size)]))
    down = both(jnp.stack([q.at[k].multiply(1 - eps) for k in range(q.size)]))
    for k in range(q.size):
        fd = float(up[k] - down[k]) / (2 * eps * float(q[k]))
        assert grad[k] == pytest.approx(fd, rel=1e-5)


def test_without_a_drop_the_solution_is_unchanged():
    for tc, limit in ((0.0, None), (1e-3, 2.0)):
        np.testing.assert_allclose(_exact(tc, limit, 0.0), _exact(tc, limit, None), atol=1e-9)


@pytest.mark.parametrize("end", [0.20, 0.21, 0.22, 0.25])
def test_a_current_flows_again_once_the_back_emf_falls_below_the_drop(end):
    """12 V, then 2 V against a 0.5 V drop: the current stops, the rotor coasts until
    K·ω falls below 1.5 V, and the current flows again.  (At that instant dia/dt = 0; a
    rounding error of the wrong sign once left the current at zero for the rest of the
    segment, depending on the trace's length.)"""
    motor = dict(MOTOR, B=2e-4)
    t = np.linspace(0.0, end, 201)
    vt, vv = np.array([0.0, 0.1]), np.array([12.0, 2.0])
    exp = make_experiment(t, vt, vv, initial="steady")
    ia, w = x64(simulate_padded)(Params(**motor, Tc=3e-3), exp, coulomb=True, drop=0.5)
    ia, w = np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w))
    bench = BenchMotor(**motor, Tc=3e-3, voltage_drop=0.5)
    x0 = np.array([ia[0], w[0], w[0], 0.0, ia[0]])
    ref = integrate(bench, "t", t, [(0.0, 0.1, 12.0, 0.0), (0.1, end, 2.0, 0.0)], x0,
                    w_eps=1e-4, i_eps=1e-7, max_step=2e-4)
    assert ia[-1] > 0.1  # conducting again at the end
    assert abs(ia[-1] - ref[0][-1]) < 1e-5 and abs(w[-1] - ref[1][-1]) < 1e-5 * abs(w[-1])


@pytest.mark.parametrize(("va", "tl", "tc"), [(5.0, -0.02, 0.0), (0.0, -0.02, 0.0),
                                              (1.0, 0.004, 0.0), (5.0, -0.02, 1e-3),
                                              (5.0, 0.0, 1e-3)])
def test_a_steady_start_with_a_drop_stays_steady_under_any_load(va, tl, tc):
    """The current's sign, not the voltage's, decides which way the drop acts: a load
    that drives the rotor makes it generate, and below the drop no current flows."""
    t = np.linspace(0.0, 0.2, 41)
    exp = make_experiment(t, [0.0], [va], [0.0], [tl], initial="steady")
    ia, w = x64(simulate_padded)(Params(**MOTOR, Tc=tc), exp, coulomb=tc > 0, drop=1.5)
    ia, w = np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w))
    np.testing.assert_allclose(w, w[0], atol=1e-9 * max(1.0, abs(w[0])))
    np.testing.assert_allclose(ia, ia[0], atol=1e-12)
    # and it is the state the drop allows: no current within the drop, else its sign
    drive = va - MOTOR["K"] * w[0]
    assert ia[0] == 0.0 if abs(drive) <= 1.5 else np.sign(ia[0]) == np.sign(drive)


@pytest.mark.parametrize(("tc", "drop"), [(0.0, None), (1e-3, None), (1e-3, 0.8)])
def test_a_driver_that_opens_the_armature_at_zero_lets_the_rotor_coast(tc, drop):
    """An H-bridge whose enable goes low at a zero command (an L298N in coast mode):
    the current returns through the diodes against the supply and stops within
    microseconds, and the rotor then coasts on its friction, far longer than a
    shorted armature would let it; the exact solution follows the integrator."""
    bench = BenchMotor(**MOTOR, Tc=tc, voltage_drop=drop or 0.0, freewheel_voltage=13.4)
    ends = np.append(VT[1:], T[-1])
    segments = list(zip(VT, ends, VV, np.zeros(VT.size), strict=True))
    ref = integrate(bench, "t", T, segments, np.zeros(5), w_eps=1e-4, i_eps=1e-7,
                    max_step=5e-4)
    exp = make_experiment(T, VT, VV)
    p = Params(**MOTOR, Tc=tc)
    ia, w = (np.asarray(exp.unpad(a)) for a in x64(simulate_padded)(
        p, exp, coulomb=tc > 0, drop=drop, open_volts=13.4))
    assert np.abs(ia - ref[0]).max() < 1e-5
    assert np.abs(w - ref[1]).max() < 1e-6 * np.abs(ref[1]).max()
    open_ = (T > 0.1502) & (T < 0.3)
    assert np.all(ia[open_] == 0.0)
    from pmdc_bayes.physics.motor import coast_down
    t_open = T[open_]
    coast = coast_down(MOTOR["B"], MOTOR["J"], w[open_][0], t_open - t_open[0], tc)
    np.testing.assert_allclose(w[open_], coast, rtol=1e-6, atol=1e-9)
    _, braked = _exact(tc, None, drop if drop else 1e-9)
    assert w[open_][-1] > 2 * braked[open_][-1]  # a shorted armature brakes it far sooner
