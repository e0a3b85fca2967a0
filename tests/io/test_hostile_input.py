"""Awkward files as spreadsheets, editors and loggers write them, through the command line.

Some are read correctly (a semicolon or tab separator with decimal commas, UTF-16 from
Excel's "Unicode text", byte-order marks); the others end in one line naming the file,
the place and the fix, exit code 2, never a traceback or a silently wrong number.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import replace_once, set_csv_cell

TOML = "session.toml"


def _run(pmdc, path, *extra):
    return pmdc("closed-form", path, *extra, timeout=120)


def _step_text(d):
    return (d / "step.csv").read_text(encoding="utf-8")


def _resave(sep=",", decimal=".", encoding="utf-8"):
    """Rewrite step.csv with another separator, decimal mark or encoding."""

    def mutate(d):
        text = _step_text(d).replace(",", "\0").replace(".", decimal).replace("\0", sep)
        (d / "step.csv").write_bytes(text.encode(encoding))

    return mutate


def _toml_bom(d):
    (d / TOML).write_bytes(b"\xef\xbb\xbf" + (d / TOML).read_bytes())


def _around(before=(), after_header=(), after=(), sep=None):
    """Rewrite step.csv as a logger writes it: lines before the header, under it and
    after the last sample (and columns separated by ``sep``)."""

    def mutate(d):
        header, *rows = _step_text(d).splitlines()
        lines = [*before, header, *after_header, *rows, *after]
        text = "\n".join(lines) + "\n"
        (d / "step.csv").write_text(text if sep is None else text.replace(",", sep))

    return mutate


def _header_as_comment(d):
    """The header written as a comment, as NumPy's ``savetxt(..., header=...)`` does."""
    header, *rows = _step_text(d).splitlines()
    (d / "step.csv").write_text("\n".join([f"# {header}", *rows]) + "\n")


ACCEPTED = [
    ("semicolon-decimal-comma", _resave(";", ",")),
    ("numpy-savetxt-header", _header_as_comment),
    ("tab-separated", _resave("\t")),
    ("tab-decimal-comma", _resave("\t", ",")),
    ("utf-16-excel-unicode-text", _resave("\t", encoding="utf-16")),
    ("utf-8-bom-csv", _resave(encoding="utf-8-sig")),
    ("utf-8-bom-session-toml", _toml_bom),
    ("space-separated", _around(sep="   ")),
    ("logger-preamble", _around(before=("Logger v2.1 (serial 1234)", "Date: 2026-01-05",
                                        "", "rate: 200 Hz"))),
    ("units-row", _around(after_header=("s,rpm,A",))),
    ("oscilloscope-export", _around(after_header=("(s),(rpm),(A)", ""))),
    ("closing-lines", _around(after=("End of log", "", "samples: 301"))),
    ("preamble-units-and-semicolons", _around(before=("DAQ export;v3",),
                                              after_header=("s;rpm;A",), sep=";")),
]


@pytest.mark.parametrize("mutate", [c[1] for c in ACCEPTED], ids=[c[0] for c in ACCEPTED])
def test_files_as_spreadsheets_save_them_are_read_the_same(session_dir, tmp_path, mutate, pmdc):
    expected = _run(pmdc, session_dir, "--json")
    assert expected.returncode == 0, expected.stderr
    mutate(session_dir)
    proc = _run(pmdc, session_dir, "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == json.loads(expected.stdout)


def _write(name, data: bytes):
    def mutate(d):
        (d / name).write_bytes(data)

    return mutate


def _edit(file, old, new):
    def mutate(d):
        replace_once(d / file, old, new)

    return mutate


def _decimal_comma_with_commas(d):
    text = _step_text(d).splitlines()
    rows = [text[0]] + [ln.replace(".", ",") for ln in text[1:]]
    (d / "step.csv").write_text("\n".join(rows) + "\n")


def _dir_for_file(d):
    (d / "step.csv").unlink()
    (d / "step.csv").mkdir()


def _symlink_loop(d):
    (d / "step.csv").unlink()
    (d / "step.csv").symlink_to(d / "step.csv")


def _huge_cell(d):
    lines = _step_text(d).splitlines()
    lines[3] = "0.02," + "1" * 200_000 + ",0.5"
    (d / "step.csv").write_text("\n".join(lines) + "\n")


STEP_READING = '\n[[step_reading]]\nname = "sr"\nvoltage = 6.0\nfinal_speed = 100.0\n'

REFUSED = [
    ("binary-named-csv", _write("step.csv", bytes(range(256)) * 4),
     ["step.csv", "binary file"]),
    ("cell-over-field-limit", _huge_cell, ["step.csv:line 4", "field limit"]),
    ("directory-for-csv", _dir_for_file, ["step.csv", "a directory, not a file"]),
    ("symlink-loop-for-csv", _symlink_loop, ["step.csv", "points back to itself"]),
    ("duplicate-header-name", _edit("step.csv", "t,speed_rpm,ia", "t,speed_rpm,speed_rpm"),
     ["step.csv:line 1", "'speed_rpm' more than once"]),
    ("comma-decimals-with-comma-separator", _decimal_comma_with_commas,
     ["step.csv:line 2", "the row has 6 fields but the header has 3", "decimal separator"]),
    ("text-between-samples", _edit("step.csv", "0.10,", "paused\n0.10,"),
     ["step.csv:line 12", "column 't': 'paused' is not a number"]),
    ("time-stamps-among-numbers", _edit("step.csv", "\n0.10,", "\n12:00:00.100,"),
     ["step.csv:line 12", "'12:00:00.100' is written unlike the rows before it"]),
    ("clock-time-for-a-speed",
     lambda d: set_csv_cell(d / "step.csv", 12, "speed_rpm", "12:00:00.100"),
     ["step.csv:line 12", "'12:00:00.100' is not a number; a clock time?"]),
    ("two-rows-of-units", _around(after_header=("s,rpm,A", "sec,rpm,amp")),
     ["step.csv:line 3", "'sec' is not a number"]),
    ("no-line-names-the-columns", _edit("step.csv", "t,speed_rpm,ia", "time,speed,current"),
     ["step.csv:line 1", "no column named 't'"]),
    ("latin-1-session-toml", lambda d: (d / TOML).write_bytes(
        (d / TOML).read_text().replace("Test motor", "Moteur d'essai \xe9").encode("latin-1")),
     [f"{TOML}:line 2", "not UTF-8"]),
    ("toml-integer-too-large", _edit(TOML, "supply_voltage = 12.0",
                                     "supply_voltage = " + "9" * 400),
     [f"{TOML}:operating_point['op'].supply_voltage", "too large"]),
    ("nul-byte-inside", lambda d: (d / "step.csv").write_text(
        _step_text(d).replace("0.10,", "0.1\x000,")), ["step.csv:line 12", "NUL byte"]),
    ("unclosed-quote", _edit("step.csv", "0.10,", '"0.10,'),
     ["step.csv:line 12", "never closed", "remove the quote"]),
    ("empty-cell-named", _edit("step.csv", "0.10,", ","), ["step.csv:line 12",
                                                          "column 't' is empty"]),
    ("dangling-symlink", lambda d: ((d / "step.csv").unlink(),
                                    (d / "step.csv").symlink_to(d / "gone.csv")),
     ["step.csv", "a symbolic link to", "gone.csv, which does not exist"]),
    ("session-toml-symlink-loop", lambda d: ((d / TOML).unlink(),
                                             (d / TOML).symlink_to(d / TOML)),
     [TOML, "points back to itself"]),
    ("step-after-the-last-sample", _edit(TOML, "voltage = [[0.0, 0.0], [0.1, 6.0]]",
                                         "voltage = [[0.0, 0.0], [30.0, 6.0]]"),
     [f"{TOML}:trace['step'].voltage", "changes at 30 s, after the last sample at 1.5 s"]),
    ("reversed-speed-sign", lambda d: (d / "step.csv").write_text(
        "\n".join([ln if i == 0 else ",".join([c if k != 1 else f"-{c}"
                                               for k, c in enumerate(ln.split(","))])
                   for i, ln in enumerate(_step_text(d).splitlines())]) + "\n"),
     ["step.csv", "speed sensor is wired the other way round", "negate this file's speed"]),
    ("operating-point-speed-unit-slip", _edit(TOML, "speed = 100.0", "speed = 954.9"),
     ["step.csv", "trace 'step' settles at", "rpm given as rad/s"]),
    # physically impossible closed-form results, named with the inputs that cause them
    ("closed-form-K-negative", _edit(TOML, "current = 0.3", "current = 3.5"),
     [f"{TOML}:operating_point", "K = -0.01 ", "Ra*Ia reaches the applied voltage"]),
    ("closed-form-K-rounded-to-zero", _edit(TOML, "[[operating_point]]",
                                            "[closed_form]\nK_decimals = 0\n\n"
                                            "[[operating_point]]"),
     [f"{TOML}:operating_point", "K = 0", "K_decimals"]),
    ("step-reading-tau-absurd", lambda d: (d / TOML).write_text(
        (d / TOML).read_text() + STEP_READING + "tau = 1e-300\n"),
     [f"{TOML}:step_reading", "1e-300 s", "electrical time constant"]),
]


@pytest.mark.parametrize(("mutate", "expected"), [c[1:] for c in REFUSED],
                         ids=[c[0] for c in REFUSED])
def test_unreadable_or_impossible_input_is_one_line(session_dir, mutate, expected, pmdc):
    mutate(session_dir)
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    (line,) = proc.stderr.splitlines()
    assert line.startswith("pmdc-bayes: error: ") and "; " in line, line
    for text in expected:
        assert text in line, f"{text!r} not in {line!r}"


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
def test_an_unreadable_csv_is_one_line(session_dir, pmdc):
    (session_dir / "step.csv").chmod(0)
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2 and "permission denied" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_a_file_over_the_size_limit_is_refused_before_it_is_read(session_dir, monkeypatch):
    from pmdc_bayes._errors import SessionError
    from pmdc_bayes.io import text
    from pmdc_bayes.io.loader import load_session

    monkeypatch.setattr(text, "MAX_BYTES", 1000)
    with pytest.raises(SessionError, match=r"step.csv: the file is 0.00\d+ MB, more .* decimate"):
        load_session(session_dir)


def test_a_closed_pipe_is_not_an_error(session_dir):
    proc = subprocess.run(f"{sys.executable} -m pmdc_bayes closed-form {session_dir} | head -1",
                          shell=True, capture_output=True, text=True, timeout=120)
    assert proc.stdout.startswith("Closed-form identification")
    assert proc.stderr == ""


@pytest.mark.parametrize(("reading", "expected"), [
    ("voltage = 0.0\nfinal_speed = 100.0\ntau = 0.2\n", "step_reading['sr'].voltage: is 0"),
    ("voltage = 6.0\nfinal_speed = 0.0\ntau = 0.2\n", "final_speed: equals the initial"),
])
def test_a_step_reading_that_is_no_step_is_one_line(session_dir, reading, expected, pmdc):
    with (session_dir / TOML).open("a") as fh:
        fh.write('\n[[step_reading]]\nname = "sr"\n' + reading)
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2 and expected in proc.stderr, proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_unknown_loads_name_driven_traces(session_dir, pmdc):
    from pmdc_bayes.io.loader import load_session

    with (session_dir / TOML).open("a") as fh:
        fh.write('\n[model]\nunknown_load = ["step"]\n')
    session = load_session(session_dir)
    assert session.unknown_load_traces() == ("step",) and "unknown_load" in session.nuisances
    replace_once(session_dir / TOML, 'unknown_load = ["step"]', 'unknown_load = ["stepp"]')
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1
    assert "model.unknown_load: expected true, false, a list of driven trace names (of " \
        "'step') or a table of them" in proc.stderr
    replace_once(session_dir / TOML, 'unknown_load = ["stepp"]', "unknown_load = true")
    assert load_session(session_dir).unknown_load_traces() == ("step",)


def test_an_unknown_load_may_name_the_part_of_the_drag_to_fit(session_dir, pmdc):
    from pmdc_bayes.inference.model.nuisances import nuisance_specs
    from pmdc_bayes.io.loader import load_session

    with (session_dir / TOML).open("a") as fh:
        fh.write('\n[model]\nunknown_load = { step = "viscous" }\n')
    session = load_session(session_dir)
    assert session.unknown_load_traces() == ("step",) and session.load_kind("step") == "viscous"
    names = [p.name for p in nuisance_specs(session, b_seed=1e-5)]
    assert "drag_step" in names and "load_step" not in names
    replace_once(session_dir / TOML, '{ step = "viscous" }', '{ step = "constant" }')
    names = [p.name for p in nuisance_specs(load_session(session_dir), b_seed=1e-5)]
    assert "load_step" in names and "drag_step" not in names
    for bad, says in (('{ step = "eddy" }', 'model.unknown_load.step: expected one of both, '
                       'constant, viscous, got the string \'eddy\''),
                      ('{ stepp = "viscous" }', "model.unknown_load.stepp: names no driven "
                       "trace (of 'step')")):
        text = (session_dir / TOML).read_text()
        start = text.index("unknown_load = ")
        end = text.index("\n", start)
        (session_dir / TOML).write_text(text[:start] + f"unknown_load = {bad}" + text[end:])
        proc = _run(pmdc, session_dir)
        assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
        assert says in proc.stderr, proc.stderr


def test_comment_lines_are_skipped_and_keep_line_numbers(session_dir, pmdc):
    expected = _run(pmdc, session_dir, "--json")
    text = _step_text(session_dir)
    (session_dir / "step.csv").write_text("# scope log 3\n# 1 kHz\n" + text)
    proc = _run(pmdc, session_dir, "--json")
    assert proc.returncode == 0 and json.loads(proc.stdout) == json.loads(expected.stdout)
    replace_once(session_dir / "step.csv", "0.10,", "x,")
    assert "step.csv:line 14" in _run(pmdc, session_dir).stderr


def test_a_file_for_the_session_and_a_bad_option_are_one_line(session_dir, pmdc):
    proc = _run(pmdc, session_dir / "step.csv")
    assert proc.returncode == 2 and "pass the session directory" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1
    proc = pmdc("fit", "--seed", "-1", timeout=120)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert "--seed" in proc.stderr and "--help" in proc.stderr


def test_a_declared_load_at_the_operating_point_enters_equation_19(session_dir, pmdc):
    base = json.loads(_run(pmdc, session_dir, "--json").stdout)
    replace_once(session_dir / TOML, "current = 0.3", "current = 0.3\nload_torque = 0.002")
    loaded = json.loads(_run(pmdc, session_dir, "--json").stdout)
    assert loaded["K"] == base["K"]
    assert loaded["B"] == pytest.approx(base["B"] - 0.002 / 100.0, rel=1e-12)


def test_a_negative_b_from_equation_19_is_said_first_and_fails(session_dir, pmdc):
    """A negative no-load current gives B < 0 from (19): not impossible for a noisy
    reading (J stays positive), but not a friction either: said before the table, exit 1."""
    replace_once(session_dir / TOML, "current = 0.3", "current = -0.3")
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 1 and proc.stdout.startswith("Closed-form identification")
    (line,) = proc.stderr.splitlines()
    assert "B = -0.000198" in line and "cannot be negative" in line


def test_a_dead_time_may_be_shared_by_every_trace(session_dir, pmdc):
    from pmdc_bayes.inference.model.nuisances import nuisance_specs
    from pmdc_bayes.io.loader import load_session

    with (session_dir / TOML).open("a") as fh:
        fh.write('\n[model]\ndead_time = "shared"\n')
    session = load_session(session_dir)
    assert session.shared_dead_time and session.nuisances == ("dead_time",)
    assert [p.name for p in nuisance_specs(session)] == ["dead_time"]
    for same, shared in (('"per_trace"', False), ("true", False)):
        replace_once(session_dir / TOML, 'dead_time = "shared"', f"dead_time = {same}")
        again = load_session(session_dir)
        assert again.shared_dead_time is shared and again.nuisances == ("dead_time",)
        assert [p.name for p in nuisance_specs(again)] == ["dead_time_step"]
        replace_once(session_dir / TOML, f"dead_time = {same}", 'dead_time = "shared"')
    replace_once(session_dir / TOML, 'dead_time = "shared"', 'dead_time = "sometimes"')
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert ("model.dead_time: expected true, false, \"per_trace\" or \"shared\", got the "
            "string 'sometimes'") in proc.stderr, proc.stderr


def _stamped(stamp, sep=",", decimal="."):
    """Rewrite step.csv's time column as a logger's time stamps, ``stamp(t)``."""

    def mutate(d):
        header, *rows = _step_text(d).splitlines()
        out = [header.replace(",", sep)]
        for row in rows:
            t, *rest = row.split(",")
            out.append(sep.join([stamp(float(t)), *(c.replace(".", decimal) for c in rest)]))
        (d / "step.csv").write_text("\n".join(out) + "\n")

    return mutate


def _clock(start: float, date: str = "", zone: str = "", comma: bool = False):
    def stamp(t):
        s = (start + t) % 86400.0
        text = f"{int(s // 3600):02d}:{int(s % 3600 // 60):02d}:{s % 60:06.3f}{zone}"
        return date + (text.replace(".", ",") if comma else text)

    return stamp


@pytest.mark.parametrize("mutate", [
    _stamped(_clock(86399.5)),  # h:mm:ss.f, through midnight
    _stamped(_clock(43200.0, date="2026-11-26T", zone="Z")),  # ISO 8601, in UTC
    _stamped(_clock(43200.0, date="26.11.2026 "), sep=";", decimal=","),  # a German logger
    _stamped(lambda t: f"{int(t // 60)}:{t % 60:06.3f}"),  # m:ss.f, an oscilloscope's
], ids=["clock-through-midnight", "iso-date-time", "date-decimal-comma", "minutes-seconds"])
def test_a_loggers_time_stamps_read_as_the_time_since_the_first_row(session_dir, mutate, pmdc):
    from pmdc_bayes.io.loader import load_session

    before = load_session(session_dir).traces[0]
    mutate(session_dir)
    after = load_session(session_dir).traces[0]
    np.testing.assert_allclose(after.time, before.time, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(after.speed, before.speed)
    proc = _run(pmdc, session_dir, "--json")
    assert proc.returncode == 0, proc.stderr


def test_time_stamps_in_milliseconds_keep_the_schedule_in_the_traces_unit(session_dir):
    """A trace whose unit of time is the millisecond: its stamps are read in it, so the
    voltage schedule written in milliseconds stays on the same clock."""
    from pmdc_bayes.io.loader import load_session

    before = load_session(session_dir).traces[0]
    replace_once(session_dir / TOML, 'units = { time = "s"', 'units = { time = "ms"')
    replace_once(session_dir / TOML, "voltage = [[0.0, 0.0], [0.1, 6.0]]",
                 "voltage = [[0.0, 0.0], [100.0, 6.0]]")
    _stamped(_clock(3600.0))(session_dir)
    after = load_session(session_dir).traces[0]
    np.testing.assert_allclose(after.time, before.time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(after.voltage.times, before.voltage.times, rtol=0, atol=1e-12)


def _without_time(d):
    """step.csv without its time column, the trace at a stated sample_rate."""
    header, *rows = _step_text(d).splitlines()
    (d / "step.csv").write_text("\n".join(",".join(r.split(",")[1:]) for r in [header, *rows])
                                + "\n")
    replace_once(d / TOML, 'columns = { time = "t", ', "sample_rate = 100.0\ncolumns = { ")


def test_rows_at_a_stated_sample_rate_need_no_time_column(session_dir, pmdc):
    from pmdc_bayes.io.loader import load_session

    before = load_session(session_dir).traces[0]
    expected = _run(pmdc, session_dir, "--json")
    _without_time(session_dir)
    after = load_session(session_dir).traces[0]
    np.testing.assert_allclose(after.time, before.time, rtol=0, atol=1e-12)
    proc = _run(pmdc, session_dir, "--json")
    assert proc.returncode == 0, proc.stderr
    got, want = json.loads(proc.stdout), json.loads(expected.stdout)
    for key in ("Ra", "K", "B", "J"):
        assert got[key] == pytest.approx(want[key], rel=1e-9), key


@pytest.mark.parametrize("edit,expected", [
    (lambda d: replace_once(d / TOML, 'columns = { time = "t", ',
                            'sample_rate = 100.0\ncolumns = { time = "t", '),
     "sample_rate: is given with a time column"),
    (lambda d: replace_once(d / TOML, 'columns = { time = "t", ', "columns = { "),
     "columns.time: no time column"),
    (lambda d: (_without_time(d), replace_once(d / TOML, "sample_rate = 100.0",
                                               "sample_rate = 100.0\ntime_wrap = 65536")),
     "time_wrap: reads a time column"),
    (lambda d: (_without_time(d), replace_once(d / TOML, "sample_rate = 100.0",
                                               "sample_rate = 0.0")),
     "sample_rate: must be positive"),
])
def test_a_sample_rate_with_a_time_column_or_neither_is_one_line(session_dir, edit, expected, pmdc):
    edit(session_dir)
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert expected in line, line
