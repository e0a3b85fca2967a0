"""Trace files as real benches write them: rows a logger missed whole, a last line cut
off mid-write, a 12-hour clock, a minus sign from a word processor, an overrange code,
a card's NUL padding, lines ended by a carriage return alone.  Each is read with the
readings where they were taken; what cannot be read unambiguously (a thousands
separator, a row of units that contradicts session.toml, a schedule on another clock)
is refused with one line naming the file, the line and the fix, never read wrong."""

from pathlib import Path

import numpy as np
import pytest
from conftest import STEP_N, replace_once, step_rows

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session

RATE_TOML = ('columns = { time = "t", speed = "speed_rpm", current = "ia" }',
             'columns = { speed = "speed_rpm", current = "ia" }\nsample_rate = 100.0')
RPM = 2 * np.pi / 60


def _rows(d):
    return (d / "step.csv").read_text().splitlines()


def _write(d, lines, end="\n"):
    (d / "step.csv").write_text(end.join(lines) + end, encoding="utf-8")


def _with_header(d, header: str) -> None:
    """The step trace's CSV under ``header`` (time, speed, current), session.toml's
    columns named by it."""
    names = header.split(",")
    replace_once(d / "session.toml",
                 'columns = { time = "t", speed = "speed_rpm", current = "ia" }',
                 f'columns = {{ time = "{names[0]}", speed = "{names[1]}", '
                 f'current = "{names[2]}" }}')
    _write(d, [header, *_rows(d)[1:]])


def _refusal(d) -> str | None:
    """The session at ``d`` loaded whole (every trace of it read in full), or its
    refusal's one line."""
    try:
        session = load_session(d)
    except SessionError as err:
        return str(err)
    assert all(tr.n == STEP_N and tr.time[1] == pytest.approx(0.01) for tr in session.traces)
    return None


def _at_rate(d):
    """The step file without its time column, at its rate of 100 Hz."""
    replace_once(d / "session.toml", *RATE_TOML)
    _write(d, [",".join(line.split(",")[1:]) for line in _rows(d)])


@pytest.mark.parametrize("missed", [",", "-,-", "NaN,NaN"])
def test_a_row_that_missed_every_reading_keeps_its_place(session_dir, missed):
    """At a sample rate, a row whose every cell is empty or a missed reading is a
    sample of its own: the rows after it keep their times, and it is left out."""
    _at_rate(session_dir)
    lines = _rows(session_dir)
    lines[41] = missed  # file line 42: the sample at 0.40 s
    _write(session_dir, lines)
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (42,) and tr.n == STEP_N - 1
    k = int(np.searchsorted(tr.time, 0.5))
    assert tr.time[k] == pytest.approx(0.5)
    assert tr.speed[k] == pytest.approx(step_rows()[50][1] * RPM, rel=1e-6)


def test_a_stamped_row_that_missed_every_reading_is_left_out(session_dir):
    lines = _rows(session_dir)
    lines[30] = "-,-,-"
    _write(session_dir, lines)
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (31,) and tr.n == STEP_N - 1
    assert np.all(np.diff(tr.time) > 0)


def test_a_last_line_cut_off_mid_write_is_left_out(session_dir):
    lines = _rows(session_dir)
    lines[-1] = lines[-1].rsplit(",", 1)[0]  # the current never written
    (session_dir / "step.csv").write_text("\n".join(lines), encoding="utf-8")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (len(lines),) and tr.n == STEP_N - 1
    # the same short row with its newline is a row to mend, not a cut
    _write(session_dir, lines)
    with pytest.raises(SessionError, match="fill in the missing fields"):
        load_session(session_dir)


def test_a_last_line_cut_inside_its_last_value_is_left_out(session_dir):
    """A serial log stopped mid-write inside the last number ("0.01" of "0.0123"): the
    value would read as a sample, wrong; written as wide as the row before it, the
    line is whole and kept though its newline is missing."""
    lines = _rows(session_dir)
    whole = lines[-1]
    cells = whole.split(",")
    assert len(cells[-1]) > 2 and len(cells[-1]) == len(lines[-2].split(",")[-1])
    lines[-1] = ",".join(cells[:-1] + [cells[-1][:-2]])
    (session_dir / "step.csv").write_text("\n".join(lines), encoding="utf-8")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (len(lines),) and tr.n == STEP_N - 1
    lines[-1] = whole
    (session_dir / "step.csv").write_text("\n".join(lines), encoding="utf-8")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == () and tr.n == STEP_N
    assert tr.current[-1] == pytest.approx(float(cells[-1]))


def test_a_last_value_written_as_short_before_is_whole(session_dir):
    """Floats printed without trailing zeros (Python's ``repr``, ``%g``) vary in width
    from row to row: a last line without its newline, its value shorter than the row
    before's but no shorter than one of the rows before, is kept."""
    lines = _rows(session_dir)
    for k, places in zip(range(len(lines) - 12, len(lines)), (4, 2, 3, 4, 3, 2, 4, 3, 4, 2, 4, 2),
                         strict=True):
        cells = lines[k].split(",")
        cells[-1] = f"{float(cells[-1]):.{places}f}"
        lines[k] = ",".join(cells)
    widths = [len(x.split(",")[-1]) for x in lines[-12:]]
    assert widths[-1] < widths[-2] and widths[-1] >= min(widths[:-1])
    (session_dir / "step.csv").write_text("\n".join(lines), encoding="utf-8")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == () and tr.n == STEP_N
    assert tr.current[-1] == pytest.approx(float(lines[-1].split(",")[-1]))


def test_a_last_value_that_lost_its_sign_is_whole(session_dir):
    """Fixed decimals with a sign before some: a last value without its minus is as
    long after the decimal mark as every one before it, so not cut."""
    lines = _rows(session_dir)
    for k in range(len(lines) - 12, len(lines)):
        cells = lines[k].split(",")
        cells[-1] = f"{(-1.0 if k < len(lines) - 1 else 1.0) * abs(float(cells[-1])):.4f}"
        lines[k] = ",".join(cells)
    assert len(lines[-1].split(",")[-1]) < len(lines[-2].split(",")[-1])
    (session_dir / "step.csv").write_text("\n".join(lines), encoding="utf-8")
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == () and tr.n == STEP_N


@pytest.mark.parametrize("code", ["9.9E37", "inf", "-Inf", "\u221e", "\u2212\u221e"])
def test_an_instrument_overrange_code_is_a_missed_reading(session_dir, code):
    lines = _rows(session_dir)
    cells = lines[60].split(",")
    lines[60] = ",".join([cells[0], code, cells[2]])
    _write(session_dir, lines)
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (61,) and np.max(tr.speed) < 1100 * RPM


def test_an_infinite_time_is_refused_with_its_line(session_dir):
    lines = _rows(session_dir)
    lines[60] = ",".join(["inf", *lines[60].split(",")[1:]])
    _write(session_dir, lines)
    with pytest.raises(SessionError, match=r"step.csv:line 61: column 't': 'inf' is not a "
                                           "finite number"):
        load_session(session_dir)


def test_a_quoted_header_with_a_space_after_each_comma_is_read(session_dir):
    """``"t", "speed_rpm", "ia"`` as some loggers write it: the quotes are the cells'."""
    lines = _rows(session_dir)
    _write(session_dir, [", ".join(f'"{c}"' for c in lines[0].split(","))]
           + [", ".join(line.split(",")) for line in lines[1:]])
    tr = load_session(session_dir).trace("step")
    assert tr.n == STEP_N and tr.speed[-1] == pytest.approx(step_rows()[-1][1] * RPM,
                                                            rel=1e-6)


def test_a_twelve_hour_clock_reads_across_noon(session_dir):
    lines = _rows(session_dir)
    out = [lines[0]]
    for k, line in enumerate(lines[1:]):
        s = 11 * 3600 + 59 * 60 + 59.5 + 0.01 * k  # 11:59:59.50 AM, then past noon
        h, rem = divmod(s, 3600)
        m, sec = divmod(rem, 60)
        clock = f"{int(h) % 12 or 12:02d}:{int(m):02d}:{sec:06.3f} {'PM' if h >= 12 else 'AM'}"
        out.append(",".join([clock, *line.split(",")[1:]]))
    _write(session_dir, out)
    tr = load_session(session_dir).trace("step")
    assert np.allclose(tr.time, np.arange(STEP_N) * 0.01, atol=1e-9)


@pytest.mark.parametrize("write", [
    lambda k: f"{0.01 * k:g} sec",  # MATLAB's writetable of a timetable: durations
    lambda k: f"{10 * k} ms",
    lambda k: f"26-Nov-2026 14:03:{7.25 + 0.01 * k:06.3f}",  # MATLAB's datetime
])
def test_matlab_timetables_times_are_read(session_dir, write):
    """A duration with its unit, or a date with its month's name before the clock, in
    the trace's unit of time."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0]] + [",".join([write(k), *line.split(",")[1:]])
                                      for k, line in enumerate(lines[1:])])
    tr = load_session(session_dir).trace("step")
    assert np.allclose(tr.time, np.arange(STEP_N) * 0.01, atol=1e-9)


def test_durations_are_read_as_written_not_from_the_first_row(session_dir):
    """A timetable cut from a longer record starts at its own time: the schedule is on
    that clock, so the times keep it (a clock's stamps count from the first row)."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0]] + [",".join([f"{5 + 0.01 * k:.2f} sec",
                                                *line.split(",")[1:]])
                                      for k, line in enumerate(lines[1:])])
    replace_once(session_dir / "session.toml", "[[0.0, 0.0], [0.1, 6.0]]",
                 "[[0.0, 0.0], [5.1, 6.0]]")
    tr = load_session(session_dir).trace("step")
    assert np.allclose(tr.time, 5 + np.arange(STEP_N) * 0.01, atol=1e-9)


def test_a_staircase_whose_first_level_barely_moves_the_motor_is_not_refused(session_dir):
    """A small first level a thousand times before the step that moves the motor is a
    staircase, not a unit mix-up: the step the motion follows is the large one."""
    replace_once(session_dir / "session.toml", "[[0.0, 0.0], [0.1, 6.0]]",
                 "[[0.0, 0.0], [0.0001, 0.2], [0.1, 6.0]]")
    assert load_session(session_dir).trace("step").n == STEP_N


def test_a_unit_session_toml_writes_as_loggers_do_is_checked_as_its_own(session_dir):
    """``units.time = "sec"`` is seconds: a header in ms is refused against it."""
    toml = session_dir / "session.toml"
    replace_once(toml, 'units = { time = "s",', 'units = { time = "sec",')
    replace_once(toml, 'time = "t"', 'time = "Time (ms)"')
    lines = _rows(session_dir)
    _write(session_dir, ["Time (ms)," + lines[0].split(",", 1)[1], *lines[1:]])
    assert "gives its unit in its header, 'ms', where session.toml reads it in 's'" in (
        _refusal(session_dir) or "")


def test_text_as_word_processors_and_cards_leave_it_is_read(session_dir):
    lines = _rows(session_dir)
    minus = [lines[0], lines[1].replace(",0.0500", ",\u22120.0500"), *lines[2:]]
    _write(session_dir, minus)
    assert load_session(session_dir).trace("step").current[0] == pytest.approx(-0.05)
    (session_dir / "step.csv").write_bytes(("\r".join(lines) + "\r").encode())
    assert load_session(session_dir).trace("step").n == STEP_N
    (session_dir / "step.csv").write_bytes(("\n".join(lines) + "\n").encode() + b"\0" * 512)
    assert load_session(session_dir).trace("step").n == STEP_N


def test_columns_not_read_may_share_a_name(session_dir):
    lines = _rows(session_dir)
    _write(session_dir, [lines[0] + ",V,V"] + [line + ",1,2" for line in lines[1:]])
    assert load_session(session_dir).trace("step").n == STEP_N


def test_a_decimal_comma_in_quotes_is_read_in_a_comma_separated_file(session_dir):
    lines = _rows(session_dir)
    quoted = [lines[0]] + [",".join(f'"{c.replace(".", ",")}"' for c in line.split(","))
                           for line in lines[1:]]
    _write(session_dir, quoted)
    tr = load_session(session_dir).trace("step")
    assert tr.speed[-1] == pytest.approx(step_rows()[-1][1] * RPM, rel=1e-4)


@pytest.mark.parametrize(("sep", "big", "mark"), [
    (";", "1.800", "decimal point"),  # a spreadsheet's locale: decimal comma, 1.800 grouped
    ("\t", "1,800", "decimal comma"),  # decimal point, 1,800 grouped
])
def test_a_thousands_separator_is_refused_not_read_as_decimals(session_dir, sep, big, mark):
    lines = _rows(session_dir)
    comma = sep == ";"
    out = [lines[0].replace(",", sep)]
    for k, line in enumerate(lines[1:]):
        cells = line.split(",")
        if comma:
            cells = [c.replace(".", ",") for c in cells]
        if k == 120:
            cells[1] = big
        out.append(sep.join(cells))
    _write(session_dir, out)
    with pytest.raises(SessionError) as err:
        load_session(session_dir)
    text = str(err.value)
    assert "line 122" in text and repr(big) in text and mark in text
    assert "thousands separator" in text


@pytest.mark.parametrize(("cell", "refused"), [("1.014", True), ("1.0140", False),
                                             ("0.014", False), ("220.125", False)])
def test_a_thousands_point_beside_whole_numbers_is_refused(session_dir, cell, refused):
    """A semicolon file from a locale whose thousands mark is a point: speeds below 1000
    written whole (933), above with the point (1.014, read as 1.014 rpm); a column whose
    points are decimals (1.0140, 0.014), or one that meets its neighbours as written
    (220.125 after 219: a logger that drops trailing zeros), is read."""
    lines = _rows(session_dir)
    out = [lines[0].replace(",", ";")]
    for k, line in enumerate(lines[1:]):
        cells = line.split(",")
        cells[1] = str(100 + k) if k != 120 else cell  # speeds written whole, as a locale does
        out.append(";".join(cells))
    _write(session_dir, out)
    text = _refusal(session_dir) or ""
    assert (f"{cell!r} may be a thousands separator" in text and "line 122" in text) is refused


def test_a_quoted_number_that_may_be_grouped_is_refused(session_dir):
    """In a comma-separated file whose numbers have no decimals, "1,800" is 1800 or 1.8:
    refused; beside a decimal comma elsewhere in the file it is 1.8."""
    lines = _rows(session_dir)
    whole = [lines[0]] + [",".join(str(round(float(c) * 100)) for c in line.split(","))
                          for line in lines[1:]]
    whole[100] = '990,"1,800",5'
    _write(session_dir, whole)
    with pytest.raises(SessionError, match="'1,800' may be a thousands separator"):
        load_session(session_dir)


@pytest.mark.parametrize(("row", "ok"), [
    ("s,rpm,A", True), ("(s),(1/min),(A)", True), ("[s],[RPM],[mA]", False),
    ("ms,rpm,A", False), ("s,rad/s,A", False), ("Time,Speed,Current", True),
])
def test_a_row_of_units_is_checked_against_session_toml(session_dir, row, ok):
    lines = _rows(session_dir)
    _write(session_dir, [lines[0], row, *lines[1:]])
    text = _refusal(session_dir)
    assert text is None if ok else (
        "step.csv:line 2" in text and "the row of units gives column" in text
        and "trace['step'].units." in text)


@pytest.mark.parametrize(("header", "ok"), [
    ("t_s,speed_rpm,ia", True), ("Time (s),Speed [RPM],I_a", True), ("t/s,n/rpm,ia", True),
    ("time (ms),speed_rpm,ia", False), ("t,speed_rpm,i_mA", False),
    ("t,Speed [rad/s],ia", False), ("t_ms,speed_rpm,ia", False),
])
def test_a_unit_in_a_columns_header_is_checked_against_session_toml(session_dir, header,
                                                                    ok):
    """A header that names its column's unit (in brackets, after a slash or after an
    underscore) and names another than session.toml's is refused with the line to add;
    a subscript (``I_a``) is not a unit."""
    _with_header(session_dir, header)
    text = _refusal(session_dir)
    assert text is None if ok else (
        "step.csv:header: column" in text and "gives its unit in its header" in text
        and "set trace['step'].units." in text)


@pytest.mark.parametrize(("header", "says"), [
    ("t,Speed [Hz],ia", 'set trace[\'step\'].units.speed = "Hz"'),
    ("t,Speed [deg/s],ia", 'set trace[\'step\'].units.speed = "deg/s"'),
    ("t,gyro_dps,ia", 'set trace[\'step\'].units.speed = "deg/s"'),
    ("t,Speed [krpm],ia", 'set trace[\'step\'].units.speed = "krpm"'),
    ("t,Tacho [V],ia", "a speed logged as a sensor's or driver's output"),
    ("t,speed_rpm,I_shunt [mV]", "trace['step'].current_sensitivity"),
    ("t,Speed [Hz],ia", "(Hz read as revolutions per second)"),
])
def test_a_header_unit_the_column_is_not_read_in_is_refused(session_dir, header, says):
    """A header whose bracketed unit is one session.toml does not read the column in,
    of its kind or another (a tachometer's volts, a shunt's millivolts), is refused: read
    as the SI quantity, it would be silently wrong by the unit's factor."""
    if "rpm" not in header.split(",")[1]:
        replace_once(session_dir / "session.toml", 'speed = "rpm"', 'speed = "rad/s"')
    _with_header(session_dir, header)
    text = _refusal(session_dir)
    assert text is not None and "step.csv:header: column" in text and says in text, text


@pytest.mark.parametrize("header", ["t,Speed (2),ia", "t,Speed [filtered],ia",
                                    "t,speed_rpm,Current (1)", "t,Speed (rev),ia",
                                    "t,speed_rpm,Current (S)", "t,speed_rpm,Current (H)",
                                    "t,speed_rpm,Current [A0]"])
def test_a_bracketed_note_that_is_no_unit_is_not_refused(session_dir, header):
    _with_header(session_dir, header)
    assert _refusal(session_dir) is None


@pytest.mark.parametrize(("unit", "hint"), [
    ("s", 's, a thousand times the time the schedule\'s voltage first changes (0.1 s): '
          'is the time column in ms? Then set units.time = "ms"'),
    ("ms", "is the schedule written in seconds?"),  # here between the first two samples
])
def test_a_schedule_a_thousand_times_before_the_motor_starts_is_refused(session_dir,
                                                                         unit, hint):
    """The time column in milliseconds, the schedule's step at 0.1 (seconds): read in
    one unit, the motor starts a thousand times after its step, which a fit would take
    for a dead time of the whole wait; refused with both ways to mend it."""
    toml = session_dir / "session.toml"
    replace_once(toml, 'units = { time = "s",', f'units = {{ time = "{unit}",')
    lines = _rows(session_dir)
    _write(session_dir, [lines[0]] + [",".join([f"{float(line.split(',')[0]) * 1000:g}",
                                                *line.split(",")[1:]]) for line in lines[1:]])
    with pytest.raises(SessionError) as err:
        load_session(session_dir)
    text = str(err.value)
    assert "trace['step'].voltage: the " in text and hint in text
    replace_once(toml, "[0.1, 6.0]", "[100.0, 6.0]")  # the schedule in the column's unit
    assert load_session(session_dir).trace("step").n == STEP_N


def test_a_schedule_on_another_clock_than_the_samples_is_refused(session_dir):
    """The logger's time starts at 12.345 s, the schedule at 0: every change lies before
    the first row, so no step would be seen; refused, where leading rows left out for a
    missed reading are not."""
    lines = _rows(session_dir)
    shifted = [lines[0]] + [",".join([f"{float(line.split(',')[0]) + 12.345:.3f}",
                                      *line.split(",")[1:]]) for line in lines[1:]]
    _write(session_dir, shifted)
    with pytest.raises(SessionError, match="before the first row at 12.345 s"):
        load_session(session_dir)


def test_a_header_in_another_case_is_matched(session_dir):
    lines = _rows(session_dir)
    _write(session_dir, ["T , Speed_RPM ,IA", *lines[1:]])
    assert load_session(session_dir).trace("step").n == STEP_N
    # two columns that differ only in case leave the name to match exactly
    _write(session_dir, ["T,Speed_rpm,SPEED_RPM,ia"] + [
        ",".join([line.split(",")[0], "1", *line.split(",")[1:]]) for line in lines[1:]])
    with pytest.raises(SessionError, match="no column named 'speed_rpm'"):
        load_session(session_dir)


def test_a_schedule_in_seconds_beside_a_time_column_in_milliseconds_is_refused(session_dir):
    """The samples in ms, the schedule still written in s: its step at 0.1 falls between
    the first two samples (0 and 10 ms), where no one schedules a step."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0]] + [",".join([f"{float(line.split(',')[0]) * 1e3:g}",
                                                *line.split(",")[1:]]) for line in lines[1:]])
    replace_once(session_dir / "session.toml", 'time = "s",', 'time = "ms",')
    with pytest.raises(SessionError, match=r"changes only at 0.1 ms, between the first two "
                                           r"samples \(0 and 10 ms\).*units.time\); "
                                           r"write 100 for 0.1 s"):
        load_session(session_dir)
    replace_once(session_dir / "session.toml", "[0.1, 6.0]", "[100.0, 6.0]")
    assert load_session(session_dir).trace("step").n == STEP_N


def test_a_row_logged_twice_is_read_once(session_dir):
    """A row repeated whole, its time included (a logger's repeated write), is read once
    and named among the rows left out; a time repeated with other readings is refused."""
    lines = _rows(session_dir)
    _write(session_dir, lines[:12] + lines[11:12] + lines[11:])  # file line 12 thrice
    tr = load_session(session_dir).trace("step")
    assert tr.n == STEP_N and tr.rows_left_out == (13, 14)
    assert np.all(np.diff(tr.time) > 0)
    cells = lines[11].split(",")
    _write(session_dir, lines[:12] + [",".join([cells[0], "1", cells[2]])] + lines[12:])
    with pytest.raises(SessionError, match="line 13: time column 't' is not strictly increasing"):
        load_session(session_dir)


@pytest.mark.parametrize(("first", "per_second", "refused"), [
    (45413.5, 1 / 86400, True),  # a spreadsheet's date serial: days since 1899-12-30
    (1714571587.0, 1.0, False),  # epoch seconds
    (45413.5, 1.0, False),  # seconds since the logger started, 12.6 hours before
])
def test_a_time_column_written_as_a_date_serial_is_refused(session_dir, first, per_second,
                                                           refused):
    lines = _rows(session_dir)
    rows = [",".join([repr(first + float(line.split(",")[0]) * per_second),
                      *line.split(",")[1:]]) for line in lines[1:]]
    _write(session_dir, [lines[0], *rows])
    text = _refusal(session_dir) or ""
    assert ("reads as a spreadsheet's date serial" in text
            and "45413.5 is 2024-05-01 12:00:00" in text) is refused, text


@pytest.mark.parametrize(("first", "interval", "per_second", "refused"), [
    (45413.5, 0.1, 1 / 86400, True),  # a slow logger's date serial: 0.1 s apart as days
    (45413.5, 1e-3, 1 / 86400, True),
    (30000.0, 1e-7, 1.0, False),  # a fast DAQ's seconds since it started, 10 MS/s
    (45413.5, 1e-3, 1.0, False),  # seconds, 12.6 hours after the logger started
])
def test_a_date_serial_is_told_from_seconds_by_its_round_sample_interval(first, interval,
                                                                          per_second, refused):
    from pmdc_bayes.io._time_order import check_date_serial

    t_raw = first + np.arange(500) * interval * per_second
    try:
        check_date_serial(Path("t.csv"), "t", t_raw, 1.0)
    except SessionError as err:
        assert refused and "date serial" in str(err)
    else:
        assert not refused


def _clock(seconds: int) -> str:
    return f"12:{seconds // 60:02d}:{seconds % 60:02d}"


def _millis_as_decimals(ms: int) -> str:
    """``micros() / 1000.0`` as an Arduino prints it: milliseconds to two decimals, each
    a few microseconds late."""
    return f"{ms + 0.004 * (ms % 7):.2f}"


@pytest.mark.parametrize(("unit", "header", "written", "step", "said"), [
    ("", "t", str, None, "holds whole numbers 10 apart"),
    ("", "t", "{:.1f}".format, None, "holds numbers 10 apart (the median)"),
    ("", "t", _millis_as_decimals, None, "holds numbers 10 apart (the median)"),
    ('time = "ms", ', "t", str, 0.01, ""), ("", "t [s]", str, 10.0, ""),
    ("", "time_s", str, 10.0, ""),
    ('time = "s", ', "t", "{:.1f}".format, 10.0, ""), ("", "t", _clock, 10.0, ""),
])
def test_plain_numbers_far_apart_in_a_time_column_without_a_unit_are_not_read_as_seconds(
        session_dir, unit, header, written, step, said):
    """A logger's millisecond counter (0, 10, 20, ...), or its milliseconds written as
    decimals (10.0, 20.04), under a header that names no unit, with none in
    session.toml, read as seconds would make every time constant a thousand times too
    long: it is refused, naming the key to add; given a unit in session.toml or the
    header, it is read in it.  Clock times (12:00:10) are read as written."""
    lines = _rows(session_dir)
    _write(session_dir, [header + ",speed_rpm,ia"]
           + [",".join([written(10 * k), *line.split(",")[1:]])
              for k, line in enumerate(lines[1:])])
    toml = session_dir / "session.toml"
    replace_once(toml, 'columns = { time = "t",', f'columns = {{ time = "{header}",')
    replace_once(toml, 'units = { time = "s", ', f"units = {{ {unit}")
    replace_once(toml, "[[0.0, 0.0], [0.1, 6.0]]", "[[0.0, 0.0], [100.0, 6.0]]")
    if step is not None:
        assert load_session(session_dir).trace("step").time[1] == pytest.approx(step, rel=1e-3)
        return
    with pytest.raises(SessionError) as err:
        load_session(session_dir)
    assert (f"step.csv:header: the time column 't' gives no unit and {said}" in str(err.value)
            and "set trace['step'].units.time = \"ms\"" in str(err.value))


@pytest.mark.parametrize(("unit", "scale", "refused"), [
    ("", 1000.0, True), ('voltage = "mV", ', 1000.0, False), ("", 1.0, False),
    ('voltage = "V", ', 1000.0, False),
])
def test_a_voltage_column_of_thousands_without_a_unit_is_not_read_as_volts(
        session_dir, unit, scale, refused):
    """A 6 V step logged in millivolts (6000) under a header that names no unit, with
    none in session.toml, would read as 6 kV: it is refused, naming the key to add;
    given a unit, it is read in it (a kilovolt when the session says so)."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0] + ",va"] + [
        line + "," + repr(scale * (6.0 if float(line.split(",")[0]) >= 0.1 else 0.0))
        for line in lines[1:]])
    toml = session_dir / "session.toml"
    replace_once(toml, 'current = "ia" }', 'current = "ia", voltage = "va" }')
    replace_once(toml, 'voltage = [[0.0, 0.0], [0.1, 6.0]]\n', "")
    replace_once(toml, 'current = "A", voltage = "V" }', f'current = "A", {unit}}}'.replace(
        ", }", " }"))
    if refused:
        with pytest.raises(SessionError) as err:
            load_session(session_dir)
        assert ("step.csv:header: the voltage column 'va' gives no unit and reads up to "
                "6000" in str(err.value))
        assert "set trace['step'].units.voltage = \"mV\"" in str(err.value)
        return
    v = load_session(session_dir).trace("step").voltage.values
    want = 6.0 * (1000.0 if unit.endswith('"V", ') and scale > 1 else 1.0)
    assert v.max() == pytest.approx(want)


@pytest.mark.parametrize(("written", "unit", "refused"), [
    ("255", "", True), ("100", "", True), ("255", 'voltage = "pwm", ', False),
    ("60", 'voltage = "V", ', False), ("60.13", "", False), ("24", "", False),
])
def test_whole_numbers_up_to_a_pwm_timers_full_scale_are_not_read_as_volts(
        session_dir, written, unit, refused):
    """A step logged as ``analogWrite``'s counts (0 then 255) or a duty in per cent
    (100), under a header naming no unit and none in session.toml, would read as a
    255 V or 100 V supply: refused, naming the PWM unit and its full scale; stated as
    counts (with their supply) or as volts, or read as an analogue voltage's readings
    (not all whole) or a low voltage's, it is read."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0] + ",va"] + [
        line + "," + (written if float(line.split(",")[0]) >= 0.1 else "0")
        for line in lines[1:]])
    toml = session_dir / "session.toml"
    replace_once(toml, 'current = "ia" }', 'current = "ia", voltage = "va" }')
    replace_once(toml, 'voltage = [[0.0, 0.0], [0.1, 6.0]]\n',
                 "supply_voltage = 12.0\npwm_full_scale = 255\n" if "pwm" in unit else "")
    replace_once(toml, 'current = "A", voltage = "V" }', f'current = "A", {unit}}}'.replace(
        ", }", " }"))
    if refused:
        with pytest.raises(SessionError) as err:
            load_session(session_dir)
        said = str(err.value)
        assert (f"step.csv:header: the voltage column 'va' gives no unit and reads only "
                f"whole numbers, up to {written}" in said)
        assert f"units.voltage = \"pwm\" with pwm_full_scale = {written} " in said
        return
    v = load_session(session_dir).trace("step").voltage.values
    assert v.max() == pytest.approx(12.0 if "pwm" in unit else float(written))


@pytest.mark.parametrize(("unit", "to_counts", "refused"), [
    ("", lambda a: round(512 + 37.8 * a), True), ("", lambda a: round(1000 * a), True),
    ('current = "mA", ', lambda a: round(1000 * a), False),
    ("", lambda a: round(a, 4), False), ("", lambda a: round(40 * a), False),
])
def test_a_current_column_of_counts_is_not_read_as_amperes(session_dir, unit, to_counts,
                                                            refused):
    """A current logged as an ADC's counts (a Hall sensor's 512 at zero, 37.8 counts an
    ampere) or as whole milliamperes, under a header naming no unit and none in
    session.toml, would read as hundreds of amperes: refused, naming the units to give;
    stated, or read as an analogue sensor's readings or as whole amperes below 100, it is
    read."""
    lines = _rows(session_dir)
    _write(session_dir, [lines[0]] + [
        ",".join([*line.split(",")[:2], str(to_counts(float(line.split(",")[2])))])
        for line in lines[1:]])
    replace_once(session_dir / "session.toml", 'current = "A", voltage = "V" }',
                 f'{unit}voltage = "V" }}')
    if refused:
        with pytest.raises(SessionError) as err:
            load_session(session_dir)
        said = str(err.value)
        assert "step.csv:header: the current column 'ia' gives no unit and reads only " \
            "whole numbers, up to " in said
        assert "set trace['step'].units.current = \"mA\"" in said
        return
    ia = load_session(session_dir).trace("step").current
    want = [float(to_counts(float(line.split(",")[2]))) for line in lines[1:]]
    assert ia == pytest.approx(np.asarray(want) * (1e-3 if "mA" in unit else 1.0))


def test_a_steady_table_of_whole_counts_is_not_read_as_volts(session_dir):
    """A steady table's voltage column of a PWM timer's counts (64, 128, 255) under a
    header naming no unit: refused, asking for volts (a table reads no duty)."""
    (session_dir / "sweep.csv").write_text("Va,w\n64,10.0\n128,30.0\n255,50.0\n")
    replace_once(session_dir / "session.toml", 'units = { voltage = "V", speed = "rad/s" }',
                 'units = { speed = "rad/s" }')
    with pytest.raises(SessionError) as err:
        load_session(session_dir)
    said = str(err.value)
    assert "sweep.csv:header: the voltage column 'Va' gives no unit and reads only whole " \
        "numbers, up to 255" in said
    assert "convert them to volts" in said and "pwm" not in said


@pytest.mark.parametrize(("units", "header", "refused"), [
    ('units = { speed = "rad/s" }', "Va,w", True),
    ('units = { voltage = "mV", speed = "rad/s" }', "Va,w", False),
    ('units = { speed = "rad/s" }', "Va [V],w", False),
])
def test_a_steady_table_of_millivolts_without_a_unit_is_not_read_as_kilovolts(
        session_dir, units, header, refused):
    """A steady table's voltages logged in millivolts under a header naming no unit, with
    none in session.toml, would read as kilovolts: refused, naming the table's key to add
    (and no PWM duty, which a table does not read); with a unit, in session.toml or its
    header, they are read in it (kilovolts when the header says volts)."""
    (session_dir / "sweep.csv").write_text(f"{header}\n2000,10.0\n4000,30.0\n6000,50.0\n")
    replace_once(session_dir / "session.toml", 'units = { voltage = "V", speed = "rad/s" }',
                 units)
    replace_once(session_dir / "session.toml", 'voltage = "Va", speed = "w"',
                 f'voltage = "{header.split(",")[0]}", speed = "w"')
    if refused:
        with pytest.raises(SessionError) as err:
            load_session(session_dir)
        said = str(err.value)
        assert "sweep.csv:header: the voltage column 'Va' gives no unit and reads up to 6000" \
            in said
        assert "set steady_table['sweep'].units.voltage = \"mV\" (or \"V\" if" in said
        assert "pwm" not in said
        return
    table = load_session(session_dir).steady_tables[0]
    scale = 1.0 if "mV" in units else 1000.0
    assert table.voltage == pytest.approx([2.0 * scale, 4.0 * scale, 6.0 * scale])


def _serial_log(path, first: str | None = None, prefix=lambda k: "") -> list[str]:
    """An Arduino's serial log of millis() and a speed, 20 rows from 3207 ms, its first
    row written as ``first`` when given; each line behind ``prefix(k)``."""
    rows = [f"{3207 + 10 * k},{0.5 * k:.2f}" for k in range(20)]
    if first is not None:
        rows[0] = first
    lines = ["ms,rpm", *rows]
    path.write_text("".join(prefix(k) + ln + "\n" for k, ln in enumerate(lines)))
    return lines


@pytest.mark.parametrize("first", ["0.00", "7,0.00", "07,0.00"])
def test_a_first_line_cut_at_its_start_is_left_out(tmp_path, first):
    """A serial monitor opened while the logger was writing a line: the first row is
    its tail (fewer fields, or a time cut short: ``7`` of ``3207``), not a sample; it is
    left out, where read as one it made a gap of three seconds before the record."""
    from pmdc_bayes.io._csv import read_columns

    path = tmp_path / "log.csv"
    _serial_log(path, first)
    read = read_columns(path, {"time": "ms", "speed": "rpm"}, asked_by="test")
    assert read.skipped == (2,) and read.lines[0] == 3
    np.testing.assert_allclose(read.values["time"], 3217 + 10 * np.arange(19))
    _serial_log(path)  # the whole first line is a sample
    whole = read_columns(path, {"time": "ms", "speed": "rpm"}, asked_by="test")
    assert whole.skipped == () and whole.values["time"][0] == 3207


def test_a_first_time_past_a_counter_s_new_digit_is_kept(tmp_path):
    """``999`` then ``1009``: written shorter, but one interval before the next: a
    counter gaining a digit, not a cut line."""
    from pmdc_bayes.io._csv import read_columns

    path = tmp_path / "log.csv"
    path.write_text("ms,rpm\n" + "".join(f"{999 + 10 * k},1.0\n" for k in range(10)))
    read = read_columns(path, {"time": "ms", "speed": "rpm"}, asked_by="test")
    assert read.skipped == () and read.values["time"][0] == 999


def test_a_serial_monitor_s_arrival_times_are_read_past(tmp_path):
    """The Arduino IDE's "Show timestamp" writes the computer's time of arrival before
    every line (``14:05:11.010 -> ``): the logger's own columns are read behind it."""
    from pmdc_bayes.io._csv import read_columns

    path = tmp_path / "log.csv"
    _serial_log(path, prefix=lambda k: f"14:05:{11 + k // 100:02d}.{10 * k % 1000:03d} -> ")
    read = read_columns(path, {"time": "ms", "speed": "rpm"}, asked_by="test")
    np.testing.assert_allclose(read.values["time"], 3207 + 10 * np.arange(20))
    np.testing.assert_allclose(read.values["speed"], 0.5 * np.arange(20))
