"""Readings a logger missed (an empty or NaN cell in a trace's channel) leave their rows
out, the other rows kept at their own times, and the run says which rows; a channel
missing in many rows, a missing time and a table's empty cell are refused."""

import numpy as np
import pytest
from conftest import STEP_DT, STEP_N, replace_once, set_csv_cell

from pmdc_bayes._errors import SessionError
from pmdc_bayes._headline import left_out_lines
from pmdc_bayes.io._missing import MISSING_SHARE
from pmdc_bayes.io.loader import load_session


@pytest.mark.parametrize("marker", ["", "NaN", "nan", "-nan", "N/A", "#N/A", "NA", "-", "null"])
def test_a_missed_reading_leaves_its_row_out_and_the_times_of_the_rest(session_dir, marker):
    set_csv_cell(session_dir / "step.csv", 7, "ia", marker)
    set_csv_cell(session_dir / "step.csv", 40, "speed_rpm", marker)
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (7, 40)
    assert tr.time.size == STEP_N - 2
    expected = np.delete(np.arange(STEP_N) * STEP_DT, [5, 38])  # file line k is sample k-2
    np.testing.assert_allclose(tr.time, expected, atol=1e-12)
    assert np.all(np.isfinite(tr.speed)) and np.all(np.isfinite(tr.current))


def test_rows_at_a_stated_rate_keep_their_place_in_time(session_dir):
    replace_once(session_dir / "session.toml", 'columns = { time = "t", speed = "speed_rpm", '
                 'current = "ia" }', 'columns = { speed = "speed_rpm", current = "ia" }\n'
                 "sample_rate = 100.0")
    replace_once(session_dir / "session.toml", 'units = { time = "s", ', "units = { ")
    set_csv_cell(session_dir / "step.csv", 12, "ia", "")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (12,)
    gaps = np.diff(tr.time)
    np.testing.assert_allclose(np.sort(gaps)[-1], 2 * STEP_DT, rtol=1e-9)
    assert np.sum(gaps > 1.5 * STEP_DT) == 1


def test_a_channel_missing_in_many_rows_is_refused_naming_it(session_dir):
    rows = np.arange(2, STEP_N + 2)[: int(MISSING_SHARE * STEP_N) + 2]
    for line in rows:
        set_csv_cell(session_dir / "step.csv", int(line), "speed_rpm", "")
    with pytest.raises(SessionError, match=r"column 'speed_rpm' has no reading in 17 of 151"):
        load_session(session_dir)


def test_a_trace_that_ends_before_its_files_time_column_ends_there(session_dir):
    """A file shared with a longer run: this trace's cells are empty after its last
    reading.  It ends there; those rows are not readings it missed."""
    tail = int(3 * MISSING_SHARE * STEP_N)
    for line in range(STEP_N + 2 - tail, STEP_N + 2):
        for column in ("speed_rpm", "ia"):
            set_csv_cell(session_dir / "step.csv", line, column, "")
    tr = load_session(session_dir).trace("step")
    assert tr.time.size == STEP_N - tail and tr.rows_left_out == ()
    np.testing.assert_allclose(tr.time[-1], (STEP_N - tail - 1) * STEP_DT, atol=1e-12)


def test_one_channel_ending_early_is_still_a_channel_missing_in_many_rows(session_dir):
    for line in range(STEP_N + 2 - int(3 * MISSING_SHARE * STEP_N), STEP_N + 2):
        set_csv_cell(session_dir / "step.csv", line, "ia", "")
    with pytest.raises(SessionError, match=r"column 'ia' has no reading in"):
        load_session(session_dir)


def test_a_few_missing_rows_are_allowed_up_to_the_share(session_dir):
    for line in range(2, 2 + int(MISSING_SHARE * STEP_N)):
        set_csv_cell(session_dir / "step.csv", line, "ia", "NaN")
    assert len(load_session(session_dir).trace("step").rows_left_out) == 15


def test_an_infinite_reading_is_an_overrange_left_out(session_dir):
    """``inf`` (an Arduino's float overflow, a scope's ``∞``) is an instrument's reading
    out of range, like ``9.9E37``: its row is left out and named."""
    set_csv_cell(session_dir / "step.csv", 9, "speed_rpm", "inf")
    assert load_session(session_dir).trace("step").rows_left_out == (9,)


def test_the_headline_names_the_rows_left_out():
    summary = {"session": {"rows_left_out": {"step": [7, 40], "ramp": list(range(2, 12))}}}
    assert left_out_lines(summary) == [
        "step: 2 rows with a missing reading left out (file lines 7, 40)",
        "ramp: 10 rows with a missing reading left out (file lines 2, 3, 4, 5, 6, ...)"]
    assert left_out_lines({"session": {"rows_left_out": {}}}) == []
