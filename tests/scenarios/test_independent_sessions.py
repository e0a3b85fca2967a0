"""Sessions written by an independent simulator (scipy's Radau between the driver's
switching events, its own conventions), logged as benches log them, in
``tests/scenarios/sessions/`` with their truths: a noisy voltage column whose driver
made each change at its own place in the sample interval before the sample that shows
it; the same with a tachogenerator's 6 ms filter; an oscilloscope's export whose
settings share the sample fields; two steps through a driver acting a whole number of
samples late."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.inference.model.switch_lead import lead_names
from pmdc_bayes.io.loader import load_session

SESSIONS = Path(__file__).parent / "sessions"
Z99 = 2.576


def _fitted(path):
    session = load_session(path)
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=0)
    assert fit.ok, fit.message
    return session, model, fit, assess(model, fit, cf)


def _declaring(tmp_path, name, line):
    """A copy of the session ``name`` whose ``[model]`` holds ``line``."""
    path = tmp_path / "session"
    shutil.copytree(SESSIONS / name, path)
    toml = path / "session.toml"
    toml.write_text(toml.read_text() + f"\n[model]\n{line}\n")
    return path


def _z(model, fit, name, truth):
    i = list(fit.names).index(name)
    value = np.asarray(model.theta({name: truth}))[i]  # in θ: log, or the value
    return float((value - fit.theta[i]) / np.sqrt(fit.cov_log[i, i]))


@pytest.mark.compiles
def test_a_column_whose_changes_fall_anywhere_between_samples_is_fitted_right():
    """0 → 5 → 9 → 2 → 0 V, the changes 0.6, 0.3, 0.9 and 0.4 ms before the samples that
    show them (1 ms apart), La/Ra = 0.32 ms, current logged: adequate, each change's lead
    and every motor parameter inside its 99 % interval."""
    path = SESSIONS / "column_steps_between_samples"
    truth = json.loads((path / "truth.json").read_text())
    session, model, fit, verdict = _fitted(path)
    assert str(verdict.verdict) == "adequate", verdict.failures()
    for name in ("Ra", "La", "K", "B", "J"):
        assert abs(_z(model, fit, name, truth[name])) < Z99, name
    leads = lead_names(session.traces[0])  # the column starts at 0 V: no lead there
    assert len(leads) == len(truth["switch_leads"]) == 4
    for name, lead in zip(leads, truth["switch_leads"], strict=True):
        assert abs(_z(model, fit, name, lead)) < Z99, name


@pytest.mark.compiles
def test_a_tacho_lag_declared_on_such_a_column_is_fitted_right(tmp_path):
    """0 → 6 → 12 V from a noisy column, each change off the samples, the tacho read
    through a 6 ms filter: with the lag declared, adequate, the lag and every motor
    parameter inside its 99 % interval."""
    path = _declaring(tmp_path, "tacho_lag_column", "speed_lag = true")
    truth = json.loads((path / "truth.json").read_text())
    _, model, fit, verdict = _fitted(path)
    assert str(verdict.verdict) == "adequate", verdict.failures()
    for name in ("Ra", "K", "B", "J", "Tc", "speed_lag"):
        assert abs(_z(model, fit, name, truth[name])) < Z99, name


@pytest.mark.compiles
def test_a_dead_time_of_a_whole_number_of_samples_converges_on_its_kink(tmp_path):
    """A 4 ms dead time at 0.5 ms samples puts the delayed step on a sample, where the
    current's slope jumps: the log-posterior has a kink at the optimum that no step of
    every parameter together leaves.  The fit converges there (the dead time held, the
    rest converged, then freed), the starts that stalled at it count as agreeing, and
    the dead time and every motor parameter lie inside their 99 % intervals."""
    path = _declaring(tmp_path, "dead_time_on_a_sample", 'dead_time = "shared"')
    truth = json.loads((path / "truth.json").read_text())
    _, model, fit, verdict = _fitted(path)
    assert str(verdict.verdict) == "adequate", verdict.failures()
    assert sum(s["agrees"] for s in fit.starts) >= 4, fit.message
    for name in ("Ra", "La", "K", "B", "J", "dead_time"):
        assert abs(_z(model, fit, name, truth[name])) < Z99, name


@pytest.mark.compiles
def test_an_undeclared_tacho_lag_on_a_two_step_column_is_diagnosed_as_one():
    """The same session without the lag declared: rejected, and the diagnosis reads the
    first step's start up to the second step (the current on time, the speed late) and
    proposes the speed sensor's lag, nothing else."""
    _, _, _, verdict = _fitted(SESSIONS / "tacho_lag_column")
    assert str(verdict.verdict) == "inadequate"
    assert [p.nuisance for p in verdict.proposals] == ["speed_lag"], verdict.diagnosis


def test_a_scope_export_with_its_settings_in_the_sample_fields_is_read():
    """A headerless export whose first lines write each setting beside its value in the
    fields the samples use (``Record Length,1500``): the settings are passed over and
    every sample read."""
    tr = load_session(SESSIONS / "scope_export").traces[0]
    assert tr.n == 1500 and np.all(np.isfinite(tr.speed)) and np.all(np.isfinite(tr.current))
    first = (SESSIONS / "scope_export" / "TEK0007.CSV").read_text().splitlines()[5]
    assert first.startswith("0.316")
    assert tr.speed[0] == pytest.approx(0.316 * 2 * np.pi)  # rev/s
