"""What the zero-command rule reads off a trace, on closed-form speeds: a first-order
rise and fall of known time constants, cut short or settled, with a sensor offset, and
speeds that never leave their noise."""

from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.onset import crossing_time, rise_time, smoothed
from pmdc_bayes.inference.adequacy.zero_command import CLEAR, coast_rules, time_constants

RATE = 2000.0


def _trace(levels, speed, t, initial="rest"):
    times, values = zip(*levels, strict=True)
    return SimpleNamespace(name="t", voltage=SimpleNamespace(times=np.array(times),
                                                              values=np.array(values)),
                           time=t, speed=speed, initial=initial)


def _response(t, switches, tau_up, tau_down, top=100.0):
    """A speed rising with ``tau_up`` toward ``top`` after the first switch and falling
    with ``tau_down`` toward 0 after the second."""
    on, off = switches
    w = np.where(t > on, top * (1.0 - np.exp(-(t - on) / tau_up)), 0.0)
    at_off = top * (1.0 - np.exp(-(off - on) / tau_up))
    return np.where(t > off, at_off * np.exp(-(t - off) / tau_down), w)


def test_a_moving_average_keeps_a_constant_to_its_ends_and_a_ramp_inside_them():
    y = np.full(400, 7.5) + np.random.default_rng(1).normal(0.0, 1.0, 400)
    ys = smoothed(y)
    assert ys.size == y.size and abs(ys[0] - 7.5) < 1.0 and abs(ys[-1] - 7.5) < 1.0
    ramp = np.linspace(0.0, 1.0, 400)
    assert np.allclose(smoothed(ramp)[50:-50], ramp[50:-50])
    assert smoothed(np.array([1.0, 2.0])).tolist() == [1.0, 2.0]


def test_a_crossing_is_the_first_sample_past_the_mark_either_way():
    t = np.arange(1000) / RATE
    up = 1.0 - np.exp(-t / 0.05)
    assert crossing_time(t, up, 0.0, 0.0, 1.0) == pytest.approx(0.05, abs=1.0 / RATE)
    down = -2.0 * np.exp(-t / 0.05)  # a negative speed toward rest
    assert crossing_time(t, down, 0.0, -2.0, 0.0) == pytest.approx(0.05, abs=1.0 / RATE)
    assert crossing_time(t, up, 0.0, 0.5, 0.5) is None
    assert crossing_time(t, up, 0.0, 0.0, 2.0) is None  # never gets 63 % of the way


def test_a_rise_time_at_the_first_sample_is_read_from_the_level_there():
    t = np.arange(3000) / RATE
    y = 1.0 - np.exp(-t / 0.1)
    assert rise_time(t, y, 0.0) == pytest.approx(0.1, rel=0.02)


@pytest.mark.parametrize("tau_down", [0.02, 0.3, 2.0])
def test_rises_and_falls_are_read_settled_or_cut_short(tau_down):
    """A fall at 0.6 s of a 1 s record is cut short for tau 0.3 and 2 s: read off the
    share of its way left (an exponential's exactly)."""
    t = np.arange(int(1.0 * RATE)) / RATE
    w = _response(t, (0.05, 0.6), 0.02, tau_down)
    rises, falls = time_constants(_trace([(0.0, 0.0), (0.05, 12.0), (0.6, 0.0)], w, t))
    assert rises == [pytest.approx(0.02, abs=2.0 / RATE)]
    assert falls == [pytest.approx(tau_down, rel=0.03)]


def test_a_rise_cut_short_is_read_from_three_points():
    t = np.arange(int(0.5 * RATE)) / RATE
    w = _response(t, (0.1, 0.3), 0.2, 0.2)  # cut after one time constant
    rises, _ = time_constants(_trace([(0.0, 0.0), (0.1, 12.0), (0.3, 0.0)], w, t))
    assert rises == [pytest.approx(0.2, rel=0.03)]


def test_a_first_level_from_rest_at_the_first_sample_is_a_rise():
    t = np.arange(int(1.0 * RATE)) / RATE
    w = _response(t, (0.0, 0.5), 0.02, 0.02)
    rises, falls = time_constants(_trace([(0.0, 12.0), (0.5, 0.0)], w, t))
    assert rises == [pytest.approx(0.02, abs=2.0 / RATE)] and len(falls) == 1


def test_a_fall_is_read_toward_the_speed_the_sensor_shows_at_rest():
    """A sensor offset of 70 % of the top speed: a braked fall is still read on its own
    time scale, and the rule proposes nothing."""
    t = np.arange(int(1.0 * RATE)) / RATE
    w = _response(t, (0.1, 0.5), 0.05, 0.05) + 70.0
    tr = _trace([(0.0, 0.0), (0.1, 12.0), (0.5, 0.0)], w, t)
    rises, falls = time_constants(tr)
    assert falls == [pytest.approx(0.05, abs=2.0 / RATE)]
    assert coast_rules(SimpleNamespace(session=SimpleNamespace(nuisances=())), tr) == []


def test_speeds_that_never_leave_their_noise_give_no_reading():
    """A rotor that never turns (a dead zone, stiction): rises and falls of the noise's
    size are not read, so nothing is proposed."""
    t = np.arange(int(1.0 * RATE)) / RATE
    rng = np.random.default_rng(3)
    w = rng.normal(0.0, 1.0, t.size)
    w[(t > 0.1) & (t < 0.5)] += CLEAR * 2.0  # a step of a fifth of the noise's range
    tr = _trace([(0.0, 0.0), (0.1, 0.5), (0.5, 0.0)], w, t)
    assert time_constants(tr) == ([], [])
    assert coast_rules(SimpleNamespace(session=SimpleNamespace(nuisances=())), tr) == []
