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
    SCAN_SHARES,
    UNIFORM_SD,
    lead_name,
    lead_scans,
    leading_traces,
)
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import fuzz_plan, fuzz_session


def _session(seed, tmp_path, **kw):
    fz = fuzz_session(seed, out=tmp_path / f"s{seed}", **kw)
    return fz, load_session(fz.path)


def test_a_trace_whose_column_switches_carries_a_lead_with_the_uniform_prior(tmp_path):
    """Seed 16's one trace logs its voltage as a column that steps once: its lead's
    prior is normal with the mean and sd of a uniform variable over the sample interval,
    fitted in value, its start chosen among values across that interval; the traces of
    seed 1 state their schedules in session.toml and carry none."""
    fz, session = _session(16, tmp_path, between_samples=True)
    assert leading_traces(session) == ("tr0_step_from_rest",)
    model = build_model(session, fit_seed(session))
    spec = model.registry[lead_name("tr0_step_from_rest")]
    dt = session.traces[0].dt
    assert spec.prior.kind == "normal" and spec.transform == "identity"
    assert spec.prior.centre == pytest.approx(dt / 2) == spec.seed
    assert spec.prior.scale == pytest.approx(dt / np.sqrt(12.0)) == UNIFORM_SD * dt
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
