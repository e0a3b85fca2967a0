"""Encoder edges of a rotor that turns back: the bench simulator's edges at every count
boundary crossed, either way, with their direction, written as the session format's
direction column; through the command line, a plan's reversing edge trace fits (the
rise check estimates the model's speed from its angle over the data's own window)."""

import json
import tomllib

import numpy as np
import pytest
from conftest import SMALL_MOTOR, plan, plan_toml, sweep

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate._encoder import edge_times
from pmdc_bayes.simulate.session import simulate_session

PLAN_TOML = plan_toml(plan(
    seed=3, motor="reversing encoder rig", friction="coulomb", truth={**SMALL_MOTOR, "Tc": 1e-3},
    bench={"Ra": (0.06, "ohm"), "La": (0.1, "mH")}, rig={},
    steady=(sweep([4.0, 8.0, 12.0], 0.3, 0.0003, name="steady"),),
    traces=({"name": "rev", "kind": "step", "duration": 0.25, "rate": 2000.0,
             "voltage": [[0.0, 0.0], [0.01, 12.0], [0.08, -12.0]], "record_current": False,
             "encoder": {"counts_per_rev": 100, "output": "edges"}},)))


def test_edges_both_ways_lie_on_the_boundaries_crossed():
    q = 1.0
    t = np.linspace(0.0, 1.0, 100_001)
    theta = 3.5 * np.sin(np.pi * t)  # up to 3.5 counts and back to 0
    times, angles, forward = edge_times(t, theta, q, 1e-6)
    assert forward.tolist() == [1, 1, 1, 0, 0, 0]
    assert angles.tolist() == [1.0, 2.0, 3.0, 3.0, 2.0, 1.0]  # a boundary left by, back
    expected = np.concatenate([np.arcsin([1 / 3.5, 2 / 3.5, 3 / 3.5]) / np.pi,
                               1.0 - np.arcsin([3 / 3.5, 2 / 3.5, 1 / 3.5]) / np.pi])
    np.testing.assert_allclose(times, expected, atol=2e-6)
    # two edges in one fine interval both count, one tick apart at least
    times, angles, forward = edge_times(np.array([0.0, 1e-7, 1.0]), np.array([0.0, 2.5, 2.5]),
                                        q, 1e-6)
    assert angles.tolist() == [1.0, 2.0] and np.all(np.diff(times) >= 1e-6 - 1e-15)


def test_a_plans_reversing_edge_trace_carries_its_directions(tmp_path):
    root = simulate_session(tomllib.loads(PLAN_TOML), tmp_path / "s")
    header = (root / "rev.csv").read_text().splitlines()[0]
    assert header == "t,dir"
    tr = load_session(root).trace("rev")
    counts = tr.position[1:] / (2 * np.pi / 100)
    assert np.allclose(counts, np.rint(counts))
    back = np.diff(counts) < 0
    assert 50 < back.sum() < back.size - 50  # many edges each way
    assert counts.max() > counts[-1] + 50  # forward, then well back past it


@pytest.mark.compiles
def test_through_the_cli_a_reversing_edge_plan_fits_and_recovers_the_motor(tmp_path, pmdc):
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN_TOML)
    proc = pmdc("simulate", plan, "--out", tmp_path / "s", timeout=900)
    assert proc.returncode == 0, proc.stderr
    proc = pmdc("fit", tmp_path / "s", "--no-mcmc", "--out", tmp_path / "fit", timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    for name in ("Ra", "La", "K", "B", "J", "Tc"):
        p = summary["parameters"][name]
        assert abs(p["map"] - truth[name]) <= 3 * p["map_sd"], (name, p, truth[name])
