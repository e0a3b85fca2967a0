"""A driver's dead zone, a different width forward and in reverse: the equation, the
independent rig simulator's, the model-free asymmetry the diagnosis proposes it on, and
the fit and the search on steps both ways drawn by that simulator (LSODA, not the
package's model)."""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest
from conftest import SMALL_MOTOR, plan

from pmdc_bayes.inference.adequacy.diagnosis_levels import _asymmetry_rule
from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.levels import direction_intercepts
from pmdc_bayes.inference.model.nuisances import nuisance_specs
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.physics.motor import driver_output
from pmdc_bayes.search import ADD_MARGIN, search_model
from pmdc_bayes.selection import laplace_log_evidence
from pmdc_bayes.simulate.rig import RigSpec, rig_steady
from pmdc_bayes.simulate.session import simulate_session

TRUTH = dict(Ra=2.0, La=2e-3, K=0.05, B=2e-5, J=2e-5, Tc=0.0)

def _plan(fwd: float, rev: float, current: bool) -> dict:
    return plan(seed=7, motor="driver with a dead zone", truth=SMALL_MOTOR,
                bench={"Ra": (0.05, "ohm"), "La": (0.1, "mH")},
                rig={"dead_zone_forward": fwd, "dead_zone_reverse": rev},
                traces=({"name": "both_ways", "kind": "step", "duration": 0.9, "rate": 2000.0,
                         "voltage": [[0.0, 0.0], [0.01, 3.0], [0.15, 8.0], [0.3, 0.0],
                                     [0.45, -3.0], [0.6, -8.0], [0.75, 0.0]],
                         "record_current": current, "speed_noise": 0.3,
                         "current_noise": 0.005},))


def _session(tmp_path, fwd, rev, current=True):
    return load_session(simulate_session(_plan(fwd, rev, current), tmp_path / "s"))


@pytest.mark.parametrize("xp", [np, jnp])
def test_driver_output_removes_the_zone_each_way_and_puts_out_nothing_within(xp):
    va = xp.asarray([-10.0, -1.0, -0.5, 0.0, 0.3, 0.8, 10.0])
    out = np.asarray(driver_output(va, 0.5, 0.7))
    np.testing.assert_allclose(out, [-9.3, -0.3, 0.0, 0.0, 0.0, 0.3, 9.5], atol=1e-12)
    # a negative width (a driver adding to its command) never turns 0 V into a voltage
    boost = np.asarray(driver_output(va, -0.2, -0.4))
    np.testing.assert_allclose(boost, [-10.4, -1.4, -0.9, 0.0, 0.5, 1.0, 10.2], atol=1e-12)


def test_the_rig_simulator_drives_the_motor_with_the_command_less_the_zone():
    rig = RigSpec(dead_zone_forward=0.6, dead_zone_reverse=1.0)
    _, w = rig_steady(TRUTH, rig, np.array([6.0, 0.5, -6.0, -0.9]), np.zeros(4))
    _, w_ideal = rig_steady(TRUTH, RigSpec(), np.array([5.4, 0.0, -5.0, 0.0]), np.zeros(4))
    np.testing.assert_allclose(w, w_ideal, rtol=1e-12)
    assert w[1] == 0.0 and w[3] == 0.0


def test_only_the_directions_commanded_get_a_width(tmp_path):
    session = _session(tmp_path, 0.6, 1.0)
    both = dataclasses.replace(session, nuisances=("dead_zone",))
    assert [s.name for s in nuisance_specs(both)] == ["Vdz_fwd", "Vdz_rev"]
    forward = dataclasses.replace(both, traces=tuple(
        dataclasses.replace(tr, voltage=dataclasses.replace(tr.voltage,
            values=np.abs(tr.voltage.values))) for tr in both.traces))
    assert [s.name for s in nuisance_specs(forward)] == ["Vdz_fwd"]


def test_the_asymmetry_is_proposed_on_a_dead_zone_and_not_on_a_symmetric_rig(tmp_path):
    zone = _session(tmp_path / "zone", 0.6, 1.0, current=False)
    icpt = direction_intercepts(zone)
    for sign, width in ((1, 0.6), (-1, 1.0)):
        assert abs(icpt[sign]["voltage"] - width) < 4 * icpt[sign]["se"] + 0.01
    [sentence] = _asymmetry_rule(zone)
    assert [p.nuisance for p in sentence.proposals] == ["dead_zone"]
    clean = _session(tmp_path / "clean", 0.0, 0.0, current=False)
    assert _asymmetry_rule(clean) == []
    same = _session(tmp_path / "same", 0.8, 0.8, current=False)
    assert _asymmetry_rule(same) == []  # the same both ways: a drop's pattern, not this


@pytest.mark.parametrize("current", [True, pytest.param(False, marks=pytest.mark.compiles)])
def test_the_dead_zone_is_fitted_and_preferred_to_a_drop(tmp_path, current):
    session = _session(tmp_path, 0.6, 1.0, current=current)
    verdicts, fits, log_z = {}, {}, {}
    for nuisances in ((), ("voltage_drop",), ("dead_zone",)):
        s = dataclasses.replace(session, nuisances=nuisances)
        cf = fit_seed(s)
        model = build_model(s, cf)
        fits[nuisances] = fit_map(model)
        verdicts[nuisances] = assess(model, fits[nuisances], cf).verdict
        log_z[nuisances] = laplace_log_evidence(model, fits[nuisances])
    assert verdicts[()] == "inadequate" and verdicts[("dead_zone",)] == "adequate"
    if current:  # the logged current shows the braking a drop would oppose
        assert verdicts[("voltage_drop",)] == "inadequate"
    assert log_z[("dead_zone",)] > log_z[("voltage_drop",)] + ADD_MARGIN
    fit = fits[("dead_zone",)]
    for name, truth in (("Vdz_fwd", 0.6), ("Vdz_rev", 1.0), ("K", 0.05), ("Ra", 2.0)):
        assert abs(fit.values[name] - truth) < 3 * fit.sd[name], (name, fit.values[name])


@pytest.mark.compiles
def test_the_search_finds_the_dead_zone_on_its_own(tmp_path):
    record = search_model(_session(tmp_path, 0.6, 1.0, current=False))
    assert record["terms"] == ["dead_zone"], record["candidates"]
    chosen = [c for c in record["candidates"] if c["decision"] == "chosen"]
    assert [c["verdict"] for c in chosen] == ["adequate"], chosen


def test_a_coarse_encoder_staircase_reads_no_asymmetry_into_its_resolution(tmp_path):
    """Short plateaus of a coarse encoder's counts: the speed a plateau's last readings
    differentiate to is the same few counts every sample, so its readings carry no
    noise to weigh the level by; the resolution (one count over the window) does, and
    a level the counts fix only coarsely neither decides the line nor breaks it."""
    plan = _plan(0.0, 0.0, False)
    tr = plan["trace"][0]
    tr.update(rate=1000.0, speed_noise=0.0, encoder={"counts_per_rev": 16,
                                                     "output": "position"})
    tr["voltage"] = [[0.0, 0.0], [0.01, 3.0], [0.04, 8.0], [0.07, 5.0], [0.1, -3.0],
                     [0.13, -8.0], [0.16, -5.0]]
    tr["duration"] = 0.19
    session = load_session(simulate_session(plan, tmp_path / "s"))
    [enc] = session.traces
    assert not enc.speed_logged and enc.encoder_step > 0
    icpt = direction_intercepts(session)
    for fit in icpt.values():
        assert np.isfinite(fit["voltage"]) and fit["se"] > 0
        assert abs(fit["voltage"]) < 4 * fit["se"] + 0.05
    assert _asymmetry_rule(session) == []


@pytest.mark.parametrize("rho", [0.0, 0.6, 0.9])
def test_a_levels_standard_error_holds_when_a_filter_colours_the_readings(rho):
    """The error of a settled level's mean, over 300 repeats of AR(1) readings: what
    ``level_se`` gives is within 20 % of the means' own scatter (read as white, a
    filter at ρ = 0.9 made it 16 times too small, and the two directions' intercepts
    differ by 'many standard errors' on a symmetric driver)."""
    from pmdc_bayes.inference.model.levels import level_se

    rng = np.random.default_rng(7)
    n, means, ses = 300, [], []
    for _ in range(300):
        e = rng.standard_normal(2000)
        x = np.empty_like(e)
        x[0] = e[0] / np.sqrt(1.0 - rho**2)
        for t in range(1, e.size):
            x[t] = rho * x[t - 1] + e[t]
        means.append(np.mean(x[-n:]))
        ses.append(level_se(50.0 + x, n))
    assert np.median(ses) == pytest.approx(np.std(means), rel=0.2)


def test_a_levels_standard_error_is_not_coloured_by_a_drift_or_a_quantiser():
    """White readings on a slow drift (what `settled` lets pass) and a quantised level
    that crosses one step: the white error, not an AR(1) one from the drift or the
    step read as correlation (which made it ~170 times too large)."""
    from pmdc_bayes.inference.model.levels import level_se

    rng = np.random.default_rng(3)
    drift = 100.0 + np.linspace(0.0, 0.5, 300) + rng.standard_normal(300)
    assert level_se(drift, 300) == pytest.approx(1.0 / np.sqrt(300), rel=0.2)
    stepped = np.r_[np.full(150, 10.0), np.full(150, 11.0)]
    assert level_se(stepped, 300) <= 1.0 / np.sqrt(12.0 * 300) * 1.01
