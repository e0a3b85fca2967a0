"""A first-order sensor lag (a tachometer, a filter): the recurrence against exact
solutions, and its recovery from benches integrated by SciPy with the lag as one more
state (``simulate/bench.py``), not by the package's model."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.physics.sensor import first_order_lag
from pmdc_bayes.simulate.bench import BenchMotor, bench_session
from pmdc_bayes.simulate.cases import MOTOR, STEADY_VOLTAGES, STEPS, case_session


@x64
def _lag(x, t, start, tau):
    return np.asarray(first_order_lag(jnp.asarray(x), jnp.asarray(t), jnp.asarray(start),
                                      tau))


def test_a_parabola_is_followed_exactly_and_each_trace_starts_settled():
    tau = 0.03
    t1 = np.linspace(0.0, 0.2, 41)
    t2 = np.sort(np.random.default_rng(0).uniform(0.0, 0.2, 30))  # uneven samples
    t2[0] = 0.0
    x1 = 5.0 * t1 + 40.0 * t1**2  # from rest
    x2 = 2.0 + 3.0 * t2  # a ramp from a settled 2
    start = np.r_[True, np.zeros(40, bool), True, np.zeros(29, bool)]
    y = _lag(np.r_[x1, x2], np.r_[t1, t2], start, tau)
    ramp = lambda t: t - tau * (1.0 - np.exp(-t / tau))  # noqa: E731
    # the lag of t²: t² − 2τ·t + 2τ²·(1 − e^(−t/τ))
    square = lambda t: t**2 - 2 * tau * t + 2 * tau**2 * (1.0 - np.exp(-t / tau))  # noqa: E731
    np.testing.assert_allclose(y[:41], 5.0 * ramp(t1) + 40.0 * square(t1), atol=1e-12)
    np.testing.assert_allclose(y[41:], 2.0 + 3.0 * ramp(t2), atol=1e-12)


def test_a_curved_signal_is_followed_to_third_order_in_the_sample_interval():
    tau, w = 0.02, 40.0
    exact = lambda t: (np.sin(w * t) - w * tau * np.cos(w * t)  # noqa: E731
                       + w * tau * np.exp(-t / tau)) / (1.0 + (w * tau) ** 2)
    errors = []
    for n in (201, 401, 801):
        t = np.linspace(0.0, 0.5, n)
        start = np.arange(n) == 0
        errors.append(np.max(np.abs(_lag(np.sin(w * t), t, start, tau) - exact(t))))
    assert errors[0] < 1e-4
    assert 7.0 < errors[0] / errors[1] < 9.0 and 7.0 < errors[1] / errors[2] < 9.0


def test_a_vanishing_lag_passes_the_signal_through():
    t = np.linspace(0.0, 1.0, 101)
    x = np.cos(7 * t)
    # (a lag is taken as at least 1e-12 s: the reading trails by that much)
    np.testing.assert_allclose(_lag(x, t, np.arange(101) == 0, 1e-300), x, atol=1e-10)
    # and its gradient is finite at every lag the prior allows
    import jax

    grad = jax.grad(lambda tau: jnp.sum(first_order_lag(jnp.asarray(x), jnp.asarray(t),
                                                        jnp.arange(101) == 0, tau)))
    for tau in (1e-300, 1e-6, 1e-2, 10.0):
        assert np.isfinite(float(x64(grad)(tau)))


def _fit(session, nuisances, **kw):
    from pmdc_bayes.pipeline import fit_session

    return fit_session(dataclasses.replace(session, nuisances=nuisances), **kw)


@pytest.mark.slow
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


@pytest.mark.slow
def test_a_lag_the_bench_does_not_have_is_found_negligible():
    fit = _fit(case_session(None, seed=3), ("speed_lag",), mcmc=False).fit
    dt = STEPS[0].dt
    assert fit.values["speed_lag"] < 0.1 * dt  # far below what the sampling can show


@pytest.mark.slow
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
