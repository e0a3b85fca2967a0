"""The linear responses of ω/Va (step and frequency) against python-control's, for an
overdamped motor, an underdamped one (a large La), poles equal and draws at once."""

from __future__ import annotations

import numpy as np
import pytest

from pmdc_bayes.physics.motor import tf_full
from pmdc_bayes.physics.response import frequency_response, poles, step_response

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

control = pytest.importorskip("control")

CASES = {
    "bench motor": (8.5, 5.6e-3, 0.062, 4.5e-5, 5.9e-4),
    "underdamped": (1.0, 0.5, 0.05, 1e-4, 1e-5),
    "close poles": (2.0, 1e-3, 0.1, 1e-4, 1e-4),
    "equal poles": (2.0, 1.0, 1.0, 0.0, 1.0),  # den = s² + 2s + 1
}


@pytest.mark.parametrize("name", CASES)
def test_step_and_frequency_responses_match_python_control(name):
    params = CASES[name]
    sys = control.tf(*tf_full(*params))
    slowest = max(-1 / np.real(control.poles(sys)))
    t = np.linspace(0.0, 6 * slowest, 700)
    _, y = control.step_response(sys, t)
    np.testing.assert_allclose(step_response(*params, t), y, rtol=0,
                               atol=1e-9 * np.max(np.abs(y)))
    w = np.logspace(-3, 6, 90)
    h = control.frequency_response(sys, w).complex
    np.testing.assert_allclose(frequency_response(*params, w), h, rtol=1e-12)
    expected = control.poles(sys)
    for p in poles(*params):
        assert np.min(np.abs(expected - p)) <= 1e-6 * np.abs(p)


def test_draws_broadcast_against_times_and_frequencies():
    base = np.array(CASES["bench motor"])
    draws = (base * np.array([[1.0], [1.05], [0.95]])).T  # (parameter, draw)
    t, w = np.linspace(0, 3, 40), np.logspace(0, 4, 30)
    steps = step_response(*draws, t)
    freqs = frequency_response(*draws, w)
    assert steps.shape == (3, 40) and freqs.shape == (3, 30)
    for k in range(3):
        np.testing.assert_array_equal(steps[k], step_response(*draws[:, k], t))
        np.testing.assert_array_equal(freqs[k], frequency_response(*draws[:, k], w))
    # the settled speed per volt is the DC gain K/(Ra·B + K²) of each draw
    Ra, La, K, B, J = draws
    np.testing.assert_allclose(step_response(*draws, [60.0])[:, 0], K / (Ra * B + K * K),
                               rtol=1e-12)
