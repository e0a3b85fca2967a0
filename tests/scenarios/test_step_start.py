"""The step-start check on rigs drawn by the independent simulator: a step the session
places half a sample early (a dead time) fails it and a fitted dead time passes; a
current sensor's lag declared in the model is not taken for one."""

import pytest
from conftest import fit_and_assess, plan, step, sweep

from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session


def _plan(**rig) -> dict:
    """A motor with a fast electrical time constant, its rig's non-idealities ``rig``."""
    return plan(seed=9, motor="fast electrical time constant", friction="coulomb",
                truth={"Ra": 4.7, "La": 1.2e-3, "K": 0.032, "B": 6e-6, "J": 8e-6,
                       "Tc": 1.5e-3},
                bench={"Ra": (0.05, "ohm"), "La": (0.05, "mH")}, rig=rig,
                steady=(sweep([3.0, 6.0, 9.0, 12.0], 0.3, 0.0003, name="steady"),),
                traces=(step("step_12v", 12.0, duration=0.3, rate=1000.0, at=0.0204,
                             speed_noise=0.3, current_noise=0.003),))


def _verdict(tmp_path, rig, nuisances):
    session = load_session(simulate_session(_plan(**rig), tmp_path))
    return fit_and_assess(session, nuisances=nuisances).verdict


@pytest.mark.compiles
def test_a_step_half_a_sample_off_fails_the_check_and_a_dead_time_mends_it(tmp_path):
    ideal = _verdict(tmp_path / "a", {"dead_time": 0.0005}, ())
    starts = [f for f in ideal.findings if f.check == "step start"]
    assert ChannelId("step_12v", "current") in {f.where for f in starts}, ideal.findings
    assert any("--add dead-time" in line for line in ideal.diagnosis)
    fitted = _verdict(tmp_path / "b", {"dead_time": 0.0005}, ("dead_time",))
    assert fitted.verdict == "adequate", fitted.findings


@pytest.mark.compiles
def test_a_declared_current_lag_is_not_taken_for_a_step_off_time(tmp_path):
    """The current rises within a sample (τe 0.26 ms, 1 ms samples) through a 0.5 ms
    lag: the exact reading passes the check, and the lag and La are recovered."""
    session = load_session(simulate_session(_plan(current_lag=0.0005), tmp_path))
    _, _, fit, verdict = fit_and_assess(session, nuisances=("current_lag",))
    assert verdict.verdict == "adequate", verdict.findings
    for name, truth in (("current_lag", 5e-4), ("La", 1.2e-3)):
        assert abs(fit.values[name] - truth) < 3 * fit.sd[name], (name, fit.values[name])


@pytest.mark.compiles
def test_an_undeclared_current_lag_is_named_in_the_diagnosis(tmp_path):
    verdict = _verdict(tmp_path, {"current_lag": 0.0002}, ())
    assert verdict.verdict == "inadequate"
    assert any("--add current-lag" in line for line in verdict.diagnosis), verdict.diagnosis
