"""The adequacy verdict on sessions from a richer simulator than the fitted model.

Each misspecified bench of :mod:`pmdc_bayes.simulate.cases` (dead time, sensor lag,
brush drop, source resistance, current limit, an unknown load on one trace, speed
differenced from an encoder) is fitted with the ideal motor: the verdict must be
"inadequate" with the matching diagnosis.  Motors the ideal model describes must come
out "adequate" (the false-alarm rate is measured over many of them in the slow test;
``benchmarks/adequacy_rates.py`` measures it per check over more).
"""

import numpy as np
import pytest
from conftest import fit_and_assess

from pmdc_bayes.simulate.bench import bench_session
from pmdc_bayes.simulate.cases import CASES, SPEED_ONLY, case_session, random_motor


def _verdict(session, seed=0):
    return fit_and_assess(session, seed=seed).verdict


def _says(adequacy, *words):
    text = " ".join(adequacy.diagnosis).lower()
    return all(w in text for w in words)


@pytest.mark.compiles
def test_the_ideal_motor_is_adequate():
    a = _verdict(case_session())
    assert a.verdict == "adequate", [f.message for f in a.findings]
    assert a.diagnosis == ()


@pytest.mark.compiles
@pytest.mark.parametrize("case", list(CASES))
def test_each_bench_non_ideality_is_flagged_with_its_diagnosis(case):
    a = _verdict(case_session(case))
    assert a.verdict == "inadequate", case
    assert _says(a, *CASES[case][1]), (case, a.diagnosis, [f.message for f in a.findings])


@pytest.mark.compiles
def test_the_diagnosis_tells_dead_time_from_a_sensor_lag():
    """Dead time delays the current too; a speed-sensor lag leaves it on time."""
    dead, lag = _verdict(case_session("dead time")), _verdict(case_session("sensor lag"))
    assert not _says(dead, "lag in the speed sensor")
    assert not _says(lag, "dead time")
    assert _says(dead, 'dead_time = true under [model] in session.toml ("shared" when one '
                 "driver and logger serve every trace)")


@pytest.mark.compiles
def test_a_voltage_drop_is_not_taken_for_an_unknown_load_or_a_delay():
    a = _verdict(case_session("brush drop"))
    assert not _says(a, "unmeasured load")
    assert not _says(a, "later than the model")


@pytest.mark.compiles
@pytest.mark.parametrize("case", [c for c, words in SPEED_ONLY.items() if words])
def test_without_any_current_the_non_idealities_are_still_flagged(case):
    """A speed-only bench: the model absorbs a delay in Ra and La rather than missing
    the traces, and the diagnosis still names it."""
    a = _verdict(case_session(case, speed_only=True, steady_current=False))
    assert a.verdict == "inadequate", case
    assert _says(a, *SPEED_ONLY[case]), (case, a.diagnosis, [f.message for f in a.findings])


@pytest.mark.compiles
def test_what_speed_alone_cannot_reveal_is_not_flagged():
    """A source resistance adds to Ra; without a current the data cannot tell, so the
    model they do not reject is adequate (J absorbs it)."""
    (case,) = [c for c, words in SPEED_ONLY.items() if words is None]
    a = _verdict(case_session(case, speed_only=True, steady_current=False))
    assert a.verdict == "adequate", [f.message for f in a.findings]


@pytest.mark.compiles
def test_a_speed_only_ideal_bench_is_adequate():
    a = _verdict(case_session(speed_only=True, steady_current=False))
    assert a.verdict == "adequate", [f.message for f in a.findings]


N_MOTORS = 20


@pytest.mark.statistical
def test_false_alarm_rate_over_motors_the_model_describes():
    rng = np.random.default_rng(2026)
    verdicts = []
    for k in range(N_MOTORS):
        motor, steps = random_motor(rng)
        a = _verdict(bench_session(motor, steps, seed=k), seed=k)
        verdicts.append((a.verdict, [f.message for f in a.failures()]))
    alarms = [v for v in verdicts if v[0] != "adequate"]
    assert len(alarms) <= 0.05 * N_MOTORS, alarms


@pytest.mark.compiles
def test_a_unit_slip_on_one_trace_is_named():
    """The step_6v log holds rpm read as rad/s: the fit cannot absorb it (the other
    trace and the steady table disagree) and names the slip."""
    import dataclasses

    session = case_session()
    traces = tuple(dataclasses.replace(tr, speed=tr.speed * 60 / (2 * np.pi))
                   if tr.name == "step_6v" else tr for tr in session.traces)
    a = _verdict(dataclasses.replace(session, traces=traces))
    assert a.verdict == "inadequate"
    assert _says(a, "step_6v", "rpm given as rad/s"), a.diagnosis
    assert not _says(a, "unmeasured load"), a.diagnosis


def test_a_trace_counting_the_other_way_is_refused_before_the_fit():
    """The step_6v log counts the other way (its speed against its voltage, where the
    other trace and the steady table turn with theirs): bad input, named, before any
    fit."""
    import dataclasses

    from pmdc_bayes._errors import SessionError
    from pmdc_bayes.inference.model.contradictions import refuse_contradictions

    session = case_session()
    traces = tuple(dataclasses.replace(tr, speed=-tr.speed)
                   if tr.name == "step_6v" else tr for tr in session.traces)
    with pytest.raises(SessionError, match="'step_6v' turns against its voltage"):
        refuse_contradictions(dataclasses.replace(session, traces=traces))


@pytest.mark.compiles
@pytest.mark.parametrize("share", [0.01, 0.003])
def test_a_current_sensor_reading_off_zero_is_flagged_where_it_matters(share):
    """A Hall sensor's zero set wrong: every current reads a share of the inrush high,
    at rest too.  Against a span the inrush sets the slow misfit is small, but at 1 %
    the fit takes it for noise several times the data's own: inadequate, not an answer
    with B off.  At 0.3 % the noise it adds is immaterial: not failed for it."""
    import dataclasses

    s = case_session()
    offset = share * max(float(np.ptp(tr.current)) for tr in s.traces)
    shifted = tuple(dataclasses.replace(tr, current=tr.current + offset) for tr in s.traces)
    a = _verdict(dataclasses.replace(s, traces=shifted, steady_tables=()))
    inflated = [f for f in a.failures() if f.check == "noise inflation"]
    if share >= 0.01:
        assert a.verdict == "inadequate" and inflated, [f.message for f in a.findings]
    else:
        assert not inflated, inflated


@pytest.mark.compiles
def test_a_ripple_aliased_near_half_the_sampling_rate_is_named():
    """A PWM ripple sampled out of step with it: the current's residuals alternate from
    sample to sample; the likelihood's white noise is wrong, and the diagnosis says so
    and what to do."""
    import dataclasses

    s = case_session()
    rippled = tuple(dataclasses.replace(
        tr, current=tr.current + 0.05 * np.cos(np.pi * np.arange(tr.n) + 0.3))
        for tr in s.traces)
    a = _verdict(dataclasses.replace(s, traces=rippled))
    assert a.verdict == "inadequate"
    assert _says(a, "pwm ripple", "filter the current"), a.diagnosis
