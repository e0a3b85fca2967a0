"""A first-order sensor lag (a tachometer, a filter) as one more linear state of the
exact solution: against the matrix exponential of the motor with the sensors as two
more states (SciPy), against a fine-grid lag of the exact state through Coulomb
friction and a current limit, and its recovery from benches integrated by SciPy with
the lag as one more state (``simulate/bench.py``), not by the package's model."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import lfilter

from pmdc_bayes._x64 import x64
from pmdc_bayes.physics import motor
from pmdc_bayes.physics.sensor import coast_down_reading, pole
from pmdc_bayes.physics.solution import Params, make_experiment, simulate_padded
from pmdc_bayes.simulate.bench import BenchMotor, bench_session
from pmdc_bayes.simulate.cases import MOTOR, STEADY_VOLTAGES, STEPS, case_session

P = Params(Ra=2.0, La=2e-3, K=0.05, B=1e-5, J=2e-5, Tc=4e-3)
T = np.arange(0.0, 0.3, 1e-3)
# a step between samples, then a reversal
VT, VV = np.array([0.0, 0.0105, 0.15]), np.array([0.0, 12.0, -6.0])


@x64
def _read(p, t, vt, vv, lags, **kw):
    exp = make_experiment(t, vt, vv)
    ia, w = simulate_padded(p, exp, lags=lags, **kw)
    return np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w))


def _augmented(p, t, vt, vv, tau_i, tau_w):
    """(ia, ω, current reading, speed reading) at ``t`` from rest: the four-state linear
    system stepped by SciPy's matrix exponential, input breakpoints included."""
    a = np.array([[-p.Ra / p.La, -p.K / p.La, 0, 0], [p.K / p.J, -p.B / p.J, 0, 0],
                  [1 / tau_i, 0, -1 / tau_i, 0], [0, 1 / tau_w, 0, -1 / tau_w]])
    m = np.zeros((5, 5))
    m[:4, :4], m[0, 4] = a, 1 / p.La
    x, out, now = np.zeros(4), [np.zeros(4)], t[0]
    for tk in t[1:]:
        cuts = [now] + [b for b in vt if now < b < tk] + [tk]
        for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
            e = expm(m * (hi - lo))
            x = e[:4, :4] @ x + e[:4, 4] * vv[np.searchsorted(vt, lo, side="right") - 1]
        now = tk
        out.append(x.copy())
    return np.array(out)


def _eigenvalues(p):
    a = np.array([[-p.Ra / p.La, -p.K / p.La], [p.K / p.J, -p.B / p.J]])
    return np.sort(np.linalg.eigvals(a).real)


@pytest.mark.parametrize("lags", [(1e-4, 3e-3), (1e-3, 0.02), (1e-3, 0.5), (0.02, 1e-4)])
def test_the_viscous_readings_are_the_four_state_matrix_exponential(lags):
    ia, w = _read(P, T, VT, VV, lags)
    ref = _augmented(P, T, VT, VV, *lags)
    np.testing.assert_allclose(ia, ref[:, 2], atol=1e-12 * np.abs(ref[:, 2]).max())
    np.testing.assert_allclose(w, ref[:, 3], atol=1e-12 * np.abs(ref[:, 3]).max())


def test_a_lag_on_one_of_the_motor_s_own_time_constants_stays_exact_with_finite_gradients(jax_x64):
    """Where −1/τs is an eigenvalue of A the resolvent is singular; there the reading is
    exactly that of a lag six parts in 10⁵ shorter (the documented move)."""
    fast, slow = -1.0 / _eigenvalues(P)
    for lags in ((fast, slow), (slow, fast)):
        ia, w = _read(P, T, VT, VV, lags)
        ref = _augmented(P, T, VT, VV, *(lag / (1.0 + 6e-5) for lag in lags))
        assert np.abs(ia - ref[:, 2]).max() < 1e-9 * np.abs(ref[:, 2]).max()
        assert np.abs(w - ref[:, 3]).max() < 1e-9 * np.abs(ref[:, 3]).max()
        unmoved = _augmented(P, T, VT, VV, *lags)  # and that is within 1e-4 of the lag's own
        assert np.abs(w - unmoved[:, 3]).max() < 1e-4 * np.abs(unmoved[:, 3]).max()
        exp = make_experiment(T, VT, VV)

        def total(q, lags=lags, exp=exp):
            ia, w = simulate_padded(Params(*q), exp, lags=lags)
            return jnp.sum(ia**2) + jnp.sum(w**2)

        grad = x64(jax.grad(total))(jnp.array([P.Ra, P.La, P.K, P.B, P.J, 0.0]))
        assert np.all(np.isfinite(np.asarray(grad)))


def test_the_lag_s_derivative_stays_accurate_close_to_an_eigenvalue(jax_x64):
    """Just outside the window where the lag is moved off an eigenvalue, the resolvent's
    derivative keeps its digits."""
    slow = -1.0 / _eigenvalues(P)[1]
    exp = make_experiment(T, VT, VV)
    grad = x64(jax.grad(lambda tau: jnp.sum(simulate_padded(P, exp, lags=(1e-3, tau))[1])))
    far = float(grad(slow * (1.0 + 1e-3)))
    for delta in (1e-7, 1e-6, 1e-5, 1e-4):
        assert float(grad(slow * (1.0 + delta))) == pytest.approx(far, rel=2e-3)


def _lag_on_grid(x, t, tau):
    """A first-order lag of ``x``, settled at the start, taken as linear between the
    points of a fine even grid ``t``: ``y_k = a·y_{k−1} + c0·x_{k−1} + c1·x_k``."""
    h = t[1] - t[0]
    a = np.exp(-h / tau)
    c1 = (h - tau * (1 - a)) / h
    c0 = 1 - a - c1
    y, _ = lfilter([c1, c0], [1.0, -a], x, zi=[(1 - c1) * x[0]])
    return y


@pytest.mark.parametrize(("coulomb", "limit"), [(True, None), (False, 1.5), (True, 1.5)])
def test_the_readings_follow_the_state_through_stick_slip_and_a_current_limit(coulomb, limit):
    """Breakaway, stops, a reversal and clamped phases, read through lags both shorter
    and longer than a sample interval."""
    t_end = 0.4
    vt, vv = np.array([0.0, 0.0105, 0.15, 0.25]), np.array([0.0, 12.0, -12.0, 0.0])
    fine = np.linspace(0.0, t_end, 800001)
    coarse = np.arange(0.0, t_end, 1e-3)
    ia_f, w_f = _read(P, fine, vt, vv, None, coulomb=coulomb, limit=limit)
    if limit is not None:
        assert np.abs(ia_f).max() == pytest.approx(limit)  # the limit is met
    at = np.searchsorted(fine, coarse - 1e-12)
    for lags in ((3e-4, 5e-3), (2e-3, 0.05)):
        ia, w = _read(P, coarse, vt, vv, lags, coulomb=coulomb, limit=limit)
        ref_i, ref_w = _lag_on_grid(ia_f, fine, lags[0]), _lag_on_grid(w_f, fine, lags[1])
        assert np.abs(ia - ref_i[at]).max() < 2e-6 * np.abs(ref_i).max()
        assert np.abs(w - ref_w[at]).max() < 2e-6 * np.abs(ref_w).max()


@pytest.mark.parametrize("tc", [0.0, 4e-3])
def test_a_coast_down_is_read_through_the_lag_until_and_after_it_stops(tc):
    w0, tau = 200.0, 0.02
    fine = np.linspace(0.0, 1.2, 200001)
    true = np.asarray(motor.coast_down(P.B, P.J, w0, fine, tc))
    if tc:
        assert true[-1] == 0.0  # the rotor stops within the record
    ref = _lag_on_grid(true, fine, tau)
    got = np.asarray(x64(coast_down_reading)(P.B, P.J, w0, jnp.asarray(fine), tc,
                                              pole(tau)))
    assert np.abs(got - ref).max() < 1e-6 * w0


def test_a_vanishing_lag_passes_the_signal_through_with_finite_gradients(jax_x64):
    ia0, w0 = _read(P, T, VT, VV, None)
    ia, w = _read(P, T, VT, VV, (1e-300, 1e-300))
    # (a lag is taken as at least 1e-12 s: the reading trails by that much)
    np.testing.assert_allclose(ia, ia0, atol=1e-9 * np.abs(ia0).max())
    np.testing.assert_allclose(w, w0, atol=1e-9 * np.abs(w0).max())
    exp = make_experiment(T, VT, VV)
    grad = x64(jax.grad(lambda tau: jnp.sum(simulate_padded(P, exp, lags=(tau, tau))[1])))
    for tau in (1e-300, 1e-6, 1e-2, 10.0):
        assert np.isfinite(float(grad(tau)))


def _fit(session, nuisances, **kw):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    return fit_session(dataclasses.replace(session, nuisances=nuisances), FitOptions(**kw))


@pytest.mark.compiles
def test_a_speed_sensor_lag_is_recovered_and_sampled():
    res = _fit(case_session("sensor lag", seed=3), ("speed_lag",), mcmc=True, seed=1)
    assert res.adequacy.verdict == "adequate"
    p = res.summary["parameters"]["speed_lag"]
    assert p["unit"] == "s" and p["r_hat"] < 1.01
    assert abs(p["mean"] - 3e-3) < 3 * p["sd"], p
    assert p["hdi_3%"] < 3e-3 < p["hdi_97%"]
    for name in ("Ra", "K", "J"):
        row = res.summary["parameters"][name]
        assert abs(row["mean"] - MOTOR[name]) < 4 * row["sd"], (name, row)


@pytest.mark.compiles
def test_a_lag_the_bench_does_not_have_is_found_negligible():
    fit = _fit(case_session(None, seed=3), ("speed_lag",), mcmc=False).fit
    dt = STEPS[0].dt
    assert fit.values["speed_lag"] < 0.1 * dt  # far below what the sampling can show


@pytest.mark.compiles
def test_a_current_sensor_lag_is_recovered():
    session = bench_session(BenchMotor(**MOTOR, current_lag=1e-3), STEPS, seed=4,
                            steady_voltages=STEADY_VOLTAGES)
    ideal = _fit(session, (), mcmc=False)
    assert ideal.adequacy.verdict == "inadequate"
    res = _fit(session, ("current_lag",), mcmc=False)
    assert res.adequacy.verdict == "adequate", [f.message for f in res.adequacy.findings]
    fit = res.fit
    assert abs(fit.values["current_lag"] - 1e-3) < 3 * fit.sd["current_lag"]
    assert abs(fit.values["La"] - MOTOR["La"]) < 3 * fit.sd["La"]


@pytest.mark.compiles
def test_a_current_lag_shorter_than_a_sample_is_recovered_with_la():
    """The current rises within a sample (La/Ra 0.26 ms, 1 ms samples) and its sensor
    lags by 0.1 ms: both are fitted from the readings."""
    fast = dict(MOTOR, La=5.2e-4)
    steps = tuple(dataclasses.replace(s, dt=1e-3) for s in STEPS)
    session = bench_session(BenchMotor(**fast, current_lag=1e-4, current_noise=0.01), steps,
                            seed=0, steady_voltages=STEADY_VOLTAGES)
    res = _fit(session, ("current_lag",), mcmc=False)
    assert res.adequacy.verdict == "adequate", [f.message for f in res.adequacy.findings]
    fit = res.fit
    for name, truth in (("current_lag", 1e-4), ("La", fast["La"]), ("Ra", fast["Ra"])):
        assert abs(fit.values[name] - truth) < 3 * fit.sd[name], (name, fit.values[name])
