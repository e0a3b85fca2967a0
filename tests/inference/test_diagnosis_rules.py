"""The model-free rules the diagnosis reads, on sessions whose cause is known."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.findings import Check, Finding, Severity
from pmdc_bayes.inference.adequacy.onset import departure
from pmdc_bayes.inference.model.levels import friction_offset, level_outliers, voltage_intercept
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.simulate.bench import BenchMotor, bench_session
from pmdc_bayes.simulate.cases import MOTOR, STEPS, case_session


def test_the_speed_voltage_line_crosses_zero_at_the_brush_drop():
    icpt = voltage_intercept(case_session("brush drop"))
    assert icpt["voltage"] == pytest.approx(1.0, abs=max(3 * icpt["se"], 0.02))
    ideal = voltage_intercept(case_session())
    assert abs(ideal["voltage"]) < max(3 * ideal["se"], 0.02)


def test_a_loaded_trace_sits_off_the_line_of_the_other_levels():
    out = level_outliers(case_session("unknown load"))
    assert list(out) == ["step_6v"] and out["step_6v"] == pytest.approx(-0.10, abs=0.02)
    assert level_outliers(case_session("brush drop")) == {}
    assert level_outliers(case_session()) == {}


def test_without_enough_levels_no_trace_is_judged():
    session = bench_session(BenchMotor(**MOTOR), STEPS)
    assert level_outliers(session) is None


def test_coulomb_friction_leaves_a_current_at_zero_speed():
    tc = 2e-3
    coulomb = bench_session(BenchMotor(**MOTOR, Tc=tc), STEPS, steady_voltages=(4.0, 8.0, 12.0))
    off = friction_offset(coulomb)
    assert off["current"] == pytest.approx(tc / MOTOR["K"], rel=0.1)
    ideal = friction_offset(case_session())
    assert abs(ideal["current"]) < max(3 * ideal["se"], 0.05 * tc / MOTOR["K"])


def test_departure_finds_when_a_signal_leaves_rest():
    t = np.arange(0, 0.1, 1e-3)
    rng = np.random.default_rng(0)
    y = np.where(t > 0.02, 1 - np.exp(-(t - 0.02) / 0.01), 0.0) + 1e-3 * rng.standard_normal(t.size)
    assert departure(t, y, 0.0, 5e-3) == pytest.approx(0.021, abs=2e-3)
    assert departure(t, np.zeros_like(t), 0.0, 5e-3) is None


def test_a_trace_cut_before_it_settles_gives_no_steady_level():
    from pmdc_bayes.inference.model.levels import settled, unloaded_levels

    t = np.linspace(0, 1, 500)
    assert not settled(1 - np.exp(-t / 0.5))
    assert settled(1 - np.exp(-t / 0.05))
    session = bench_session(BenchMotor(**MOTOR), [s.__class__(s.name, s.voltage, 0.01, s.dt)
                                                  for s in STEPS])
    rows, names = unloaded_levels(session)
    assert rows.shape[0] == 0 and names == []


def test_a_no_load_speed_the_session_contradicts_fails_the_plausibility_check():
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.plausibility import plausibility_checks
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.paper.closed_form import closed_form

    session = case_session()
    model = build_model(session, closed_form(session))
    truth = dict(session.truth)
    preds = [(np.asarray(tr.current), np.asarray(tr.speed)) for tr in session.traces]
    _, found = plausibility_checks(model, SimpleNamespace(values=truth), preds)
    assert not [f for f in found if f.where == "no-load speed"]
    wrong = dict(truth, K=0.6 * truth["K"])  # no-load speed ~ 1/K: 1.6x the logged one
    out, found = plausibility_checks(model, SimpleNamespace(values=wrong), preds)
    (f,) = [f for f in found if f.where == "no-load speed"]
    assert f.severity == "fail"
    # the steady table's 12 V row (0.3 % reading noise) is the level compared
    assert out["no_load_speed"]["logged_speed"] == pytest.approx(
        session.steady_tables[0].speed[-1], rel=1e-12)


def test_a_steady_readings_miss_is_read_on_its_priors_student_t():
    """The no-load level from a steady table: a reading's noise is not known from the
    reading, so its miss is read on the steady channel's prior (Student's t with ν0
    degrees at the scale s0), whatever the fit's noise level says: a miss of 5·s0 (a
    reading as noisy as the prior allows) is no alarm where a normal at s0 would call it
    one, a miss of 40·s0 is one."""
    from types import SimpleNamespace

    from scipy.optimize import brentq

    from pmdc_bayes.inference.adequacy.plausibility import plausibility_checks
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.paper.closed_form import closed_form
    from pmdc_bayes.physics.motor import steady_state

    session = case_session()
    model = build_model(session, closed_form(session))
    preds = [(np.asarray(tr.current), np.asarray(tr.speed)) for tr in session.traces]
    table = session.steady_tables[0]
    v, top = float(table.voltage[-1]), float(table.speed[-1])
    (ch,) = [c for c in model.channels if c.id == ChannelId("steady", "speed")]
    truth = dict(session.truth)

    def model_speed(k):
        return float(steady_state(truth["Ra"], k, truth["B"], v)[1])

    verdicts = {}
    for misses in (5.0, 40.0):  # the model's speed below the reading by this many s0
        k = brentq(lambda k, m=misses: top - model_speed(k) - m * ch.s0,
                   truth["K"], 3 * truth["K"])
        fit = SimpleNamespace(values=dict(truth, K=k), noise_sd={ch.id: 50 * ch.s0})
        out, found = plausibility_checks(model, fit, preds)
        assert out["no_load_speed"]["logged_speed"] == pytest.approx(top, rel=1e-12)
        verdicts[misses] = [f.severity for f in found if f.where == "no-load speed"]
    assert verdicts == {5.0: [], 40.0: ["fail"]}


@pytest.mark.parametrize("volts", [0.0, 0.04])
def test_a_rotor_at_rest_where_the_model_holds_it_is_no_contradiction(volts):
    """A level at rest (a trace back at 0 V, or a voltage too low to break Coulomb
    friction away) is no evidence against a model that holds the rotor there too: no
    no-load speed is judged at 0 V, and a model at rest where the rotor is does not fail."""
    import dataclasses
    from pathlib import Path
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.plausibility import plausibility_checks
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.io.session import SteadyTable
    from pmdc_bayes.paper.closed_form import closed_form

    tc = 2e-3
    motor = dict(MOTOR, Tc=tc)
    assert volts < tc * motor["Ra"] / motor["K"]  # below breakaway: the rotor stays put
    short = [s.__class__(s.name, s.voltage, 0.01, s.dt) for s in STEPS]  # never settles
    session = bench_session(BenchMotor(**motor), short, steady_voltages=(4.0, 8.0))
    rest = SteadyTable("rest", Path("rest.csv"), np.array([volts]), np.array([0.0]), None,
                       np.zeros(1))
    session = dataclasses.replace(session, steady_tables=(rest,), friction="coulomb")
    model = build_model(session, closed_form(session), coulomb=True)
    preds = [(np.asarray(tr.current), np.asarray(tr.speed)) for tr in session.traces]
    out, found = plausibility_checks(model, SimpleNamespace(values=dict(session.truth)), preds)
    assert not [f for f in found if f.where == "no-load speed"]
    if volts:
        assert out["no_load_speed"]["model_at_logged_voltage"] == 0.0


def test_a_level_read_off_an_angle_is_judged_on_the_angles_noise():
    """A trace logging only its angle (an encoder) ends on a level whose speed is the
    angle's change over the window: the true motor is no contradiction there (it was
    judged on a speed noise of zero, p = 0), a motor 10 % faster is one."""
    import dataclasses
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.plausibility import plausibility_checks
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.io.position import speed_estimate
    from pmdc_bayes.paper.closed_form import closed_form
    from pmdc_bayes.physics.motor import steady_state

    rng = np.random.default_rng(3)
    session = bench_session(BenchMotor(**MOTOR), STEPS)
    traces, preds = [], []
    for tr in session.traces:
        true_w = np.asarray(tr.speed)
        preds.append((np.asarray(tr.current), true_w))
        angle = np.concatenate([[0.0], np.cumsum(0.5 * (true_w[1:] + true_w[:-1])
                                                 * np.diff(tr.time))])
        angle = angle + 1e-3 * rng.standard_normal(angle.size)
        traces.append(dataclasses.replace(tr, position=angle, speed_logged=False,
                                          speed=speed_estimate(tr.time, angle)))
    session = dataclasses.replace(session, traces=tuple(traces), steady_tables=(),
                                  operating_points=())
    model = build_model(session, closed_form(session))
    truth = dict(session.truth)
    out, found = plausibility_checks(model, SimpleNamespace(values=truth), preds)
    assert out["no_load_speed"]["logged_voltage"] != 0
    assert not [f for f in found if f.where == "no-load speed"]
    v = out["no_load_speed"]["logged_voltage"]
    k = truth["K"] / 1.1  # about 10 % faster at no load
    fast = [(i, w * steady_state(truth["Ra"], k, truth["B"], v)[1]
             / steady_state(truth["Ra"], truth["K"], truth["B"], v)[1]) for i, w in preds]
    out, found = plausibility_checks(model, SimpleNamespace(values=dict(truth, K=k)), fast)
    assert [f.severity for f in found if f.where == "no-load speed"] == ["fail"]


def test_a_driven_trace_whose_speed_never_leaves_its_noise_is_named():
    import dataclasses
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.diagnosis import _still
    from pmdc_bayes.inference.model.noise import Channel, noise_scale
    from pmdc_bayes.simulate.bench import StepSpec

    session = bench_session(BenchMotor(**MOTOR), [StepSpec("off", 0.0, 0.12, 2e-4),
                                                  StepSpec("on", 12.0, 0.12, 2e-4)])
    off, on = session.traces
    rng = np.random.default_rng(3)
    blocked = dataclasses.replace(on, speed=off.speed + 0.01 * rng.standard_normal(off.n))
    model = SimpleNamespace(channels=[Channel(ChannelId(tr.name, "speed"), "rad/s", tr.n,
                                              noise_scale(tr.speed)) for tr in (off, on)])
    assert _still(model, off) == []  # nothing applied, nothing expected
    assert _still(model, on) == []  # it turns
    (sentence,) = _still(model, blocked)
    assert sentence.startswith("on: the speed never leaves its noise although 12 V")


def test_a_resistance_above_the_bench_proposes_a_source_resistance_and_a_drop():
    """A fitted Ra above the bench's is what a source resistance and a constant drop at
    the brushes or switches both leave at a steady current: both are proposed, and the
    evidence chooses (a drop was explained as a source resistance, with K 36 sd off)."""
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.diagnosis import diagnose
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.paper.closed_form import closed_form

    session = case_session()
    model = build_model(session, closed_form(session))
    truth = dict(session.truth)
    preds = [(np.asarray(tr.current), np.asarray(tr.speed)) for tr in session.traces]
    fit = SimpleNamespace(values=dict(truth, Ra=1.3 * truth["Ra"]))
    conflict = Finding(Check.BENCH_CONFLICT, "Ra", Severity.FAIL, "+5 sd",
                       "Ra is 5 sd above the bench")
    _, proposals = diagnose(model, fit, preds, [conflict])
    assert {p.nuisance for p in proposals} >= {"source_resistance", "voltage_drop"}


def test_a_step_start_on_a_trace_named_with_a_colon_proposes_for_that_trace():
    """A finding names its channel by trace and signal, not by text: a trace whose name
    holds ": " gets the dead time proposed for it, and the lag of the signal that
    missed the step's start."""
    import dataclasses
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.diagnosis import diagnose
    from pmdc_bayes.inference.adequacy.proposals import Proposal
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.paper.closed_form import closed_form

    session = case_session()
    first = session.traces[0]
    assert first.current is not None
    renamed = dataclasses.replace(first, name="run: 12 V")
    session = dataclasses.replace(session, traces=(renamed, *session.traces[1:]))
    model = build_model(session, closed_form(session))
    preds = [(np.asarray(tr.current), np.asarray(tr.speed)) for tr in session.traces]
    fit = SimpleNamespace(values=dict(session.truth))
    start = Finding(Check.STEP_START, ChannelId("run: 12 V", "current"), Severity.FAIL,
                    "x9 elsewhere", "the model misses the start of the voltage steps")
    said, proposals = diagnose(model, fit, preds, [start])
    assert Proposal("dead_time", "run: 12 V") in proposals, said
    assert Proposal("current_lag") in proposals, said
    assert any(line.startswith("run: 12 V: the model misses the start") for line in said)


def test_a_quantised_levels_mean_is_read_with_the_quantisers_bias():
    """A settled speed read through a quantiser whose noise does not dither it: the mean
    of 500 readings sits off the true speed by the quantiser's bias, which depends on
    where the speed lies in the lattice and does not average away; the level's standard
    error carries it, so the miss stays within the two-sided 1 % band about as often as
    it should (it was judged on the noise over √n alone and rejected a fitting model)."""
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.plausibility import _end_speed_se

    rng = np.random.default_rng(7)
    q, n, misses, trials, ses = 4.73, 500, 0, 300, []
    for _ in range(trials):
        true = 500.0 + rng.uniform(0, q)
        readings = q * np.round((true + 0.25 * q * rng.standard_normal(n)) / q)
        tr = SimpleNamespace(name="t", speed=readings, speed_logged=True)
        se = _end_speed_se(tr, n, {ChannelId("t", "speed"): float(np.std(readings))}, {}, {})
        misses += abs(np.mean(readings) - true) / se > 2.576
        ses.append(se)
    assert misses / trials < 0.03
    assert max(ses) < q / 4  # the bias bound q/(π√2) and the noise over √n, not a blanket


def test_the_models_no_load_speed_carries_the_fits_uncertainty():
    """The Laplace sd of the model's no-load speed (central differences in θ) is the
    spread of the no-load speed over draws from the Laplace approximation."""
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.plausibility import _no_load_speed, _no_load_speed_sd
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.paper.closed_form import closed_form

    session = case_session()
    model = build_model(session, closed_form(session))
    theta = np.asarray(model.theta(dict(session.truth)))
    sd = np.full(theta.size, 0.01)
    cov = np.diag(sd**2)
    cov[2, 3] = cov[3, 2] = 0.5 * 1e-4  # K and B partly correlated
    fit = SimpleNamespace(theta=theta, cov_log=cov)
    draws = np.random.default_rng(1).multivariate_normal(theta, cov, 4000)
    names = list(model.names)
    w = [_no_load_speed(model, dict(zip(names, model.registry.to_values(d), strict=True)),
                        12.0) for d in draws]
    assert _no_load_speed_sd(model, fit, 12.0) == pytest.approx(np.std(w), rel=0.05)
    assert _no_load_speed_sd(model, SimpleNamespace(values={}), 12.0) == 0.0


def test_a_steady_miss_proposes_the_calibration_of_a_sensor_the_traces_log():
    """Steady readings missed beyond their scatter point at the traces' sensor of that
    signal; with no trace logging the signal there is no such sensor to calibrate, and a
    current missed so proposes Coulomb friction."""
    import dataclasses
    from types import SimpleNamespace

    from pmdc_bayes.inference.adequacy.diagnosis import diagnose
    from pmdc_bayes.inference.adequacy.proposals import COULOMB, Proposal
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.io.channel import STEADY
    from pmdc_bayes.paper.closed_form import closed_form

    def proposals(session, signal):
        model = build_model(session, closed_form(session))
        preds = [(np.asarray(tr.current) if tr.current is not None else np.zeros(tr.n),
                  np.asarray(tr.speed)) for tr in session.traces]
        miss = Finding(Check.STEADY_MISS, ChannelId(STEADY, signal), Severity.FAIL,
                       "6 % of the largest reading", "the steady readings miss")
        return diagnose(model, SimpleNamespace(values=dict(session.truth)), preds, [miss])[1]

    session = case_session()
    assert {Proposal("speed_gain"), Proposal("speed_offset")} <= set(proposals(session, "speed"))
    with_current = set(proposals(session, "current"))
    assert {Proposal("current_gain"), Proposal(COULOMB)} <= with_current
    no_current = dataclasses.replace(
        session, traces=tuple(dataclasses.replace(tr, current=None) for tr in session.traces))
    without = set(proposals(no_current, "current"))
    assert Proposal(COULOMB) in without
    assert not {Proposal("current_gain"), Proposal("current_offset")} & without
