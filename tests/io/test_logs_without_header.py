"""Trace files without a header of names: columns given by their field number (a
logger that writes bare rows, an oscilloscope's export with its settings in the first
fields), ``name=value`` lines as a microcontroller's serial prints write them, JSON
lines, and a header in Windows-1252.  Each is read to the same arrays as the plain
file with a header; what the file cannot answer is refused with one line."""

import numpy as np
import pytest
from conftest import STEP_N, replace_once

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session

COLUMNS = 'columns = { time = "t", speed = "speed_rpm", current = "ia" }'


def _rows(d):
    return (d / "step.csv").read_text().splitlines()


def _write(d, lines):
    (d / "step.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def _arrays(d):
    tr = load_session(d).trace("step")
    return tr.time, tr.speed, tr.current


def _same(a, b):
    return all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


@pytest.mark.parametrize("sep", [",", ";", "\t", " "])
def test_columns_given_by_field_number_read_a_file_without_header(session_dir, sep):
    plain = _arrays(session_dir)
    lines = _rows(session_dir)[1:]
    if sep == ";":  # a spreadsheet's locale: decimal commas between semicolons
        lines = [line.replace(",", ";").replace(".", ",") for line in lines]
    else:
        lines = [line.replace(",", sep) for line in lines]
    _write(session_dir, lines)
    replace_once(session_dir / "session.toml", COLUMNS,
                 "columns = { time = 1, speed = 2, current = 3 }")
    assert _same(_arrays(session_dir), plain)


def test_an_oscilloscope_export_with_settings_in_the_first_fields(session_dir):
    """Settings in fields 1-3 of the first rows, the samples in fields 4-6 of every
    row; a header line above them is passed over when the columns are numbered."""
    plain = _arrays(session_dir)
    lines = _rows(session_dir)
    settings = ["Record Length,151,", "Sample Interval,0.01,s", "Trigger Point,10,Samples"]
    out = [",,," + lines[0]]
    for k, line in enumerate(lines[1:]):
        out.append((settings[k] if k < len(settings) else ",,") + "," + line)
    _write(session_dir, out)
    replace_once(session_dir / "session.toml", COLUMNS,
                 "columns = { time = 4, speed = 5, current = 6 }")
    assert _same(_arrays(session_dir), plain)


def test_an_export_whose_settings_share_the_sample_fields_passes_them_over(session_dir):
    """A scope's settings written in the fields the samples use (``Record Length,151``:
    a word beside a number) are passed over, not read as a first sample, nor refused;
    a line whose fields are all numbers is the first sample."""
    plain = _arrays(session_dir)
    lines = _rows(session_dir)[1:]
    settings = ["Record Length,151,", "Sample Interval,0.01,s", "Trigger Point,0,",
                "Source,CH1,CH2", "Units,s,rpm A"]
    _write(session_dir, settings + lines)
    replace_once(session_dir / "session.toml", COLUMNS,
                 "columns = { time = 1, speed = 2, current = 3 }")
    assert _same(_arrays(session_dir), plain)


@pytest.mark.parametrize(("columns", "match"), [
    ('{ time = 1, speed = "speed_rpm", current = 3 }', "mixes header names and field numbers"),
    ("{ time = 0, speed = 2, current = 3 }", "count the fields from 1"),
    ("{ time = 1, speed = 2, current = 7 }", "the row has 3 fields, and field 7 is asked for"),
])
def test_field_numbers_the_file_cannot_answer_are_refused(session_dir, columns, match):
    _write(session_dir, _rows(session_dir)[1:])
    replace_once(session_dir / "session.toml", COLUMNS, f"columns = {columns}")
    with pytest.raises(SessionError, match=match):
        load_session(session_dir)


def _pairs(lines, fmt):
    out = []
    for line in lines[1:]:
        t, w, i = line.split(",")
        out.append(fmt.format(t=t, w=w, i=i))
    return out


@pytest.mark.parametrize("fmt", [
    "t={t} s speed_rpm={w} rpm ia={i} A",  # Serial.print with the units after the values
    "t={t}s speed_rpm={w}rpm ia={i}A",  # ... and against them
    "t: {t}, speed_rpm: {w}, ia: {i}",
    '{{"t": {t}, "speed_rpm": {w}, "ia": {i}, "state": "run"}}',  # JSON lines
    "[log] 12:00:01 t={t}\tspeed_rpm={w}\tia={i}",
])
def test_name_value_lines_are_read_as_rows(session_dir, fmt):
    plain = _arrays(session_dir)
    lines = _pairs(_rows(session_dir), fmt)
    _write(session_dir, ["# motor test, firmware 1.2", "starting...", *lines, "done"])
    assert _same(_arrays(session_dir), plain)


def test_a_name_value_number_is_not_split_into_a_value_and_a_unit():
    """Scientific notation and an overrange code stay numbers; a suffix that names no
    unit (a hex value, a date) leaves the value whole, to be refused, never read short."""
    from pmdc_bayes.io._key_values import _pairs

    pairs = _pairs("t=12ms w=1.5e3 x=9.9E37 h=0x1F d=20240105T120001 ia=0.41A")
    assert pairs["t"] == ("12", "ms") and pairs["ia"] == ("0.41", "A")
    assert pairs["w"] == ("1.5e3", "") and pairs["x"] == ("9.9E37", "")
    assert pairs["h"] == ("0x1F", "") and pairs["d"] == ("20240105T120001", "")
    commas = _pairs("t=12,5ms speed=153,2rpm ia=0,41 A w=3,5")
    assert commas["t"] == ("12,5", "ms") and commas["speed"] == ("153,2", "rpm")
    assert commas["ia"] == ("0,41", "A") and commas["w"] == ("3,5", "")


def test_name_value_lines_with_a_reading_missed_or_a_unit_against_the_session(session_dir):
    lines = _pairs(_rows(session_dir), "t={t} s speed_rpm={w} rpm ia={i} A")
    lines[40] = lines[40].split(" ia=")[0]  # the current not printed on file line 41
    _write(session_dir, lines)
    tr = load_session(session_dir).trace("step")
    assert tr.rows_left_out == (41,) and tr.n == STEP_N - 1
    for glue in (" ", ""):
        _write(session_dir, [line.replace(" s ", f"{glue}ms ") for line in lines])
        with pytest.raises(SessionError, match=r"step.csv:line 1: the row of units gives "
                                               r"column 't' in 'ms'.*units.time = \"ms\""):
            load_session(session_dir)


def test_a_header_written_in_windows_1252_is_read(session_dir):
    plain = _arrays(session_dir)
    lines = _rows(session_dir)
    text = "\n".join(["t [\u00b5s]," + lines[0].split(",", 1)[1]] + [
        ",".join([str(round(float(line.split(",")[0]) * 1e6)), *line.split(",")[1:]])
        for line in lines[1:]]) + "\n"
    (session_dir / "step.csv").write_bytes(text.encode("cp1252"))
    toml = session_dir / "session.toml"
    replace_once(toml, 'time = "t",', 'time = "t [\u00b5s]",')
    replace_once(toml, 'time = "s",', 'time = "us",')
    replace_once(toml, "voltage = [[0.0, 0.0], [0.1, 6.0]]", "voltage = [[0.0, 0.0], [1e5, 6.0]]")
    time, speed, current = _arrays(session_dir)
    assert np.allclose(time, plain[0], rtol=0, atol=1e-12)
    assert np.array_equal(speed, plain[1]) and np.array_equal(current, plain[2])


def test_a_steady_table_without_header(session_dir):
    plain = load_session(session_dir).steady_tables[0]
    (session_dir / "sweep.csv").write_text("2.0,10.0\n4.0,30.0\n6.0,50.0\n")
    replace_once(session_dir / "session.toml", 'columns = { voltage = "Va", speed = "w" }',
                 "columns = { voltage = 1, speed = 2 }")
    table = load_session(session_dir).steady_tables[0]
    assert np.array_equal(table.voltage, plain.voltage)
    assert np.array_equal(table.speed, plain.speed)


def test_a_file_without_header_read_by_names_says_to_number_the_fields(session_dir):
    _write(session_dir, _rows(session_dir)[1:])
    with pytest.raises(SessionError, match=r"step.csv:line 1: no header: line 1 holds numbers "
                                           r"\('0.00', .*give every column as its field number"):
        load_session(session_dir)


def test_name_value_lines_read_the_names_asked_for_and_not_their_look_alikes(session_dir):
    """A pair whose name differs only in case (a power ``W`` beside the speed ``w``) is
    another column; a comment line holding pairs is no sample; a decimal comma is read."""
    plain = _arrays(session_dir)
    lines = _pairs(_rows(session_dir), "t={t} w={w} ia={i} W={i}0 IA=7")
    _write(session_dir, ["# t=0 w=500 ia=9", *lines])
    replace_once(session_dir / "session.toml", COLUMNS,
                 'columns = { time = "t", speed = "w", current = "ia" }')
    assert _same(_arrays(session_dir), plain)
    _write(session_dir, [line.replace(".", ",") for line in lines])
    assert _same(_arrays(session_dir), plain)


def test_a_header_of_names_and_units_is_not_read_as_pairs(session_dir):
    lines = _rows(session_dir)
    _write(session_dir, ["t:s,speed_rpm:rpm,ia:A", *lines[1:]])
    with pytest.raises(SessionError, match="no column named 't'"):
        load_session(session_dir)


def test_a_stray_windows_1252_byte_leaves_the_utf8_names_as_written(session_dir):
    plain = _arrays(session_dir)
    lines = _rows(session_dir)
    text = ("Temp 25\u00b0C".encode("cp1252") + b"\n"
            + "\n".join(["speed_rpm [\u00b5]," + lines[0].split(",", 1)[0] + ",ia",
                         *[",".join([ln.split(",")[1], ln.split(",")[0], ln.split(",")[2]])
                           for ln in lines[1:]]]).encode("utf-8") + b"\n")
    (session_dir / "step.csv").write_bytes(text)
    replace_once(session_dir / "session.toml", 'speed = "speed_rpm"',
                 'speed = "speed_rpm [\u00b5]"')
    assert _same(_arrays(session_dir), plain)


def test_a_short_row_in_a_file_without_header_is_named_as_such(session_dir):
    lines = _rows(session_dir)[1:]
    lines[40] = lines[40].rsplit(",", 1)[0]  # file line 41 without its current
    _write(session_dir, lines)
    replace_once(session_dir / "session.toml", COLUMNS,
                 "columns = { time = 1, speed = 2, current = 3 }")
    with pytest.raises(SessionError, match="line 41: the row has 2 fields but column 'field 3'"):
        load_session(session_dir)
