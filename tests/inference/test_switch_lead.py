"""The lead of a logged column's changes over the samples that show them: which traces
carry one, its prior, and a session whose rig switches between samples fitted right
(before the lead, the model placed the change at the sample that shows it: the step
start check failed, La 2.8 sd off)."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.fit.multistart import maximise
from pmdc_bayes.inference.fit.optimiser import Stepper
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.inference.model.switch_lead import (
    PRIOR_MEAN,
    PRIOR_SD,
    SCAN_SHARES,
    lead_name,
    lead_names,
    lead_scans,
    leading_traces,
    segment_leads,
)
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.physics.experiment import experiment_from_traces
from pmdc_bayes.simulate.fuzz import fuzz_plan, fuzz_session


def _session(seed, tmp_path, **kw):
    fz = fuzz_session(seed, out=tmp_path / f"s{seed}", **kw)
    return fz, load_session(fz.path)


def test_a_trace_whose_column_switches_once_carries_a_lead_with_its_prior(tmp_path):
    """Seed 16's one trace logs its voltage as a column that steps once: its lead's
    prior is normal with the mean and sd of an even mixture of a lead of 0 and a uniform
    one over the sample interval, fitted in value, its start chosen among values across
    that interval; the traces of seed 1 state their schedules in session.toml and carry
    none."""
    fz, session = _session(16, tmp_path, between_samples=True)
    assert leading_traces(session) == ("tr0_step_from_rest",)
    model = build_model(session, fit_seed(session))
    spec = model.registry[lead_name("tr0_step_from_rest")]
    dt = session.traces[0].dt
    assert spec.prior.kind == "normal" and spec.transform == "identity"
    # an even mixture of a lead of 0 and one uniform over the interval: its moments
    assert spec.prior.centre == pytest.approx(dt / 4) == spec.seed == PRIOR_MEAN * dt
    assert spec.prior.scale == pytest.approx(dt * np.sqrt(1 / 6 - 1 / 16)) == PRIOR_SD * dt
    scan = lead_scans(session)[spec.name]
    assert scan.min() < 0.0 < scan.max() < dt and scan == pytest.approx(SCAN_SHARES * dt)
    plan, extras = fuzz_plan(1)
    assert not extras["columns"]
    assert leading_traces(load_session(fuzz_session(1, out=tmp_path / "s1").path)) == ()


@pytest.mark.compiles
def test_a_rig_that_switches_between_samples_is_fitted_right(tmp_path):
    """Seed 16 with its step between samples (a 9.4 V step from rest, 408 Hz, current
    logged, La/Ra under a sample interval): adequate, every motor parameter and the
    true lead (from the first sample showing the step back to the rig's switch) inside
    their 99 % Laplace intervals."""
    fz, session = _session(16, tmp_path, between_samples=True)
    model = build_model(session, fit_seed(session))
    fit = fit_map(model, seed=16)
    assert fit.ok
    assert str(assess(model, fit, fit_seed(session)).verdict) == "adequate"
    plan, _ = fuzz_plan(16, between_samples=True)
    switch = plan["trace"][0]["voltage"][1][0]
    tr = session.traces[0]
    truth = dict(fz.truth)
    truth[lead_name(tr.name)] = float(tr.time[np.searchsorted(tr.time, switch)] - switch)
    assert 0.0 < truth[lead_name(tr.name)] < tr.dt
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in truth.items() if k in names}))
    for name in ("Ra", "La", "K", "B", "J", lead_name(tr.name)):
        i = names.index(name)
        z = (theta[i] - fit.theta[i]) / np.sqrt(fit.cov_log[i, i])  # log, or the lead
        assert abs(z) < 2.576, (name, z)


@pytest.mark.compiles
def test_a_rig_that_switches_at_the_samples_fits_its_lead_at_the_box_edge(tmp_path):
    """Seed 25 on the sample grid (the change at the sample that shows it; current logged,
    La/Ra = 0.1 ms against 2.5–4.4 ms between samples): the density in the lead is flat
    on both sides of a fall a time constant wide at 0, and its optimum a kink there.  The
    fit starts the lead on the right side and converges at the edge, where no step of all
    parameters together rises, with every motor parameter inside its 99 % interval; a
    lead started on the far side (the prior's centre) reaches an optimum far below."""
    fz, session = _session(25, tmp_path)
    model = build_model(session, fit_seed(session))
    fit = fit_map(model, seed=25)
    assert fit.ok, fit.message
    assert str(assess(model, fit, fit_seed(session)).verdict) == "adequate"
    (name,) = lead_scans(session)
    dt = next(tr.dt for tr in session.traces if lead_name(tr.name) == name)
    assert abs(fit.values[name]) < 0.01 * dt
    assert "edge" in fit.starts[0]["stopped"]
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in fz.truth.items() if k in names}))
    for k in ("Ra", "La", "K", "B", "J", "Tc"):
        i = names.index(k)
        assert abs(theta[i] - fit.theta[i]) < 2.576 * np.sqrt(fit.cov_log[i, i]), k
    (far,) = maximise(Stepper.of(model), [np.asarray(model.theta_seed())])
    assert far.lp < fit.log_posterior - 10.0


def test_each_change_of_a_column_has_its_own_lead(tmp_path, monkeypatch):
    """Seed 71's staircase (five changes of a logged voltage column, each between two
    samples): a lead per change, each segment a change starts reading its own, the
    trace's first segment none; a column of more changes than allowed shares one."""
    _, session = _session(71, tmp_path, between_samples=True)
    (tr,) = session.traces
    names = lead_names(tr)
    assert names == tuple(f"{lead_name(tr.name)}_{j}" for j in range(5))
    exp = experiment_from_traces(session.traces)
    assert segment_leads(session, exp.seg_t0, exp.seg_trace).tolist() == [-1, 0, 1, 2, 3, 4]
    monkeypatch.setattr("pmdc_bayes.inference.model.switch_lead.MAX_CHANGES", 4)
    assert lead_names(tr) == (lead_name(tr.name),)
    assert segment_leads(session, exp.seg_t0, exp.seg_trace).tolist() == [-1, 0, 0, 0, 0, 0]


@pytest.mark.compiles
def test_a_staircase_whose_changes_fall_anywhere_between_samples_is_fitted_right(tmp_path):
    """Seed 71 between samples (a staircase of five levels, current logged, each change
    at its own place in the interval before the sample that shows it; one lead for them
    all failed the step start): adequate, each change's lead and every motor parameter
    inside their 99 % Laplace intervals."""
    fz, session = _session(71, tmp_path, between_samples=True)
    model = build_model(session, fit_seed(session))
    fit = fit_map(model, seed=71)
    assert fit.ok, fit.message
    assert str(assess(model, fit, fit_seed(session)).verdict) == "adequate"
    plan, _ = fuzz_plan(71, between_samples=True)
    (tr,) = session.traces
    switches = [t for t, _ in plan["trace"][0]["voltage"][1:]]
    truth = dict(fz.truth)
    for name, switch in zip(lead_names(tr), switches, strict=True):
        truth[name] = float(tr.time[np.searchsorted(tr.time, switch)] - switch)
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in truth.items() if k in names}))
    for name in ("Ra", "La", "K", "B", "J", "Tc", *lead_names(tr)):
        i = names.index(name)
        z = (theta[i] - fit.theta[i]) / np.sqrt(fit.cov_log[i, i])
        assert abs(z) < 2.576, (name, z)
