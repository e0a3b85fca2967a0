"""The adequacy statistics and the onset diagnosis on signals whose answer is known."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.calibrate import ratio_p
from pmdc_bayes.inference.adequacy.onset import onset_shape
from pmdc_bayes.inference.adequacy.residual_stats import fit_percent, systematic_misfit, whiteness
from pmdc_bayes.io.channel import ChannelId


def test_white_noise_passes_and_a_slow_wave_fails_the_whiteness_test():
    rng = np.random.default_rng(1)
    e = rng.standard_normal(2000)
    w = whiteness(e)
    assert w["p_value"] > 1e-3 and w["max_abs_rho"] < 0.1
    wave = e + 3 * np.sin(np.linspace(0, 6 * np.pi, 2000))
    assert whiteness(wave)["p_value"] < 1e-10
    assert whiteness(wave)["rho1"] > 0.8


def test_differenced_noise_is_anti_correlated_at_lag_one():
    rng = np.random.default_rng(2)
    d = np.diff(rng.standard_normal(3001))
    assert whiteness(d)["rho1"] == pytest.approx(-0.5, abs=0.05)


def test_input_cross_correlation_sees_a_residual_that_follows_the_input():
    rng = np.random.default_rng(3)
    u = np.repeat(rng.choice([0.0, 1.0], 40), 50)
    r = rng.standard_normal(u.size)
    assert whiteness(r, u)["input_xcorr"] < 0.1
    assert whiteness(r + 2 * u, u)["input_xcorr"] > 0.5
    assert whiteness(r, np.ones(u.size))["input_xcorr"] is None


def test_fit_percent_is_matlab_compare():
    y = np.linspace(0, 10, 101)
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full_like(y, y.mean())) == pytest.approx(0.0)
    assert fit_percent(y, y + 0.1 * (y - y.mean())) == pytest.approx(90.0)


def test_systematic_misfit_ignores_white_noise_and_measures_a_wave():
    rng = np.random.default_rng(4)
    noise = 0.5 * rng.standard_normal(4000)
    assert systematic_misfit(noise, 0.5) < 0.03
    wave = 0.2 * np.sin(np.linspace(0, 4 * np.pi, 4000))
    assert systematic_misfit(noise + wave, 0.5) == pytest.approx(0.2 / np.sqrt(2), rel=0.15)


def test_the_noise_ratios_p_value_tightens_with_more_samples():
    assert ratio_p(1.2, 1.0, 50) > 0.05 > ratio_p(1.2, 1.0, 5000)
    assert ratio_p(1.0, 1.0, 500) == pytest.approx(0.5, abs=1e-12)


@pytest.mark.parametrize("kind", ["plain", "delayed", "lagged", "ramp"])
def test_onset_shape_tells_a_delay_or_lag_from_a_ramp(kind):
    t = np.arange(0, 0.5, 1e-3)
    tau, d = 0.05, 0.02
    if kind == "plain":
        y = 1 - np.exp(-t / tau)
    elif kind == "delayed":
        y = np.where(t > d, 1 - np.exp(-(t - d) / tau), 0.0)
    elif kind == "lagged":  # exponential seen through a first-order sensor of 20 ms
        y = 1 - (tau * np.exp(-t / tau) - d * np.exp(-t / d)) / (tau - d)
    else:  # acceleration limited for 40 ms, then exponential with matching slope
        tc, T = 0.04, 0.09
        y = np.where(t <= tc, t / T, 1 - (1 - tc / T) * np.exp(-(t - tc) / (T - tc)))
    y = 100 * y + 0.2 * np.random.default_rng(5).standard_normal(t.size)
    s = onset_shape(t, y, 0.0)
    if kind == "plain":
        assert min(s["delayed"], s["lagged"], s["ramp"]) > 0.6
    elif kind == "ramp":
        assert s["ramp"] < 0.6 and s["ramp"] < min(s["delayed"], s["lagged"])
        assert s["ramp_time"] == pytest.approx(0.04, rel=0.25)
    else:
        assert min(s["delayed"], s["lagged"]) < 0.6
        assert min(s["delayed"], s["lagged"]) < s["ramp"]
        if kind == "delayed":
            assert s["dead_time"] == pytest.approx(d, rel=0.25)


@pytest.mark.parametrize("seed", range(12))
def test_onset_shape_stays_finite_and_quiet_on_short_noisy_rises(seed):
    """Short, coarse, noisy rises whose shape searches wander far past the record: the
    times found stay between a tenth of a sample and ten records, without a numerical
    warning (which the suite turns into an error)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(12, 40))
    t = np.arange(n) * 1e-3
    tau = 10 ** rng.uniform(-3.5, -1)
    y = np.round(50 * (1 - np.exp(-t / tau)) + rng.normal(0, 10 ** rng.uniform(-1, 1), n))
    s = onset_shape(t, y, 0.0)
    if s is not None:
        assert all(np.isfinite(v) for v in s.values())
        assert 1e-4 <= s["dead_time"] <= 10 * t[-1]


def test_only_optima_close_to_the_map_raise_a_search_warning():
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.checks import search_checks

    assert search_checks(SimpleNamespace(mode_gaps=())) == []
    assert search_checks(SimpleNamespace(mode_gaps=(40.0, 900.0))) == []
    (w,) = search_checks(SimpleNamespace(mode_gaps=(2.5, 40.0)))
    assert w.severity == "warn" and w.check == "global search" and "2.5" in w.message


def _step_trace(n=400, h=1e-3, t_step=0.1):
    from pathlib import Path

    from pmdc_bayes.io.session import Schedule, Trace

    t = np.arange(n) * h
    return Trace("s", "step", Path("s.csv"), t, np.zeros(n), None,
                 Schedule(np.array([0.0, t_step]), np.array([0.0, 12.0])),
                 Schedule(np.array([0.0]), np.array([0.0])))


def test_a_misfit_at_the_steps_start_fails_and_noise_or_a_slow_misfit_does_not():
    from pmdc_bayes.inference.adequacy.checks import step_start_check

    tr = _step_trace()
    rng = np.random.default_rng(0)
    t = tr.time
    exact = np.where(t >= 0.1, 1.0 - np.exp(-(t - 0.1) / 2e-3), 0.0)
    late = np.where(t >= 0.1 + 1e-3, 1.0 - np.exp(-(t - 0.1 - 1e-3) / 2e-3), 0.0)
    y = exact + 0.002 * rng.standard_normal(t.size)
    (found,) = step_start_check(tr, "current", y, late, 0.002)  # one sample late
    assert found.severity == "fail" and found.where == ChannelId("s", "current")
    assert "--add dead-time" in found.message
    assert step_start_check(tr, "current", y, exact, 0.002) == []  # noise only
    # colored noise (a slow wave) as large: spread over the trace, not at the step
    wave = y + 0.02 * np.sin(2 * np.pi * t / 0.05)
    assert step_start_check(tr, "current", wave, exact, 0.002) == []
    # a logged voltage toggling every few samples: no step to single out
    toggling = type(tr.voltage)(t[::2], np.where(np.arange(t[::2].size) % 2, 12.0, 0.0))
    import dataclasses

    assert step_start_check(dataclasses.replace(tr, voltage=toggling), "current", y, late,
                            0.002) == []
