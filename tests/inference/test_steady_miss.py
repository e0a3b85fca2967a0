"""The steady readings' test: a model-free line's scatter calibrates the miss."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from pmdc_bayes.inference.adequacy.findings import Check, Severity
from pmdc_bayes.inference.adequacy.steady import (
    PRIOR_MATERIAL,
    Noise,
    line_columns,
    line_test,
    reading_quantum,
    steady_tests,
)
from pmdc_bayes.inference.model.noise import NU0
from pmdc_bayes.io.channel import STEADY, ChannelId

TRIALS = 4000
LEVEL = 0.05


def _band(n: int, p: float, mass: float = 0.999) -> tuple[int, int]:
    tail = (1 - mass) / 2
    return int(stats.binom.ppf(tail, n, p)), int(stats.binom.ppf(1 - tail, n, p))


def _table(rng, n: int):
    """A steady table's voltages, loads and true speeds (an affine law)."""
    v = np.sort(rng.uniform(2.0, 24.0, n))
    tl = rng.choice([0.0, 0.01], n)
    return v, tl, 30.0 * v - 800.0 * tl + 5.0


def test_the_columns_follow_the_predicted_regime():
    v = np.array([6.0, 12.0, -6.0, -12.0, 3.0, 0.5])
    tl = np.zeros(6)
    i_model = np.array([1.0, 2.0, -1.0, -2.0, 1.5, 0.0])  # the last: no current
    w_model = np.array([50.0, 100.0, -50.0, -100.0, 0.0, 2.0])  # the fifth: held
    x = line_columns(v, tl, i_model, w_model)
    # voltage, load, four direction pairs, and one column for each of the two others
    assert x.shape == (6, 8)
    assert np.array_equal(x[:, 0], [6.0, 12.0, -6.0, -12.0, 0.0, 0.0])
    pairs = x[:, 2:6]
    assert np.array_equal(pairs.sum(axis=1), [1, 1, 1, 1, 0, 0])
    assert np.array_equal(x[4:, 6:], np.eye(2))


def test_no_degree_of_freedom_for_the_scatter_leaves_the_channel_untested():
    v = np.array([6.0, 12.0])
    x = line_columns(v, np.zeros(2), np.ones(2), np.ones(2))
    assert line_test(30.0 * v, 30.0 * v + 1.0, x) is None  # two readings, three columns
    assert line_test(np.ones(3), np.ones(3), np.zeros((3, 0))) is None


def test_a_correct_prediction_is_rejected_at_the_nominal_rate():
    rng = np.random.default_rng(1)
    hits = 0
    for _ in range(TRIALS):
        n = int(rng.integers(4, 9))
        v, tl, w = _table(rng, n)
        y = w + 0.02 * w.max() * rng.standard_normal(n)
        t = line_test(y, w, line_columns(v, tl, np.ones(n), np.ones(n)))
        hits += t.p_value < LEVEL
    lo, hi = _band(TRIALS, LEVEL)
    assert lo <= hits <= hi, hits


def test_a_prediction_fitted_to_the_readings_is_not_rejected_more_often():
    """A model fitted to the same readings (fewer parameters than the line) leaves a
    smaller miss than an exact one: at most the nominal rate."""
    rng = np.random.default_rng(2)
    hits = 0
    for _ in range(TRIALS):
        n = int(rng.integers(4, 9))
        v, _, _ = _table(rng, n)
        w = 30.0 * v
        y = w + 0.02 * w.max() * rng.standard_normal(n)
        yhat = v * float(v @ y / (v @ v))  # through the origin, as the true law
        t = line_test(y, yhat, line_columns(v, np.zeros(n), np.ones(n), np.ones(n)))
        hits += t.p_value < LEVEL
    assert hits <= _band(TRIALS, LEVEL)[1], hits


def test_the_predictions_own_uncertainty_keeps_the_rate_nominal():
    """A slope the rest of the session fixes only to about the readings' noise: counted
    exact, the readings reject it far too often; with its covariance, at most at the
    nominal rate (the statistic is then lighter-tailed than its F)."""
    rng = np.random.default_rng(3)
    slope_sd = 0.1
    hits_exact = hits_cov = 0
    for _ in range(TRIALS):
        n = int(rng.integers(4, 9))
        v, tl, w = _table(rng, n)
        y = w + 0.5 * rng.standard_normal(n)
        yhat = w + slope_sd * rng.standard_normal() * v
        x = line_columns(v, tl, np.ones(n), np.ones(n))
        hits_exact += line_test(y, yhat, x).p_value < LEVEL
        hits_cov += line_test(y, yhat, x, slope_sd**2 * np.outer(v, v)).p_value < LEVEL
    hi = _band(TRIALS, LEVEL)[1]
    assert hits_exact > hi
    assert hits_cov <= hi, hits_cov


def test_a_sensor_reading_eight_percent_high_is_found_in_eight_readings():
    rng = np.random.default_rng(4)
    v, tl, w = _table(rng, 8)
    y = w + 0.005 * w.max() * rng.standard_normal(8)
    t = line_test(y, 1.08 * w, line_columns(v, tl, np.ones(8), np.ones(8)))
    assert t.p_value < 1e-3
    assert t.excess > 0.015


def test_a_stalled_reading_leaves_the_others_tested():
    rng = np.random.default_rng(5)
    v, _, w = _table(rng, 6)
    tl = np.array([0.0, 0.0, 0.01, 0.01, 0.0, 0.01])
    w = 30.0 * v - 800.0 * tl + 5.0
    w[0] = 0.0  # the rotor held there: the model's own column
    y = w + 0.005 * w.max() * rng.standard_normal(6)
    i_model = np.ones(6)
    x = line_columns(v, tl, i_model, np.where(np.arange(6) == 0, 0.0, 1.0))
    t = line_test(y, 1.08 * w, x)
    assert t is not None and t.dof == (4, 2)
    assert t.p_value < 0.01


def test_a_coarse_lattice_is_not_taken_for_a_miss():
    """Readings logged on a lattice as coarse as the model's error: the line's scatter
    is the rounding's, not zero."""
    rng = np.random.default_rng(6)
    q = 10.0
    hits = 0
    for _ in range(400):
        v, tl, w = _table(rng, 6)
        y = q * np.round(w / q)
        t = line_test(y, w, line_columns(v, tl, np.ones(6), np.ones(6)), quantum=q)
        hits += t.p_value < 0.01
    assert hits <= _band(400, 0.01)[1], hits


def test_evenly_spaced_readings_are_not_taken_for_a_lattice():
    v = np.linspace(4.0, 12.0, 6)
    assert reading_quantum(30.0 * v) == 0.0
    rpm = 2 * np.pi / 60
    assert reading_quantum(rpm * np.array([1450.0, 1453.0, 1461.0, 1466.0])) == 0.0
    fine = rpm * np.array([1450.0, 1451.0, 1460.0, 1461.0, 1470.0])
    assert reading_quantum(fine) == pytest.approx(rpm)


def _fake(speeds, s0=None):
    """A model whose steady speed is θ·v with no current logged, its steady speed
    channel at the noise scale ``s0`` (1 % of the first reading), and its fit at θ = 30."""
    v = np.linspace(4.0, 12.0, len(speeds))
    speeds = np.asarray(speeds, float)
    st = {"v": v, "tl": np.zeros(v.size), "w": speeds, "i": np.zeros(v.size),
          "w_mask": np.ones(v.size, bool), "i_mask": np.zeros(v.size, bool)}
    channel = SimpleNamespace(id=ChannelId(STEADY, "speed"), unit="rad/s",
                              s0=0.01 * speeds[0] if s0 is None else s0)
    def with_jacobian(th):
        pred = np.stack([np.ones_like(v), th[0] * v])
        return pred, np.stack([np.zeros_like(v), v])[:, :, None], v

    model = SimpleNamespace(steady=st, channels=(channel,), steady_with_jacobian=with_jacobian)
    fit = SimpleNamespace(theta=np.array([30.0]), cov_map=None, cov_log=np.zeros((1, 1)))
    return model, fit


@pytest.mark.parametrize(("miss", "warned", "rejected"),
                         [(0.01, False, False), (0.05, True, False), (0.5, True, True)])
def test_a_lone_operating_point_is_read_on_its_noise_prior(miss, warned, rejected):
    """One reading shows no scatter of its own: its miss is read on the channel's noise
    prior (here 1 % of the prediction, F(1, ν0)), so that 5 % passes with a warning and a
    reading the model misses by half fails."""
    assert PRIOR_MATERIAL < 0.05
    model, fit = _fake([30.0 * 4.0 * (1 + miss)], s0=0.01 * 30.0 * 4.0)
    rows, tests, warns = steady_tests(model, fit)
    assert rows["steady: speed"]["noise"] == Noise.PRIOR
    assert len(warns) == warned
    assert all(w.check is Check.STEADY_MISS and w.severity is Severity.WARN for w in warns)
    (t,) = tests
    assert (t.p_value < 1e-3) == rejected and t.material == (miss > 0.015)
    assert t.p_value == pytest.approx(stats.f.sf((miss / 0.01) ** 2, 1, NU0), rel=1e-6)


def test_a_table_missed_beyond_its_scatter_is_a_test_of_the_verdicts_family():
    v = np.linspace(4.0, 12.0, 6)
    noise = 0.01 * np.array([1.0, -1.0, 0.5, -0.5, 0.2, -0.2])
    model, fit = _fake(33.0 * v + noise)  # 10 % above the model's
    rows, tests, warns = steady_tests(model, fit)
    assert rows["steady: speed"]["noise"] == Noise.SCATTER
    assert warns == [] and len(tests) == 1
    assert tests[0].p_value < 1e-6 and tests[0].material
    assert tests[0].finding.severity is Severity.FAIL
    assert rows["steady: speed"]["p_value"] == tests[0].p_value


def _assessed(seed: int, misspecified, tmp_path):
    from pmdc_bayes.inference.adequacy.verdict import assess
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.simulate.fuzz import fuzz_session

    f = fuzz_session(seed, misspecified=misspecified, out=tmp_path / "s")
    session = load_session(f.path)
    cf = fit_seed(session)
    model = build_model(session, cf)
    return assess(model, fit_map(model, seed=seed), cf)


@pytest.mark.compiles
def test_a_traces_speed_sensor_reading_high_is_found_on_the_steady_table(tmp_path):
    """A fuzzed session (the bench simulator) with a steady table: the traces fit
    whatever the speed sensor's gain, the table read by another instrument does not;
    the same session in class passes."""
    from pmdc_bayes.inference.adequacy.proposals import Proposal

    ok = _assessed(202, None, tmp_path)
    assert ok.ok, ok.headline()
    assert ok.channels["steady: speed"]["noise"] == Noise.SCATTER
    bad = _assessed(202, "speed gain", tmp_path)
    assert [f.check for f in bad.failures()] == [Check.STEADY_MISS], bad.headline()
    assert Proposal("speed_gain") in bad.proposals


def test_a_prediction_that_is_not_finite_fails_and_a_held_rotor_is_read():
    """A steady prediction the model cannot make fails the channel, it does not pass for
    want of a test; a reading of zero speed (the rotor held) that the model sees turning
    is read on the noise prior, not divided by its zero."""
    model, fit = _fake([120.0, 180.0])
    fit = SimpleNamespace(theta=np.array([np.nan]), cov_map=None, cov_log=np.zeros((1, 1)))
    rows, tests, found = steady_tests(model, fit)
    assert tests == [] and [f.severity for f in found] == [Severity.FAIL]
    model, fit = _fake([0.0], s0=0.0)
    rows, tests, found = steady_tests(model, fit)
    (t,) = tests
    assert rows["steady: speed"]["noise"] == Noise.PRIOR and t.p_value < 1e-6 and t.material
