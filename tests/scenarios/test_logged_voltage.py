"""A voltage logged at every sample (a driver's PWM-averaged output, jittering from
sample to sample) on rigs drawn by the independent simulator: its jitter is not taken
for a step by the closed form, and a dead time of several samples is recovered exactly
(the inputs' breakpoints move with it, however close they lie)."""

import dataclasses

import numpy as np
import pytest

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Schedule
from pmdc_bayes.paper.checks import step_of
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5}


def _jittery(level, t_on, rate=1000.0, duration=0.15, seed=0):
    """Breakpoints at every sample: 0 V until ``t_on``, then ``level`` ± 0.3 V."""
    t = np.arange(0.0, duration, 1.0 / rate)
    v = np.where(t < t_on, 0.0, level + np.random.default_rng(seed).normal(0.0, 0.3, t.size))
    return [[float(a), float(b)] for a, b in zip(t, v, strict=True)]


def _plan(rig):
    traces = [{"name": name, "kind": "step", "duration": 0.15, "rate": 1000.0,
               "voltage": _jittery(level, 0.02, seed=k), "speed_noise": 0.05,
               "current_noise": 0.002}
              for k, (name, level) in enumerate((("run_9v", 9.0), ("run_5v", 5.0)))]
    return {"seed": 4, "motor": {"name": "logged voltage"}, "truth": dict(TRUTH),
            "bench": {"Ra": {"sd": 0.06, "unit": "ohm"}}, "rig": rig,
            "steady_table": [{"name": "steady", "voltages": [3.0, 6.0, 9.0],
                              "speed_sd": 0.3, "current_sd": 0.0003}],
            "trace": traces}


def test_the_jitter_of_a_logged_voltage_is_not_a_step(tmp_path):
    session = load_session(simulate_session(_plan({}), tmp_path))
    tr = session.traces[0]
    assert tr.voltage.values.size >= tr.n - 1  # a breakpoint at every sample
    t_step, before, after = step_of(tr)
    assert t_step == pytest.approx(0.02) and before == 0.0 and after == pytest.approx(9.0, abs=0.3)
    # the same level from the first sample: a step from rest there, at the median level
    times, values = tr.voltage.times, tr.voltage.values
    steady = dataclasses.replace(tr, voltage=Schedule(times, np.where(times < 0.02, 9.0,
                                                                       values)))
    t_step, before, after = step_of(steady)
    assert t_step == tr.time[0] and before == 0.0 and after == pytest.approx(9.0, abs=0.1)


@pytest.mark.compiles
def test_a_dead_time_of_several_samples_under_a_logged_voltage_is_recovered(tmp_path):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    session = load_session(simulate_session(_plan({"dead_time": 0.0043}), tmp_path))
    ideal = fit_session(session, FitOptions(mcmc=False))
    assert ideal.adequacy.verdict == "inadequate"
    res = fit_session(dataclasses.replace(session, nuisances=("dead_time",)),
                      FitOptions(mcmc=False))
    assert res.adequacy.verdict == "adequate", [f.message for f in res.adequacy.findings]
    fit = res.fit
    for name in ("dead_time_run_9v", "dead_time_run_5v"):
        assert abs(fit.values[name] - 0.0043) < 3 * fit.sd[name], (name, fit.values[name])
    for name in ("La", "K", "Ra"):
        assert abs(fit.values[name] - TRUTH[name]) < 3 * fit.sd[name], (name, fit.values[name])
