"""A counted angle's leading run of identical readings at rest: left out of the
likelihood but for its last reading, and only for a counted angle of a trace that
starts at rest."""

import dataclasses
from pathlib import Path

import numpy as np

from pmdc_bayes.inference.model.channels import resting_counts
from pmdc_bayes.io.session import Schedule, Trace

Q = 2 * np.pi / 400


def _trace(counts, *, step=Q, initial="rest"):
    y = np.asarray(counts, dtype=float) * Q
    t = np.arange(y.size) * 1e-3
    v = Schedule(np.array([0.0]), np.array([6.0]))
    return Trace("a", "step", Path("a.csv"), t, np.zeros(y.size), None, v,
                 Schedule(np.array([0.0]), np.array([0.0])), initial=initial, position=y,
                 speed_logged=False, encoder_step=step)


def test_the_leading_rest_run_is_left_out_but_its_last_reading():
    out = resting_counts(_trace([0, 0, 0, 0, 1, 1, 2, 4, 4, 4]))
    assert out.tolist() == [True, True, True, False, False, False, False, False, False, False]


def test_missing_readings_are_skipped_and_a_rest_without_motion_is_kept():
    out = resting_counts(_trace([np.nan, 0, 0, 1, 2]))
    assert out.tolist() == [False, True, False, False, False]
    assert not resting_counts(_trace([3, 3, 3, 3])).any()  # never moved: nothing to weigh


def test_only_a_counted_angle_of_a_trace_from_rest():
    counts = [0, 0, 0, 1, 2]
    assert not resting_counts(_trace(counts, step=0.0)).any()  # an analogue angle: noise
    assert not resting_counts(_trace(counts, initial="steady")).any()
    no_angle = dataclasses.replace(_trace(counts), position=None)
    assert not resting_counts(no_angle).any()
