"""Simulation plans with a ``[rig]``: the rig's non-idealities drawn by the independent
bench simulator on any plan trace (encoder counts, edges, lags, a sensor delay), the
rig's truths in ``truth.json`` under the fit's names, errors in one line, and through the
command line: the ideal motor rejected on such a session, and every rig parameter
recovered once the session declares the rig's model."""

import copy
import json

import numpy as np
import pytest
from conftest import SMALL_MOTOR, plan, plan_toml, sweep

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.bench import BenchMotor, StepSpec, bench_session, steady_point
from pmdc_bayes.simulate.plan import check_plan
from pmdc_bayes.simulate.rig import RigSpec, rig_steady, rig_trace
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {**SMALL_MOTOR, "Tc": 1e-3}


def _trace(name, volts, **extra):
    return {"name": name, "kind": "step", "duration": 0.15, "rate": 2000.0,
            "voltage": [[0.0, 0.0], [0.01, volts]], **extra}


PLAN = plan(
    seed=11, motor="rig motor", friction="coulomb", truth=TRUTH, bench={"Ra": (0.06, "ohm")},
    rig={"dead_time": 0.002, "voltage_drop": 0.8, "current_limit": 2.0,
         "unknown_load": {"step_9v": {"viscous": 1e-4}}},
    steady=(sweep([3.0, 6.0, 9.0, 12.0], 0.3, 0.0003, name="steady"),),
    traces=(_trace("step_12v", 12.0, record_current=False,
                   encoder={"counts_per_rev": 400, "output": "position"}),
            _trace("step_6v", 6.0, record_current=False,
                   encoder={"counts_per_rev": 400, "output": "edges"}),
            _trace("step_9v", 9.0, speed_noise=0.5, current_noise=0.01)))
PLAN_TOML = plan_toml(PLAN)
MODEL = ('\n[model]\ndead_time = "shared"\nvoltage_drop = true\ncurrent_limit = true\n'
         'unknown_load = { step_9v = "viscous" }\n')


def test_a_rig_session_holds_the_rigs_truth_and_its_encoder_traces(tmp_path):
    root = simulate_session(PLAN, tmp_path / "s")
    truth = json.loads((root / "truth.json").read_text())
    assert truth["Vdrop"] == 0.8 and truth["Imax"] == 2.0 and truth["dead_time"] == 0.002
    assert truth["dead_time_step_12v"] == 0.002 and truth["drag_step_9v"] == 1e-4
    s = load_session(root)
    by = {tr.name: tr for tr in s.traces}
    q = 2 * np.pi / 400
    assert by["step_12v"].current is None and by["step_12v"].encoder_step == pytest.approx(q)
    counts = by["step_12v"].position / q
    assert np.allclose(counts, np.rint(counts)) and np.all(np.diff(counts) >= 0)
    edges = np.diff(by["step_6v"].time[1:])  # one row per edge: as irregular as the motion
    assert np.all(edges > 0) and edges.max() > 3 * edges.min()
    assert by["step_9v"].current is not None
    # the session declares only what a user knows: the commanded step
    assert by["step_9v"].voltage.times.tolist() == [0.0, 0.01]
    assert "rig" in (root / "session.toml").read_text().splitlines()[2]


def test_same_plan_same_bytes(tmp_path):
    a, b = simulate_session(PLAN, tmp_path / "a"), simulate_session(PLAN, tmp_path / "b")
    for f in sorted(p.name for p in a.iterdir()):
        assert (a / f).read_bytes() == (b / f).read_bytes(), f


def test_an_empty_rig_is_the_ideal_motor_by_the_bench_simulator():
    """The rig simulator (LSODA) and the package's exact model agree on an ideal rig."""
    from pmdc_bayes.simulate.session import true_steady, true_trace

    spec = check_plan({**copy.deepcopy(PLAN), "rig": {},
                       "trace": [_trace("step", 12.0, initial="rest")]}).traces[0]
    out = rig_trace(TRUTH, RigSpec(), spec)
    _, ia, w = true_trace(TRUTH, spec)
    assert np.max(np.abs(out["speed"] - w)) < 1e-3 * np.max(w)
    assert np.max(np.abs(out["current"] - ia)) < 1e-3 * np.max(np.abs(ia))
    ia_r, w_r = rig_steady(TRUTH, RigSpec(), [6.0, 12.0], [0.0, 0.0])
    ia_t, w_t = true_steady(TRUTH, np.array([6.0, 12.0]))
    assert np.allclose(w_r, w_t, rtol=1e-9) and np.allclose(ia_r, ia_t, rtol=1e-9)


def test_a_rig_step_matches_the_bench_simulators_own():
    """A plan step on a rig is the bench simulator's step (dead time, drop, limit, brake)."""
    rig = RigSpec(dead_time=0.002, voltage_drop=0.8, current_limit=2.0,
                  unknown_load=(("step", 0.0, 1e-4),))
    spec = check_plan({**copy.deepcopy(PLAN), "rig": {},
                       "trace": [_trace("step", 9.0, speed_noise=0.0)]}).traces[0]
    ours = rig_trace(TRUTH, rig, spec)
    motor = BenchMotor(**TRUTH, dead_time=0.002, voltage_drop=0.8, current_limit=2.0,
                       extra_load={"step": (0.0, 1e-4)}, speed_noise=0.0, current_noise=0.0)
    theirs = bench_session(motor, [StepSpec("step", 9.0, 0.15, 5e-4, t_step=0.01)]).traces[0]
    assert np.allclose(ours["speed"], theirs.speed, rtol=1e-6, atol=1e-6 * theirs.speed.max())
    ia, w = steady_point(motor, 9.0, drag=(0.0, 1e-4))
    assert ours["speed"][-1] == pytest.approx(w, rel=2e-3)  # the brake is felt


def test_a_sensor_lag_and_delay_lag_the_readings():
    spec = check_plan({**copy.deepcopy(PLAN), "rig": {},
                       "trace": [_trace("step", 12.0, delay=0.004)]}).traces[0]
    plain = rig_trace(TRUTH, RigSpec(), spec)
    lagged = rig_trace(TRUTH, RigSpec(speed_lag=0.01), spec)
    assert np.all(lagged["speed"][40:] < plain["speed"][40:])
    assert np.all(plain["speed"][spec.time <= 0.014] == 0.0)  # the step's response, delayed


@pytest.mark.parametrize(("mutate", "where", "what"), [
    (lambda p: p["rig"].update(dead_tme=0.1), "rig", "dead_tme"),
    (lambda p: p["rig"].update(current_limit=-1.0), "rig.current_limit", "positive"),
    (lambda p: p["rig"]["unknown_load"].update(nope={"viscous": 1.0}), "nope", "names no trace"),
    (lambda p: p["trace"][0]["encoder"].update(counts_per_rev=0), "counts_per_rev", ">= 1"),
    (lambda p: p["trace"][0]["encoder"].update(output="pulses"), "output", "pulses"),
    (lambda p: p["trace"][1].update(initial="steady"), "encoder", "starts at rest"),
    (lambda p: p.pop("rig"), "trace", "add a [rig] table"),
])
def test_rig_plan_errors_are_one_line(mutate, where, what):
    plan = copy.deepcopy(PLAN)
    mutate(plan)
    with pytest.raises(SessionError) as info:
        check_plan(plan, "plan.toml")
    text = str(info.value)
    assert where in text and what in text and "\n" not in text, text




@pytest.mark.compiles
def test_through_the_cli_the_ideal_motor_is_rejected_and_the_rig_recovered(tmp_path, pmdc):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN_TOML)
    proc = pmdc("simulate", plan, "--out", tmp_path / "s", timeout=900)
    assert proc.returncode == 0, proc.stderr
    ideal = pmdc("fit", tmp_path / "s", "--no-mcmc", "--no-search", "--out", tmp_path / "ideal",
                 timeout=900)
    assert ideal.returncode == 3, ideal.stderr
    assert "current-limit" in ideal.stderr
    declared = tmp_path / "declared"
    declared.mkdir()
    for f in (tmp_path / "s").iterdir():
        (declared / f.name).write_bytes(f.read_bytes())
    (declared / "session.toml").write_text((declared / "session.toml").read_text() + MODEL)
    proc = pmdc("fit", declared, "--no-mcmc", "--out", tmp_path / "fit", timeout=900)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    truth = json.loads((declared / "truth.json").read_text())
    for name in ("Ra", "K", "B", "J", "Tc", "Vdrop", "Imax", "dead_time", "drag_step_9v"):
        p = summary["parameters"][name]
        assert abs(p["map"] - truth[name]) <= 3 * p["map_sd"], (name, p, truth[name])


def _rig_plan(rig: str, model: str, traces: str, bench_la: bool = True) -> tuple[str, str]:
    bench = {"Ra": (0.06, "ohm"), **({"La": (0.1, "mH")} if bench_la else {})}
    head = plan_toml(plan(seed=11, motor="rig motor", friction="coulomb", truth=TRUTH,
                          bench=bench))
    steady = plan_toml({"steady_table": PLAN["steady_table"]})
    return head + rig + steady + traces, model


ANALOGUE = "".join(f"""[[trace]]
name = "step_{v:g}v"
kind = "step"
duration = 0.15
rate = 2000.0
voltage = [[0.0, 0.0], [0.01, {v}]]
speed_noise = 0.5
current_noise = 0.005
""" for v in (12.0, 6.0))


@pytest.mark.compiles
@pytest.mark.parametrize(("rig", "model", "names"), [
    ('[rig]\nspeed_offset = 3.0\ncurrent_gain = 1.06\ncurrent_offset = 0.02\n',
     "[model]\nspeed_offset = true\ncurrent_gain = true\ncurrent_offset = true\n",
     ("speed_offset", "current_gain", "current_offset")),
    ('[rig]\ncurrent_limit = 1.5\nunknown_load = { step_6v = { constant = 0.004 } }\n',
     '[model]\ncurrent_limit = 1.5\nunknown_load = { step_6v = "constant" }\n',
     ("Imax", "load_step_6v")),
])
def test_sensor_calibrations_a_set_limit_and_a_constant_brake_are_recovered(
        tmp_path, rig, model, names, pmdc):
    """Through the CLI: the ideal motor rejected, the declared model adequate, and each
    rig parameter and the motor's within 3 sd of the truth (a current gain is told from
    Ra only with a bench La as well as a bench Ra)."""
    plan_text, model_text = _rig_plan(rig, model, ANALOGUE)
    plan = tmp_path / "plan.toml"
    plan.write_text(plan_text)
    assert pmdc("simulate", plan, "--out", tmp_path / "s", timeout=900).returncode == 0
    ideal = pmdc("fit", tmp_path / "s", "--no-mcmc", "--no-search", "--out", tmp_path / "ideal",
                 timeout=900)
    assert ideal.returncode == 3, ideal.stdout + ideal.stderr
    declared = tmp_path / "declared"
    declared.mkdir()
    for f in (tmp_path / "s").iterdir():
        (declared / f.name).write_bytes(f.read_bytes())
    (declared / "session.toml").write_text((declared / "session.toml").read_text() + "\n"
                                           + model_text)
    proc = pmdc("fit", declared, "--no-mcmc", "--out", tmp_path / "fit", timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    truth = json.loads((declared / "truth.json").read_text())
    for name in ("Ra", "K", "B", "J", *names):
        p = summary["parameters"][name]
        assert abs(p["map"] - truth[name]) <= 3 * p["map_sd"], (name, p, truth[name])
