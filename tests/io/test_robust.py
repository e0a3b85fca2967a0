"""The robust noise level and the first run beyond a threshold, read before any model."""

import numpy as np
import pytest

from pmdc_bayes.io.robust import difference_sd, first_run


@pytest.mark.parametrize("order", [1, 2])
def test_difference_sd_reads_white_noise_through_steps_and_a_ramp(order):
    rng = np.random.default_rng(3)
    sigma = 0.02
    # a slope of 2.5 sds per sample: the differences' median is far from 0
    signal = np.repeat([0.0, 5.0, -3.0, 2.0], 2500) + 2.5 * sigma * np.arange(10_000)
    sd = difference_sd(signal + rng.normal(0.0, sigma, signal.size), order)
    assert abs(sd / sigma - 1.0) < 0.05


def test_difference_sd_of_a_held_signal_is_zero_and_missing_readings_are_left_out():
    held = np.repeat([1.0, 2.0, 3.0], 50)
    assert difference_sd(held) == 0.0
    rng = np.random.default_rng(4)
    noisy = rng.normal(0.0, 0.1, 4000)
    gappy = noisy.copy()
    gappy[::7] = np.nan
    assert np.isfinite(difference_sd(gappy))
    assert abs(difference_sd(gappy) / 0.1 - 1.0) < 0.1
    assert difference_sd([1.0]) == 0.0


def test_first_run_needs_every_sample_of_the_run():
    beyond = np.array([0, 1, 1, 0, 1, 1, 1, 1, 0], bool)
    assert first_run(beyond) == 4
    assert first_run(beyond, 2) == 1
    assert first_run(np.array([1, 1, 0, 1], bool)) is None
    assert first_run(np.array([], bool)) is None and first_run(np.ones(2, bool)) is None
