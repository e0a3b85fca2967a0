"""Quantised readings with too little noise to dither them carry one independent error
per quantum the signal passes through, not one per reading: counted so, a fit of such
a session (from the independent bench simulator) covers the truth."""

import numpy as np
import pytest

from pmdc_bayes.inference.model.noise import effective_fraction, quanta_passed

Q = 0.5


def _quantised(signal, sigma, seed=0):
    rng = np.random.default_rng(seed)
    return np.round((signal + sigma * rng.standard_normal(signal.size)) / Q) * Q


@pytest.mark.parametrize("at,sigma,levels", [(0.5, 0.1, 2), (0.0, 0.35, 3)])
def test_readings_scattered_over_neighbouring_levels_pass_no_quantum(at, sigma, levels):
    y = _quantised(np.full(5000, (10.0 + at) * Q), sigma * Q)
    assert np.unique(y).size == levels and np.count_nonzero(np.diff(y)) > 100
    assert quanta_passed(y, Q) == 0


@pytest.mark.parametrize("sigma", [0.0, 0.1, 0.3])
def test_a_ramp_passes_the_quanta_it_crosses_whatever_the_flicker(sigma):
    ramp = np.linspace(0.0, 40.0 * Q, 4000)
    y = _quantised(ramp, sigma * Q)
    assert 38 <= quanta_passed(y, Q) <= 40
    # up and back down: twice as many
    assert 76 <= quanta_passed(np.concatenate([y, y[::-1]]), Q) <= 80
    if sigma < 0.5:  # not dithered: the ramp's quanta, not its readings
        assert effective_fraction(y) == pytest.approx((1 + quanta_passed(y, Q)) / y.size)


def test_a_dithered_channel_keeps_every_reading():
    y = _quantised(np.linspace(0.0, 40.0 * Q, 4000), 0.8 * Q)
    assert effective_fraction(y) == 1.0
    assert effective_fraction(np.linspace(0.0, 1.0, 100) ** 2) == 1.0  # not quantised


@pytest.mark.compiles
def test_an_undithered_quantised_session_covers_the_truth(tmp_path):
    """Fuzzed session 57: a load change logged at 16.7 kHz whose speed is quantised to
    0.86 rad/s under 0.22 rad/s of noise, 11,735 readings passing about a hundred
    quanta.  Counting every run of equal readings as an independent error put K 3.5 sd
    and J 4.0 sd from the truth; the central 99 % intervals now cover every motor
    parameter."""
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.simulate.fuzz import fuzz_session

    fz = fuzz_session(57, out=tmp_path / "s57")
    session = load_session(fz.path)
    model = build_model(session, fit_seed(session))
    fit = fit_map(model, seed=57)
    for name in ("Ra", "La", "K", "B", "J"):
        i = list(fit.names).index(name)
        z = (np.log(fz.truth[name]) - fit.theta[i]) / np.sqrt(fit.cov_log[i, i])
        assert abs(z) < 2.576, (name, z)
