"""A noisy logged input column is read as the levels its driver held; a column without
noise as written."""

import numpy as np
import pytest
from scipy import stats

from pmdc_bayes.io.held_levels import FALSE_SPLIT, ZERO_MISS, held_levels, switched_swing
from pmdc_bayes.io.robust import difference_sd

RATE = 1000.0


def _staircase(levels, hold: int, sigma: float, seed: int = 0):
    t = np.arange(len(levels) * hold) / RATE
    clean = np.repeat(levels, hold).astype(float)
    return t, clean, clean + np.random.default_rng(seed).normal(0.0, sigma, t.size)


def test_a_noisy_staircase_column_is_read_as_its_levels_at_the_samples_that_show_them():
    steps = [0.0, 2.0, 4.0, 8.0, 12.0, 4.0, -4.0, -12.0, 0.0]
    sigma, hold = 0.03, 400
    t, _, noisy = _staircase(steps, hold, sigma)
    levels = held_levels(t, noisy)
    assert np.allclose(levels.times, t[::hold])
    driven = np.asarray(steps) != 0
    assert np.allclose(levels.se[driven], difference_sd(noisy) / np.sqrt(hold))
    assert np.all(levels.values[~driven] == 0) and np.all(levels.se[~driven] == 0)
    assert np.all(np.abs(levels.values - steps) < 5 * sigma / np.sqrt(hold)), levels.values
    assert abs(difference_sd(noisy) / sigma - 1.0) < 0.1


def test_a_level_held_at_zero_is_read_as_zero_as_often_as_stated():
    """Of levels held at zero between two driven ones, a share ``ZERO_MISS`` at most is
    left a fitted level off zero (a binomial bound); one a few standard errors off zero
    is kept as read."""
    sigma, hold, n_columns = 0.05, 200, 600
    missed = 0
    for seed in range(n_columns):
        t, _, noisy = _staircase([6.0, 0.0, 6.0], hold, sigma, seed=seed)
        levels = held_levels(t, noisy)
        j = int(np.searchsorted(levels.times, t[hold + hold // 2], side="right")) - 1
        missed += levels.values[j] != 0
        assert (levels.values[j] == 0) == (levels.se[j] == 0)
    assert missed <= stats.binom.isf(1e-3, n_columns, ZERO_MISS), missed
    t, _, noisy = _staircase([6.0, 5 * sigma / np.sqrt(hold), 6.0], hold, sigma, seed=1)
    off = held_levels(t, noisy)
    assert off.values[1] != 0 and off.se[1] > 0


def test_a_column_without_noise_is_read_as_written():
    t = np.arange(3000) / RATE
    ramp = np.where(t < 1.0, 0.0, np.minimum(t - 1.0, 1.0) * 6.0)  # a step, a ramp, held
    column = np.where(t < 0.5, 0.0, 3.0) + ramp
    held = held_levels(t, column)
    assert np.array_equal(held.times, t) and np.array_equal(held.values, column)
    assert held.se is None


def test_a_sag_a_few_noise_widths_deep_is_kept():
    sigma = 0.02
    t, clean, noisy = _staircase([0.0, 12.0], 1000, sigma, seed=1)
    noisy[1000:1040] -= 20 * sigma  # the supply sags while the current rises
    levels = held_levels(t, noisy)
    times, values = levels.times, levels.values
    assert np.allclose(times, [0.0, 1.0, 1.04]), times
    assert abs(values[1] - (12.0 - 20 * sigma)) < 5 * sigma / np.sqrt(40)


@pytest.mark.parametrize("n, n_columns", [(2000, 400), (20, 2000)])
def test_a_constant_noisy_column_is_split_no_more_often_than_stated(n, n_columns):
    """Also a short column, whose noise is known only roughly from its few readings."""
    rng = np.random.default_rng(2)
    read = [held_levels(np.arange(n) / RATE, 5.0 + rng.normal(0.0, 0.01, n), switching=True)
            for _ in range(n_columns)]
    split = sum(levels.times.size > 1 for levels in read)
    assert split <= stats.binom.isf(1e-3, n_columns, FALSE_SPLIT), split
    assert not any(levels.switched for levels in read)


def _pwm_sampled(duties, hold: int, rail: float, seed: int = 0):
    """A driver's switched output sampled far slower than it switches: each reading the
    rail (of the duty's sign) with the duty's probability, else zero."""
    t = np.arange(len(duties) * hold) / RATE
    d = np.repeat(duties, hold).astype(float)
    on = np.random.default_rng(seed).uniform(size=t.size) < np.abs(d)
    return t, d, np.where(on, np.sign(d) * rail, 0.0)


def test_a_sampled_switching_output_is_read_as_the_levels_of_its_duty():
    duties, hold, rail = [0.0, 0.6, 0.85, 0.3, -0.7, 0.0], 500, 24.0
    t, _, column = _pwm_sampled(duties, hold, rail)
    assert switched_swing(column) == 2 * rail
    assert not held_levels(t, column).switched  # a load column is never a driver's output
    levels = held_levels(t, column, switching=True)
    assert levels.switched
    assert levels.values.size == len(duties), levels.values
    off = np.abs(levels.times - t[::hold]) * RATE
    assert off[1] <= 3 and np.all(off <= 20), off  # a start from rest to a few samples
    rest = np.asarray(duties) == 0  # levels that never switched are read as zero
    assert np.all(levels.values[rest] == 0) and np.all(levels.se[rest] == 0)
    assert np.all(levels.se[~rest] > 0.01 * rail)
    z = (levels.values - rail * np.asarray(duties))[~rest] / levels.se[~rest]
    assert np.all(np.abs(z) < 4), z


@pytest.mark.parametrize("kind", ["held steps", "noisy steps", "quantised noise",
                                  "noisy constant", "noisy low staircase", "one-bit noise"])
def test_a_held_or_noisy_column_is_not_taken_for_a_switching_output(kind):
    t, clean, noisy = _staircase([0.0, 12.0, 0.0, 12.0, -12.0], 300, 0.05)
    rng = np.random.default_rng(7)
    column = {"held steps": clean, "noisy steps": noisy,
              "quantised noise": 0.05 * np.round(noisy / 0.05),
              "noisy constant": 5.0 + 0.1 * rng.standard_normal(1000),
              "noisy low staircase": _staircase([10.0, 11.0, 12.0], 300, 0.2)[2],
              "one-bit noise": 12.0 + 0.01 * rng.integers(0, 2, 1000)}[kind]
    assert switched_swing(column) == 0.0
    assert not held_levels(np.arange(column.size) / RATE, column, switching=True).switched


@pytest.mark.parametrize("duty, n, n_columns", [(0.5, 2000, 300), (0.15, 300, 1000),
                                                (-0.8, 100, 1000)])
def test_a_constant_duty_is_split_no_more_often_than_stated(duty, n, n_columns):
    read = [held_levels(*_pwm_sampled([duty], n, 12.0, seed=s)[::2], switching=True)
            for s in range(n_columns)]
    assert all(levels.switched for levels in read)
    split = sum(levels.times.size > 1 for levels in read)
    assert split <= stats.binom.isf(1e-3, n_columns, FALSE_SPLIT), split


def test_a_change_of_direction_is_cut_where_the_zeros_between_belong():
    """The zeros between the last reading of one sign and the first of the other go to
    the duty that makes them likely: here the low duty after the change."""
    hits = []
    for seed in range(50):
        t, _, column = _pwm_sampled([0.7, -0.15], 200, 12.0, seed=seed)
        levels = held_levels(t, column, switching=True)
        assert levels.values[0] > 0 > levels.values[-1]
        hits.append(np.flatnonzero(levels.values < 0)[0] == 1 and
                    abs(levels.times[1] * RATE - 200) <= 4)
    assert np.mean(hits) > 0.9, hits


def test_a_rest_before_a_low_duty_is_a_level_of_its_own():
    """A hundred readings at zero then a duty of 0.2: a run of zeros that long is
    improbable at that duty, however little the mean moves against the rail."""
    t, _, column = _pwm_sampled([0.0, 0.2], 100, 8.0, seed=3)
    t, column = np.arange(600) / RATE, np.concatenate([column[:100], _pwm_sampled(
        [0.2], 500, 8.0, seed=4)[2]])
    levels = held_levels(t, column, switching=True)
    assert levels.values.size == 2 and levels.values[0] == 0.0, levels.values
    assert abs(levels.times[1] * RATE - 100) <= 10


def test_a_driver_that_never_rests_is_read_from_its_two_rails():
    """Locked anti-phase: each reading one rail or the other, the mean the duty's."""
    duties, hold, rail = [0.2, -0.4, 0.6], 500, 12.0
    t = np.arange(len(duties) * hold) / RATE
    d = np.repeat(duties, hold)
    up = np.random.default_rng(5).uniform(size=t.size) < (1.0 + d) / 2.0
    levels = held_levels(t, np.where(up, rail, -rail), switching=True)
    assert levels.switched and levels.values.size == len(duties), levels.values
    z = (levels.values - rail * np.asarray(duties)) / levels.se
    assert np.all(np.abs(z) < 4), z


def test_a_driver_that_never_rests_is_not_cut_at_a_lone_zero_or_at_each_change_of_sign():
    rng = np.random.default_rng(8)
    t = np.arange(2000) / RATE
    column = np.where(rng.uniform(size=t.size) < 0.65, 12.0, -12.0)
    column[700] = 0.0
    assert held_levels(t, column, switching=True).values.size == 1
    column[:200] = 0.0  # the driver enabled after 0.2 s
    levels = held_levels(t, column, switching=True)
    assert levels.values.size == 2 and levels.values[0] == 0.0, levels.values
    assert abs(levels.times[1] * RATE - 200) <= 2


def test_a_lone_reading_of_the_other_sign_is_not_a_level():
    t, _, column = _pwm_sampled([0.5], 2000, 12.0, seed=9)
    column[900] = -12.0
    assert held_levels(t, column, switching=True).values.size == 1


def test_a_change_of_direction_after_a_long_rest_is_cut_where_the_readings_show_it():
    hits = 0
    for seed in range(50):
        t, _, column = _pwm_sampled([0.0] * 10 + [0.7, -0.15], 200, 12.0, seed=seed)
        levels = held_levels(t, column, switching=True)
        negative = np.flatnonzero(levels.values < 0)
        hits += (levels.values.size == 3 and negative.size == 1
                 and abs(levels.times[negative[0]] * RATE - 2200) <= 4)
    assert hits >= 45, hits


@pytest.mark.parametrize("digits", [None, 4])
def test_a_command_that_moves_smoothly_is_read_as_written(digits):
    """A logged chirp (exact, or written to a few decimals) changes at every sample; its
    changes are no noise and its value no held level."""
    t = np.arange(1000) / RATE
    chirp = 6.0 + np.sin(2 * np.pi * (1.0 * t + 5.0 * t**2))
    column = chirp if digits is None else np.round(chirp, digits)
    read = held_levels(t, column, switching=True)
    assert read.se is None and np.array_equal(read.values, column)


@pytest.mark.parametrize("kind", ["AR(1) 0.9", "two-pole 0.2", "two-pole 0.02",
                                  "the column filtered"])
def test_filtered_reading_noise_is_still_read_as_levels(kind):
    """An ADC behind a filter: noise correlated from sample to sample about a staircase
    (AR(1); a two-pole low-pass at 0.2 or 0.02 of the Nyquist rate, on the noise or on
    the whole column, its steps rounded too); the column is still a noisy one, read as
    levels with their errors, not as a smooth command written exactly."""
    from scipy.signal import butter, lfilter

    rng = np.random.default_rng(11)
    t, clean, _ = _staircase([0.0, 6.0, 12.0], 700, 0.0)
    if kind.startswith("AR"):
        e = np.zeros(t.size)
        for k in range(1, t.size):
            e[k] = 0.9 * e[k - 1] + rng.normal(0.0, 0.01)
        column = clean + e
    elif kind.startswith("two-pole"):
        column = clean + lfilter(*butter(2, float(kind.split()[1])), rng.normal(0, 0.05, t.size))
    else:
        column = lfilter(*butter(2, 0.02), clean + rng.normal(0.0, 0.05, t.size))
    read = held_levels(t, column)
    assert read.se is not None and read.values.size < t.size
