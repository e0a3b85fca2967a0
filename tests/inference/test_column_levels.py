"""The levels a noisy logged input column held, fitted with their readings' standard
error: which traces carry them, how the segments take them, and a session whose K and B
the read levels' error moved several sd when the levels were taken as exact."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model import column_levels
from pmdc_bayes.inference.model.column_levels import (
    READINGS,
    level_names,
    level_specs,
    segment_levels,
)
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.physics.experiment import experiment_from_traces
from pmdc_bayes.simulate.fuzz import fuzz_session


@pytest.fixture(scope="module")
def seed81(tmp_path_factory):
    """Seed 81: a step from rest, a staircase of 10 levels and a step from steady, each
    with a noisy voltage column (the third's read as written), a steady table and an
    operating point."""
    fz = fuzz_session(81, out=tmp_path_factory.mktemp("s81"))
    return fz, load_session(fz.path)


def test_each_level_of_a_noisy_column_is_a_parameter_known_to_its_standard_error(seed81):
    _, session = seed81
    held = [tr for tr in session.traces if tr.voltage.se is not None]
    assert [tr.name for tr in held] == ["tr0_step_from_rest", "tr1_staircase"]
    specs = level_specs(session)
    assert len(specs) == sum(int(np.sum(tr.voltage.se > 0)) for tr in held)
    zero = [tr.voltage.se == 0 for tr in held]
    assert any(z.any() for z in zero)  # a level read as zero is not a parameter
    assert all(np.all(tr.voltage.values[z] == 0) for tr, z in zip(held, zero, strict=True))
    assert all(f"voltage_level_{tr.name}_{j}" not in level_names(session, "voltage")
               for tr, z in zip(held, zero, strict=True) for j in np.flatnonzero(z))
    assert tuple(s.name for s in specs) == level_names(session, "voltage")
    first = held[1]
    spec = next(s for s in specs if s.name == "voltage_level_tr1_staircase_2")
    assert spec.prior.kind == "normal" and spec.prior.source == READINGS
    assert spec.transform == "identity" and spec.unit == "V"
    assert spec.prior.centre == first.voltage.values[2] == spec.seed
    assert spec.prior.scale == first.voltage.se[2] > 0
    assert level_names(session, "load") == ()


def test_each_segment_takes_the_level_that_holds_at_its_start(seed81):
    _, session = seed81
    exp = experiment_from_traces(session.traces)
    index = segment_levels(session, exp.seg_t0, exp.seg_len, exp.seg_trace, "voltage")
    va, trace = np.asarray(exp.seg_va), np.asarray(exp.seg_trace)
    values = np.concatenate([tr.voltage.values[tr.voltage.se > 0]
                             for tr in session.traces[:2]])
    assert np.all(index[trace == 2] == -1)  # the column read as written
    on = index >= 0
    np.testing.assert_allclose(va[on], values[index[on]], rtol=1e-6)
    assert set(index[on]) == set(range(values.size))
    assert np.all(va[(trace < 2) & ~on] == 0)  # a level read as zero drives its own
    assert segment_levels(session, exp.seg_t0, exp.seg_len, exp.seg_trace, "load") is None


def _z(model, fit, truth, names=("Ra", "La", "K", "B", "J")):
    """Per motor parameter, (truth − MAP) / Laplace sd in the fit's coordinates."""
    t = np.asarray(model.theta({k: v for k, v in truth.items() if k in fit.names}))
    out = {}
    for k in names:
        i = fit.names.index(k)
        out[k] = float((t[i] - fit.theta[i]) / np.sqrt(fit.cov_log[i, i]))
    return out


@pytest.mark.compiles
def test_the_levels_error_reaches_the_motors_intervals(seed81, monkeypatch):
    """Seed 81 with its levels fitted: adequate, every motor parameter inside its 99 %
    Laplace interval; with the levels taken as exact (none fitted), K lies outside its."""
    fz, session = seed81
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=81)
    assert fit.ok, fit.message
    assert str(assess(model, fit, cf).verdict) == "adequate"
    z = _z(model, fit, fz.truth)
    assert all(abs(v) < 2.576 for v in z.values()), z
    monkeypatch.setattr(column_levels, "MAX_LEVELS", 0)
    exact = build_model(session, cf)
    assert not level_names(session, "voltage")
    fit = fit_map(exact, seed=81)
    assert fit.ok, fit.message
    assert abs(_z(exact, fit, fz.truth)["K"]) > 2.576
