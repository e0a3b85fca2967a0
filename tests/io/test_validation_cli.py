"""Every user mistake the loader knows about, through the command line.

Each case breaks one thing of the small valid session from ``conftest.py``, runs
``python -m pmdc_bayes closed-form DIR`` and checks: exit code 2, exactly one line on
stderr, no traceback, the file named, and the specific problem described.
"""


import pytest
from conftest import replace_once, set_csv_cell

TOML = "session.toml"


def _sub(old, new, file=TOML):
    """Mutation: replace the one occurrence of ``old`` in ``file``."""

    def mutate(d):
        replace_once(d / file, old, new)

    return mutate


def _cell(line, column, text, file="step.csv"):
    """Mutation: overwrite one CSV cell (1-based file line)."""

    def mutate(d):
        set_csv_cell(d / file, line, column, text)

    return mutate


def _delete(file):
    def mutate(d):
        (d / file).unlink()

    return mutate


def _missing_dir(d):
    return d.parent / "no_such_session"


def _two_samples(d):
    (d / "step.csv").write_text("t,speed_rpm,ia\n0.0,0.0,0.5\n0.01,40.0,0.5\n")


def _append_trace(d):
    text = (d / TOML).read_text()
    text += '\n[[trace]]\nname = "step"\nkind = "step"\nfile = "step.csv"\n'
    (d / TOML).write_text(text + STEP_COLUMNS + '\nunits = { speed = "rpm" }\n' + SCHEDULE
                          + "\n")


def _sparse_current(d):
    """The current logged at every other row only (a slower channel in the same file)."""
    lines = (d / "step.csv").read_text().splitlines()
    lines[2::2] = [",".join(x.split(",")[:2] + [""]) for x in lines[2::2]]
    (d / "step.csv").write_text("\n".join(lines) + "\n")


def _coarse_clock(d):
    """Time stamps at 20 ms for samples every 10 ms (a logger's coarse clock)."""
    lines = (d / "step.csv").read_text().splitlines()
    rows = [x.split(",") for x in lines[1:]]
    (d / "step.csv").write_text(lines[0] + "\n" + "".join(
        f"{int(round(float(r[0]) * 100)) // 2 / 50:.2f},{r[1]},{r[2]}\n" for r in rows))


def _long_format(d):
    """One row per channel and time: each time written twice, the speed's and the
    current's readings swapping columns on the second."""
    lines = (d / "step.csv").read_text().splitlines()
    rows = [x.split(",") for x in lines[1:]]
    (d / "step.csv").write_text(lines[0] + "\n" + "".join(
        f"{t},{w},{i}\n{t},{i},{w}\n" for t, w, i in rows))


def _stray_stamp(d):
    """A second reading logged at line 20's time stamp (two readings under one stamp)."""
    lines = (d / "step.csv").read_text().splitlines(keepends=True)
    t, w, i = lines[19].strip().split(",")
    extra = f"{t},{float(w) + 0.5!r},{float(i) + 0.01!r}\n"
    (d / "step.csv").write_text("".join(lines[:20] + [extra] + lines[20:]))


def _two_records(d):
    """The record logged twice into one file, the second from time 0 again."""
    lines = (d / "step.csv").read_text().splitlines(keepends=True)
    (d / "step.csv").write_text("".join(lines + lines[1:]))


def _header_again(d):
    """The header written again at line 21 (two logs joined into one file)."""
    lines = (d / "step.csv").read_text().splitlines(keepends=True)
    (d / "step.csv").write_text("".join(lines[:20] + lines[:1] + lines[20:]))


def _flat_step(d):
    rows = "".join(f"{k * 0.01:.2f},500.0,0.2\n" for k in range(50))
    (d / "step.csv").write_text("t,speed_rpm,ia\n" + rows)


def _dead_current(d):
    rows = "".join(f"{k * 0.01:.2f},{500.0 * (1 - 0.9 ** k):.3f},0\n" for k in range(50))
    (d / "step.csv").write_text("t,speed_rpm,ia\n" + rows)


def _truth(text):
    def mutate(d):
        (d / "truth.json").write_text(text)

    return mutate


RA_SD = "value = 2.0\nunit = \"ohm\"\nsd = 0.05\n"
SCHEDULE = "voltage = [[0.0, 0.0], [0.1, 6.0]]"
STEP_COLUMNS = 'columns = { time = "t", speed = "speed_rpm", current = "ia" }'
STEP_UNITS = 'units = { time = "s", speed = "rpm", current = "A", voltage = "V" }'

# (case id, mutation, substrings the one-line error must contain)
CASES = [
    # files and directories
    ("missing-directory", _missing_dir, ["no_such_session", "no such session directory",
                                         "bundled session (paper, demo, bench)"]),
    ("missing-session-toml", _delete(TOML), [TOML, "file not found", "must hold session.toml"]),
    ("missing-trace-csv", _delete("step.csv"), ["step.csv", "file not found"]),
    ("missing-table-csv", _delete("sweep.csv"), ["sweep.csv", "file not found"]),
    ("trace-file-misnamed", _sub('file = "step.csv"', 'file = "stepp.csv"'),
     ["stepp.csv", "file not found"]),
    # TOML syntax
    ("toml-syntax-unquoted-string", _sub('name = "Test motor"', "name = Test motor"),
     [f"{TOML}:line 2, column 8", "TOML syntax error", "Invalid value"]),
    ("toml-syntax-duplicate-key", _sub("sd = 0.04", "sd = 0.04\nsd = 0.03"),
     [f"{TOML}:line 14", "TOML syntax error"]),
    # missing required keys
    ("missing-bench-Ra-sd", _sub(RA_SD, RA_SD.replace("sd = 0.05\n", "")),
     [f"{TOML}:bench.Ra.sd", "missing required key", "add sd ="]),
    ("missing-bench-Ra", _sub('[bench.Ra]\nvalue = 2.0\nunit = "ohm"\nsd = 0.05\n', ""),
     [f"{TOML}:bench.Ra", "missing required table", "add a [bench.Ra] section"]),
    ("missing-trace-columns", _sub(STEP_COLUMNS + "\n", ""),
     [f"{TOML}:trace['step'].columns", "missing required table", "add columns = { ... }"]),
    ("missing-motor-name", _sub('name = "Test motor"\n', ""),
     [f"{TOML}:motor.name", "missing required key"]),
    ("missing-bench-unit", _sub('unit = "mH"\n', ""), [f"{TOML}:bench.La.unit", "missing"]),
    ("missing-trace-time-column", _sub('time = "t", ', ""),
     [f"{TOML}:trace['step'].columns.time", "no time column; add columns.time"]),
    ("missing-op-speed", _sub("speed = 100.0\n", ""),
     [f"{TOML}:operating_point['op'].speed", "missing required key"]),
    ("missing-table-file", _sub('file = "sweep.csv"\n', ""),
     [f"{TOML}:steady_table['sweep'].file", "missing required key"]),
    ("unknown-key-typo", _sub("supply_voltage = 12.0", "suply_voltage = 12.0"),
     [f"{TOML}:operating_point['op'].suply_voltage", "unknown key", "supply_voltage"]),
    # unknown kinds and units
    ("unknown-friction-model", _sub('friction = "viscous"', 'friction = "coulumb"'),
     [f"{TOML}:motor.friction", "unknown friction model 'coulumb'", "viscous, coulomb"]),
    ("unknown-speed-unit", _sub('speed = "rpm"', 'speed = "rpmm"'),
     [f"{TOML}:trace['step'].units.speed", "unknown speed unit 'rpmm'", "rad/s, rpm, rev/s"]),
    ("unknown-inductance-unit", _sub('unit = "mH"', 'unit = "mHz"'),
     [f"{TOML}:bench.La.unit", "unknown inductance unit 'mHz'", "H, mH"]),
    ("unknown-units-key", _sub(STEP_UNITS, 'units = { time = "s", torque = "N*m" }'),
     [f"{TOML}:trace['step'].units.torque", "unknown key", "load_torque"]),
    # CSV columns and cells
    ("misnamed-trace-column", _sub(STEP_COLUMNS, STEP_COLUMNS.replace('"speed_rpm"', '"rpm"')),
     ["step.csv:line 1", "no column named 'rpm'", "'t', 'speed_rpm', 'ia'"]),
    ("misnamed-table-column", _sub('voltage = "Va", speed = "w"', 'voltage = "V", speed = "w"'),
     ["sweep.csv:line 1", "no column named 'V'", "'Va', 'w'"]),
    ("non-numeric-cell", _cell(5, "speed_rpm", "abc"),
     ["step.csv:line 5", "column 'speed_rpm'", "'abc' is not a number"]),
    ("empty-cell", _cell(7, "t", ""), ["step.csv:line 7", "column 't' is empty"]),
    ("empty-table-cell", _cell(3, "w", "", file="sweep.csv"),
     ["sweep.csv:line 3", "column 'w' is empty"]),
    ("sparse-channel", _sparse_current,
     ["step.csv:line 3", "column 'ia' has no reading in", "75 of 151 rows", "own"]),
    ("unit-in-cell", _cell(3, "Va", "4 V", file="sweep.csv"),
     ["sweep.csv:line 3", "column 'Va'", "'4 V' is not a number"]),
    ("nan-cell", _cell(3, "w", "nan", file="sweep.csv"),
     ["sweep.csv:line 3", "column 'w'", "'nan' is not a finite number"]),
    ("inf-cell", _cell(4, "w", "inf", file="sweep.csv"),
     ["sweep.csv:line 4", "column 'w'", "'inf' is not a finite number"]),
    ("time-not-increasing", _cell(10, "t", "0.07"),
     ["step.csv:line 10", "not strictly increasing", "(line 9)"]),
    ("time-decreasing", _cell(20, "t", "0.01"), ["step.csv:line 20", "not strictly increasing"]),
    ("time-coarse-clock", _coarse_clock,
     ["step.csv:line 3", "not strictly increasing", "coarser than the sampling",
      "sample_rate = 100 "]),
    ("time-long-format", _long_format,
     ["step.csv:line 3", "not strictly increasing", "a long format: every time is written "
      "2 times over", "give each channel a column of its own"]),
    ("time-stray-repeat", _stray_stamp,
     ["step.csv:line 21", "not strictly increasing", "(line 20)",
      "the time repeats the line before at line 21 only", "remove or mend it",
      "unless the clock is coarser than the sampling", "sample_rate = "]),
    ("time-starts-again", _two_records,
     ["not strictly increasing", "the time starts again at line", "two records are joined",
      "a trace (and a file) of its own"]),
    ("header-written-again", _header_again,
     ["step.csv:line 21", "the header ('t' ...) is written again here", "remove this line"]),
    ("fewer-than-3-samples", _two_samples, ["step.csv", "only 2 samples", "at least 3"]),
    # schedules
    ("schedule-no-overlap", _sub(SCHEDULE, "voltage = [[5.0, 6.0]]"),
     [f"{TOML}:trace['step'].voltage", "trace and schedule don't overlap"]),
    ("schedule-starts-late", _sub(SCHEDULE, "voltage = [[0.05, 0.0], [0.1, 6.0]]"),
     [f"{TOML}:trace['step'].voltage", "after the first sample", "add a pair at the first "
      "sample time"]),
    ("schedule-not-increasing", _sub(SCHEDULE, "voltage = [[0.0, 0.0], [0.0, 6.0]]"),
     [f"{TOML}:trace['step'].voltage[1]", "strictly increasing"]),
    ("schedule-not-pairs", _sub(SCHEDULE, "voltage = [0.0, 6.0]"),
     [f"{TOML}:trace['step'].voltage[0]", "[time, value] pair"]),
    ("schedule-string-value", _sub(SCHEDULE, 'voltage = [[0.0, "6 V"]]'),
     [f"{TOML}:trace['step'].voltage[0].value", "expected a number", "'6 V'"]),
    ("voltage-column-and-schedule",
     _sub(STEP_COLUMNS, STEP_COLUMNS.replace('ia" }', 'ia", voltage = "ia" }')),
     [f"{TOML}:trace['step'].voltage", "both as a column", "and as a schedule"]),
    ("no-voltage", _sub(SCHEDULE, ""), [f"{TOML}:trace['step'].voltage", "no armature voltage"]),
    # values out of range
    ("zero-Ra", _sub("value = 2.0", "value = 0.0"),
     [f"{TOML}:bench.Ra.value", "must be positive", "got 0.0"]),
    ("negative-La", _sub("value = 1.5", "value = -1.5"),
     [f"{TOML}:bench.La.value", "must be positive", "got -1.5"]),
    ("zero-sd", _sub("sd = 0.04", "sd = 0.0"), [f"{TOML}:bench.La.sd", "must be positive"]),
    ("negative-sd", _sub("sd = 0.05", "sd = -0.05"), [f"{TOML}:bench.Ra.sd", "must be positive"]),
    ("duty-zero", _sub("duty = 0.5", "duty = 0.0"),
     [f"{TOML}:operating_point['op'].duty", "outside (0, 1]"]),
    ("duty-above-one", _sub("duty = 0.5", "duty = 1.2"),
     [f"{TOML}:operating_point['op'].duty", "duty 1.2 is outside (0, 1]"]),
    ("op-speed-zero", _sub("speed = 100.0", "speed = 0.0"),
     [f"{TOML}:operating_point['op'].speed", "must be positive"]),
    ("op-speed-negative", _sub("speed = 100.0", "speed = -100.0"),
     [f"{TOML}:operating_point['op'].speed", "must be positive", "-100.0"]),
    # wrong types
    ("string-for-number", _sub("supply_voltage = 12.0", 'supply_voltage = "12 V"'),
     [f"{TOML}:operating_point['op'].supply_voltage", "expected a number",
      "the string '12 V'"]),
    ("bool-for-number", _sub("current = 0.3", "current = true"),
     [f"{TOML}:operating_point['op'].current", "expected a number", "boolean true"]),
    ("number-for-name", _sub('name = "Test motor"', "name = 7"),
     [f"{TOML}:motor.name", "expected a non-empty string", "7"]),
    ("kind-not-string", _sub('kind = "step"', "kind = 3"),
     [f"{TOML}:trace['step'].kind", "expected a non-empty string"]),
    ("kind-empty", _sub('kind = "step"', 'kind = ""'),
     [f"{TOML}:trace['step'].kind", "expected a non-empty string", "''"]),
    ("bench-not-table", _sub('[bench.La]\nvalue = 1.5\nunit = "mH"\nsd = 0.04\n',
                             "[bench]\nLa = 1.5\n"),
     [f"{TOML}:bench.La", "expected a table", "got 1.5"]),
    ("initial-unknown", _sub(SCHEDULE, SCHEDULE + '\ninitial = "resting"'),
     [f"{TOML}:trace['step'].initial", '"rest", "steady"']),
    ("K-decimals-float", _sub("[[operating_point]]", "[closed_form]\nK_decimals = 2.5\n\n"
                              "[[operating_point]]"),
     [f"{TOML}:closed_form.K_decimals", "whole number"]),
    ("duplicate-trace-name", _append_trace,
     [f"{TOML}:trace['step']", "two [[trace]] entries are named 'step'"]),
    # found by the closed-form method rather than the loader
    ("speed-never-changes", _flat_step,
     ["step.csv", "the speed column 'speed_rpm' is 500 in every row", "did not turn"]),
    ("current-dead", _dead_current,
     ["step.csv", "the current column 'ia' is 0 in every row", "leave current out of columns"]),
    ("truth-bad-json", _truth("{Ra: 1}"), ["truth.json", "not valid JSON"]),
    ("truth-non-number", _truth('{"Ra": "two"}'), ["truth.json:Ra", "not a finite number"]),
]


def _run(pmdc, path):
    return pmdc("closed-form", path, timeout=120)


def test_the_unbroken_session_runs(session_dir, pmdc):
    proc = _run(pmdc, session_dir)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""


@pytest.mark.parametrize(("mutate", "expected"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_cli_reports_one_line(session_dir, mutate, expected, pmdc):
    target = mutate(session_dir) or session_dir
    proc = _run(pmdc, target)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    (line,) = lines
    assert line.startswith("pmdc-bayes: error: "), line
    assert proc.stdout == ""
    for text in expected:
        assert text in line, f"{text!r} not in {line!r}"
    # every message says what to do: the "; <fix>" part after the problem
    assert "; " in line, line


def test_case_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


def test_an_internal_fault_exits_4_with_one_line_and_a_saved_traceback(
        session_dir, monkeypatch, capsys, tmp_path):
    from pmdc_bayes import cli, pipeline

    def broken(*args, **kwargs):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(pipeline, "run_fit", broken)
    monkeypatch.setenv("PMDC_BAYES_CACHE", str(tmp_path / "cache"))
    code = cli.main(["fit", str(session_dir), "--no-mcmc", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == cli.EXIT_INTERNAL == 4
    assert len(err) == 1 and "internal error" in err[0] and "ZeroDivisionError" in err[0]
    (log,) = (tmp_path / "cache" / "logs").glob("error-*.log")
    assert str(log) in err[0]
    assert "Traceback" in log.read_text() and "float division by zero" in log.read_text()
    assert not (tmp_path / "run").exists()


def test_a_negative_seed_is_bad_input_and_version_is_printed(capsys):
    from pmdc_bayes import cli

    with pytest.raises(SystemExit) as exc:
        cli.main(["fit", "demo", "--seed", "-1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--seed: -1 is outside" in err and "Traceback" not in err
    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("pmdc-bayes ")


@pytest.mark.parametrize("bad", ["-1", "soon", "inf", "nan"])
def test_a_malformed_sampling_limit_is_bad_input(bad, capsys):
    from pmdc_bayes.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["fit", "demo", "--max-sampling-seconds", bad])
    assert exc.value.code == 2
    assert "--max-sampling-seconds" in capsys.readouterr().err


def test_fit_help_names_every_non_ideality_and_every_candidate_of_compare():
    import re

    from pmdc_bayes._cli_parser import build_parser
    from pmdc_bayes.io.session import NUISANCES

    commands = dict.fromkeys(("closed-form", "simulate", "fit", "report", "cache", "lot"))
    fit = build_parser(commands)._subparsers._group_actions[0].choices["fit"]
    helps = {a.dest: " ".join(a.help.split()) for a in fit._actions if a.help}
    for name in NUISANCES:
        assert re.search(rf"\b{name.replace('_', '-')}\b", helps["add"]), name
    for name in NUISANCES:  # each non-ideality the search may add is named, as '+ name'
        assert f"+ {name.replace('_', '-')}" in helps["compare"], name
