"""The adequacy checks' thresholds come from their statistics' distributions under the
fitted model (:mod:`pmdc_bayes.inference.adequacy.calibrate`), the diagnosis proposes only what
the model lacks, and a source resistance cannot go negative."""

import dataclasses

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.calibrate import holm, logged_quantum, tail_p
from pmdc_bayes.inference.adequacy.proposals import Proposal, has
from pmdc_bayes.inference.adequacy.trace_checks import channel_tests
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.io.session import NUISANCES

LEVEL = 0.05
TRIALS = 150
# false alarms at LEVEL over TRIALS in-class replicates: binomial sd √(0.05·0.95/150)
# = 0.018; allow three of them above the level
ALARM_LIMIT = LEVEL + 3 * np.sqrt(LEVEL * (1 - LEVEL) / TRIALS)


def _response(n=400):
    t = np.linspace(0.0, 0.2, n)
    return t, 100.0 * (1.0 - np.exp(-t / 0.03))


def _p_values(quantum, sigma, misfit=0.0):
    t, yhat = _response()
    rng = np.random.default_rng(11)
    out = []
    for _ in range(TRIALS):
        y = yhat + misfit * np.exp(-t / 0.02) + sigma * rng.standard_normal(t.size)
        if quantum:
            y = quantum * np.round(y / quantum)
        s0 = max(float(np.std(np.diff(y, 2)) / np.sqrt(6)), quantum / np.sqrt(12))
        row, _, _ = channel_tests(ChannelId("t", "speed"), y, yhat, None, s0,
                                  float(np.sqrt(np.mean((y - yhat) ** 2))), rng,
                                  quantum=quantum)
        out.append((row["systematic_p"], row["anti_correlation_p"], row["whiteness"]["p_value"]))
    return np.array(out)


@pytest.mark.statistical
@pytest.mark.parametrize(("quantum", "sigma"), [(0.0, 0.5), (1.0, 0.3)])
def test_a_correct_model_alarms_at_about_the_checks_level(quantum, sigma):
    """In-class replicates (white noise; a coarse quantum with noise below it): each
    check's p-value falls below the level about as often as the level says."""
    p = _p_values(quantum, sigma)
    rates = np.mean(p < LEVEL, axis=0)
    assert np.all(rates <= ALARM_LIMIT), rates


@pytest.mark.compiles
def test_a_systematic_misfit_is_flagged_negative_control():
    p = _p_values(0.0, 0.5, misfit=3.0)
    assert np.mean(p[:, 0] < LEVEL) > 0.95


def test_holm_controls_the_family_and_tail_p_reads_the_replicates():
    assert holm([0.001, 0.2, 0.006], 0.01).tolist() == [True, False, False]
    assert holm([0.003, 0.004], 0.01).tolist() == [True, True]
    reps = np.random.default_rng(0).standard_normal(400)
    assert tail_p(0.0, reps, side="two") > 0.8
    assert tail_p(5.0, reps, side="upper") < 1e-5
    assert logged_quantum(0.25 * np.array([0, 1, 3, 2, 7])) == pytest.approx(0.25)
    assert logged_quantum(np.random.default_rng(1).standard_normal(50)) == 0.0


def test_proposals_name_a_registry_key_and_a_trace_and_nothing_else():
    assert Proposal("unknown_load", "step_6v").trace == "step_6v"
    assert Proposal("coulomb").trace is None
    with pytest.raises(ValueError, match="speed-lag"):
        Proposal("speed-lag")
    assert set(NUISANCES) >= {"dead_time", "unknown_load", "source_resistance"}


def test_a_proposal_the_model_already_fits_is_recognised():
    from types import SimpleNamespace

    session = SimpleNamespace(nuisances=("unknown_load", "dead_time"),
                              unknown_load_traces=lambda: ("a",))
    model = SimpleNamespace(session=session, coulomb=False)
    assert has(model, Proposal("unknown_load", "a"))
    assert not has(model, Proposal("unknown_load", "b"))
    assert has(model, Proposal("dead_time", "b"))
    assert not has(model, Proposal("coulomb")) and not has(model, Proposal("speed_lag"))


def test_a_source_resistance_is_positive_and_none_stays_within_its_prior():
    from pmdc_bayes.inference.model.nuisances import nuisance_specs
    from pmdc_bayes.simulate.cases import case_session

    session = dataclasses.replace(case_session(), nuisances=("source_resistance",))
    (rs,) = [s for s in nuisance_specs(session) if s.name == "Rs"]
    assert rs.transform == "log" and rs.prior.kind == "lognormal" and rs.seed > 0
    none = 1e-3 * session.Ra.value  # a thousandth of Ra: "absent"
    assert abs(np.log(none / rs.prior.centre)) < 2 * rs.prior.scale


def test_the_rise_time_is_not_read_on_a_load_change_at_constant_voltage():
    from pmdc_bayes.inference.adequacy.plausibility import rise_eligible
    from pmdc_bayes.io.session import Schedule
    from pmdc_bayes.simulate.cases import case_session

    step = case_session().traces[0]
    assert rise_eligible(step)
    held = Schedule(np.array([0.0]), np.array([12.0]))
    loads = Schedule(np.array([0.0, 0.1]), np.array([0.0, 0.01]))
    load_change = dataclasses.replace(step, kind="load_change", voltage=held,
                                      load_torque=loads, initial="steady")
    assert not rise_eligible(load_change)


@pytest.mark.compiles
def test_a_misspecified_bench_is_flagged_with_its_p_value_and_no_proposal_the_model_has():
    from pmdc_bayes.inference.adequacy.verdict import assess
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.simulate.cases import case_session

    session = dataclasses.replace(case_session("unknown load"),
                                  nuisances=("dead_time", "speed_lag"))
    cf = fit_seed(session)
    model = build_model(session, cf)
    a = assess(model, fit_map(model), cf)
    assert a.verdict == "inadequate"
    fails = a.failures()
    m = sum(t["family"] == "verdict" for t in a.tests)
    assert min(f.p_value for f in fails if f.p_value is not None) <= a.level / m
    assert a.as_json()["family_level"] == a.level == 0.01
    assert a.proposals and all(not has(model, p) for p in a.proposals)
    assert Proposal("unknown_load", "step_6v") in a.proposals
    assert not {"dead_time", "speed_lag"} & {p.nuisance for p in a.proposals}


def test_the_rise_time_of_a_trace_that_steps_twice_is_read_before_its_second_step():
    """0 → 6 V at 31 ms, then 6 → 12 V at 300 ms, a speed rising with τ = 13.5 ms after
    each: the check reads the first step's rise up to the second step (about τ), not up
    to 63 % of the trace's final speed, which the second step makes (0.27 s)."""
    from pmdc_bayes.inference.adequacy.onset import step_window
    from pmdc_bayes.inference.adequacy.plausibility import _rise_test
    from pmdc_bayes.io.session import Schedule
    from pmdc_bayes.simulate.cases import case_session

    t = np.arange(600) * 1e-3
    tau = 0.0135
    w = sum(100.0 * (1.0 - np.exp(-np.clip(t - t0, 0.0, None) / tau)) for t0 in (0.031, 0.3))
    w = w + np.random.default_rng(2).normal(0.0, 0.5, t.size)
    volts = Schedule(np.array([0.0, 0.031, 0.3]), np.array([0.0, 6.0, 12.0]))
    tr = dataclasses.replace(case_session().traces[0], time=t, speed=w, current=None,
                             voltage=volts, load_torque=Schedule(np.zeros(1), np.zeros(1)),
                             position=None, speed_logged=True, initial="rest")
    t_step, inside = step_window(tr)
    assert t_step == pytest.approx(0.031) and t[inside][-1] < 0.3 <= t[~inside][0]
    once = dataclasses.replace(tr, voltage=Schedule(volts.times[:2], volts.values[:2]))
    assert step_window(once)[1].all()  # no later change: read to the trace's end
    rises = {}
    (test,) = _rise_test(None, 0, tr, w, {}, {ChannelId(tr.name, "speed"): 0.5},
                         np.random.default_rng(3), rises, {})
    assert rises[tr.name]["observed"] == pytest.approx(tau, abs=2e-3)
    assert test.p_value > 0.01  # the model is the data's own curve
