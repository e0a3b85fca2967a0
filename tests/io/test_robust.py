"""The robust noise level, the first run beyond a threshold and where a signal leaves its
first level, read before any model."""

import numpy as np
import pytest

from pmdc_bayes.io.robust import departure, difference_sd, first_run


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


def test_a_signal_leaves_its_first_level_where_a_run_of_samples_clears_its_noise():
    rng = np.random.default_rng(3)
    rise = np.where(np.arange(400) < 100, 0.0, 1.0 - np.exp(-(np.arange(400) - 100) / 40.0))
    noisy = rise + 0.002 * rng.standard_normal(400)
    k = departure(noisy, 0.002, 10.0)  # 5 % of the swing: 2 samples after the step
    assert 101 <= k <= 104, k
    assert departure(noisy, 0.002, 3.0, share=0.0) < k
    assert departure(-noisy, 0.002, 10.0, falling=True) == k
    assert departure(noisy, 0.002, 10.0, falling=True) is None  # it only rises
    assert departure(0.002 * rng.standard_normal(400), 0.002, 10.0) is None
