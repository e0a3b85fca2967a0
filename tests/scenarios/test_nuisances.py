"""Rig non-idealities fitted as parameters, end to end through the command line: a
session whose responses lag the logged command is rejected by the ideal model with
the diagnosis "dead time", and fitted with ``--add dead-time`` it passes, with the
dead time recovered and sampled."""

import json

import pytest
from conftest import SMALL_MOTOR, plan, plan_toml, step, sweep

from pmdc_bayes.simulate.session import simulate_session

DELAY = 3e-3

_STEP = {"duration": 0.12, "rate": 5000.0, "speed_noise": 0.05, "current_noise": 0.002,
         "delay": DELAY}
PLAN = plan_toml(plan(
    seed=5, motor="delayed motor", truth=SMALL_MOTOR,
    bench={"Ra": (0.06, "ohm"), "La": (0.2, "mH")},
    steady=(sweep([4.0, 8.0, 12.0], 0.2, 0.001),),
    traces=(step("step_12v", 12.0, **_STEP), step("step_6v", 6.0, **_STEP))))


def _fit(pmdc, session, out, *extra):
    return pmdc("fit", session, "--out", out, "--seed", "1", *extra, timeout=1500)


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    root = tmp_path_factory.mktemp("delayed")
    (root / "plan.toml").write_text(PLAN)
    return simulate_session(root / "plan.toml", root / "session")


@pytest.mark.compiles
def test_the_ideal_model_is_rejected_and_told_to_add_a_dead_time(session, tmp_path, pmdc):
    proc = _fit(pmdc, session, tmp_path / "ideal", "--no-mcmc", "--no-search")
    assert proc.returncode == 3, proc.stderr
    assert proc.stdout.startswith("MODEL INADEQUATE")
    assert "dead time" in proc.stdout and "--add dead-time" in proc.stdout


@pytest.mark.compiles
def test_with_the_dead_time_fitted_the_model_passes_and_recovers_it(session, tmp_path, pmdc):
    out = tmp_path / "delayed"
    proc = _fit(pmdc, session, out, "--add", "dead-time")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    for name in ("dead_time_step_12v", "dead_time_step_6v"):
        row = summary["parameters"][name]
        assert row["unit"] == "s" and row["closed_form"] is None
        assert abs(row["mean"] - DELAY) < 3 * row["sd"] + 1e-5, row
        assert row["hdi_3%"] < DELAY < row["hdi_97%"] or abs(row["mean"] - DELAY) < 1e-5
        assert row["r_hat"] < 1.01
    truth = json.loads((session / "truth.json").read_text())
    for name in ("Ra", "K", "B", "J"):
        row = summary["parameters"][name]
        assert abs(row["mean"] - truth[name]) < 4 * row["sd"], (name, row, truth[name])
    assert (out / "posterior.nc").exists() and (out / "report.html").exists()
    assert "dead_time_step_12v" in (out / "report.md").read_text()


@pytest.mark.compiles
def test_compare_picks_the_dead_time_and_runs_it(session, tmp_path, pmdc):
    out = tmp_path / "compared"
    proc = _fit(pmdc, session, out, "--compare", "--no-mcmc")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.startswith("Model adequate")
    assert "The model, found by a search (--compare):" in proc.stdout
    assert "Chosen: dead time" in proc.stdout
    # the rig's parameters are named in words under the table
    assert "The rig's parameters: dead_time" in proc.stdout
    summary = json.loads((out / "summary.json").read_text())
    sel = summary["model_selection"]
    assert sel["compare"] is True
    assert sel["recommended"].startswith("dead time") and sel["nuisances"] == ["dead_time"]
    verdicts = {r["name"]: r["verdict"] for r in sel["candidates"]}
    assert verdicts["ideal"] == "inadequate" and verdicts[sel["recommended"]] == "adequate"
    assert any(n.startswith("dead_time") for n in summary["parameters"])
    assert "Model choice" in (out / "report.md").read_text()


def test_compare_and_add_together_are_bad_input(session, tmp_path, pmdc):
    proc = _fit(pmdc, session, tmp_path / "x", "--compare", "--add", "dead-time")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "--compare" in proc.stderr
    assert not (tmp_path / "x").exists()
