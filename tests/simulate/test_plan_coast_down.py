"""Plans with coast-down traces and known loads: the coast-down drawn exactly on an ideal
plan and by LSODA on a rig (through the rig's speed sensor: lag, gain, offset), a known
drag felt by both simulators and declared in the session written, errors in one line,
and through the command line the speed sensor's lag and offset recovered from a session
whose coast-down is read through them."""

import copy
import json
import tomllib

import numpy as np
import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Drag
from pmdc_bayes.physics import motor
from pmdc_bayes.simulate.coast import ideal_coast_down, rig_coast_down
from pmdc_bayes.simulate.plan import check_plan
from pmdc_bayes.simulate.rig import RigSpec, rig_trace
from pmdc_bayes.simulate.session import sample_trace, simulate_session, true_trace

TRUTH = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5, "Tc": 1e-3}

PLAN_TOML = """\
seed = 7
[motor]
name = "rig with a run-down"
friction = "coulomb"
[truth]
Ra = 2.0
La = 2e-3
K = 0.05
B = 2e-5
J = 2e-5
Tc = 1e-3
[bench.Ra]
sd = 0.05
unit = "ohm"
[[steady_table]]
name = "steady"
voltages = [3.0, 6.0, 9.0, 12.0]
speed_sd = 0.5
[[trace]]
name = "step_12v"
kind = "step"
duration = 0.5
rate = 1000.0
voltage = [[0.0, 0.0], [0.05, 12.0]]
record_current = false
speed_noise = 0.5
[[trace]]
name = "fan_9v"
kind = "step"
duration = 0.5
rate = 1000.0
voltage = [[0.0, 0.0], [0.05, 9.0]]
record_current = false
speed_noise = 0.5
drag = { constant = 2e-3, viscous = 1e-5 }
[[trace]]
name = "run_down"
kind = "coast-down"
duration = 1.0
rate = 500.0
initial = { speed = 220.0 }
speed_unit = "rpm"
speed_noise = 0.5
[rig]
speed_lag = 0.004
speed_offset = 2.0
"""
PLAN = tomllib.loads(PLAN_TOML)


def _spec(name, rig=True):
    plan = copy.deepcopy(PLAN)
    if not rig:
        plan.pop("rig")
    return {tr.name: tr for tr in check_plan(plan).traces}[name]


@pytest.mark.parametrize("tc", [0.0, 1e-3, 6e-3])  # 6e-3: it stops within the record
def test_a_coast_down_on_an_empty_rig_is_the_exact_run_down(tc):
    truth = {**TRUTH, "Tc": tc}
    spec = _spec("run_down")
    exact = motor.coast_down(truth["B"], truth["J"], 220.0, spec.time, tc)
    drawn = sample_trace(truth, spec, seed=0)["speed"]
    assert np.max(np.abs(drawn - exact)) < 5 * 0.5  # the plan's noise (sd 0.5) only
    np.testing.assert_allclose(ideal_coast_down(truth, spec)["speed"], exact, rtol=1e-12)
    lsoda = rig_coast_down(truth, RigSpec(), spec)["speed"]
    np.testing.assert_allclose(lsoda, exact, rtol=1e-6, atol=1e-6 * 220.0)
    if tc == 6e-3:
        assert exact[-1] == 0.0 and lsoda[-1] == 0.0  # stopped and held


def test_a_coast_down_is_read_through_the_rigs_speed_sensor():
    spec = _spec("run_down")
    plain = rig_coast_down(TRUTH, RigSpec(), spec)["speed"]
    lagged = rig_coast_down(TRUTH, RigSpec(speed_lag=0.01), spec)["speed"]
    assert lagged[0] == plain[0] and np.all(lagged[5:] > plain[5:])  # behind a falling speed
    # a first-order lag of a decay of time constant J/B settles at a constant ratio
    tail = slice(200, None)
    assert np.allclose(lagged[tail] - plain[tail], 0.01 * -np.gradient(plain, spec.time)[tail],
                       rtol=0.05)
    read = rig_coast_down(TRUTH, RigSpec(speed_gain=1.1, speed_offset=2.0), spec)["speed"]
    np.testing.assert_allclose(read, 1.1 * plain + 2.0, rtol=1e-12)


def test_a_known_drag_is_felt_by_both_simulators_and_declared(tmp_path):
    spec = _spec("fan_9v", rig=False)
    _, _, w_ideal = true_trace(TRUTH, spec)
    rig = rig_trace(TRUTH, RigSpec(), spec)["speed"]
    np.testing.assert_allclose(rig, w_ideal, rtol=1e-3, atol=1e-3 * w_ideal.max())
    free = copy.deepcopy(spec.__dict__)
    free["drag"] = Drag()
    _, _, w_free = true_trace(TRUTH, type(spec)(**free))
    # the steady speed with the load: (K·V − Ra·(Tc + c)) / (Ra·(B + b) + K²)
    loaded = (0.05 * 9.0 - 2.0 * (1e-3 + 2e-3)) / (2.0 * (2e-5 + 1e-5) + 0.05**2)
    free_speed = (0.05 * 9.0 - 2.0 * 1e-3) / (2.0 * 2e-5 + 0.05**2)
    assert w_ideal[-1] == pytest.approx(loaded, rel=2e-4)
    assert w_free[-1] == pytest.approx(free_speed, rel=2e-4)  # 1.7 % faster
    root = simulate_session(PLAN, tmp_path / "s")
    s = load_session(root)
    assert s.trace("fan_9v").drag == Drag(2e-3, 1e-5) and s.trace("step_12v").drag == Drag()
    (cd,) = s.coast_downs
    assert cd.name == "run_down" and cd.current is None
    truth = json.loads((root / "truth.json").read_text())
    assert truth["initial_speed_run_down"] == 220.0 and truth["speed_lag"] == 0.004
    assert "dead_time_run_down" not in truth  # a coast-down has no input to delay


@pytest.mark.parametrize(("mutate", "where", "what"), [
    (lambda t: t.update(voltage=[[0.0, 12.0]]), "run_down", "voltage"),
    (lambda t: t.pop("initial"), "initial", "missing"),
    (lambda t: t.update(initial="steady"), "initial", "initial = { speed"),
    (lambda t: t.update(initial={"speed": 200.0, "current": 0.1}), "current", "unknown key"),
])
def test_coast_down_plan_errors_are_one_line(mutate, where, what):
    plan = copy.deepcopy(PLAN)
    mutate(plan["trace"][2])
    with pytest.raises(SessionError) as info:
        check_plan(plan, "plan.toml")
    text = str(info.value)
    assert where in text and what in text and "\n" not in text, text


@pytest.mark.compiles
def test_through_the_cli_a_coast_down_read_through_the_sensor_gives_its_lag_and_offset(
        tmp_path, pmdc):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN_TOML)
    proc = pmdc("simulate", plan, "--out", tmp_path / "s", timeout=900)
    assert proc.returncode == 0, proc.stderr
    proc = pmdc("fit", tmp_path / "s", "--no-mcmc", "--add", "speed-lag", "--add",
               "speed-offset", "--out", tmp_path / "fit", timeout=900)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    for name in ("Ra", "K", "B", "J", "Tc", "speed_lag", "speed_offset",
                 "initial_speed_run_down"):
        p = summary["parameters"][name]
        assert abs(p["map"] - truth[name]) <= 3 * p["map_sd"], (name, p, truth[name])
