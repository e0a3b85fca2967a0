"""A lot of motors in one ``pmdc-bayes fit``: sessions named one by one or as a folder
of them, one's bad input not stopping the others, one run per motor and the lot's
table, the worst exit code."""

from __future__ import annotations

import csv
import shutil

import pytest

from pmdc_bayes import UsageError
from pmdc_bayes._batch import expand_sessions, lot_outs
from pmdc_bayes.cli import main
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.rundir import RUN_MARKER


def _lot(tmp_path, broken=True):
    lot = tmp_path / "lot"
    for name in ("m1", "m2"):
        shutil.copytree(bundled_session_dir("paper"), lot / name)
    if broken:
        (lot / "m3").mkdir()
        (lot / "m3" / "session.toml").write_text("[motor\n", encoding="utf-8")
    (lot / "notes").mkdir()  # a folder that is not a session is passed over
    return lot


def _rows(path):
    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_a_folder_of_sessions_is_its_sessions_in_name_order(tmp_path):
    lot = _lot(tmp_path)
    assert [p.name for p in expand_sessions([str(lot)])] == ["m1", "m2", "m3"]
    assert [p.name for p in expand_sessions([str(lot / "m2"), str(lot / "m1")])] == ["m2", "m1"]
    assert expand_sessions([]) == [bundled_session_dir("demo")]
    with pytest.raises(UsageError, match="named twice"):
        expand_sessions([str(lot / "m1"), str(lot / "m1" / ".." / "m1")])
    with pytest.raises(UsageError, match="neither a session"):
        expand_sessions([str(lot / "notes")])


def test_a_local_directory_named_like_a_bundled_session_hides_it_only_if_a_session(
        tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "demo"  # as 'pmdc-bayes fit demo --out demo' leaves it
    shutil.copytree(bundled_session_dir("paper"), run / "session")
    (run / RUN_MARKER).write_text("", encoding="utf-8")
    notes = []
    assert expand_sessions(["demo"], note=notes.append) == [bundled_session_dir("demo")]
    assert len(notes) == 1 and "bundled session 'demo'" in notes[0]
    assert "./demo here is a run directory" in notes[0]
    with pytest.raises(UsageError, match="a run directory written by 'pmdc-bayes fit'"):
        expand_sessions(["./demo"])
    # a folder of sessions named so is the lot only when named as a path
    shutil.copytree(bundled_session_dir("paper"), tmp_path / "paper" / "m1")
    notes.clear()
    assert expand_sessions(["paper"], note=notes.append) == [bundled_session_dir("paper")]
    assert len(notes) == 1 and "write ./paper for the local one" in notes[0]
    assert [p.name for p in expand_sessions(["./paper"])] == ["m1"]
    # a session directory of that name is the user's, without a note
    shutil.copytree(bundled_session_dir("paper"), tmp_path / "bench")
    notes.clear()
    assert [p.resolve() for p in expand_sessions(["bench"], note=notes.append)] == [
        tmp_path / "bench"]
    assert notes == []
    assert main(["closed-form", "demo", "--json"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pmdc-bayes: note: using the bundled session 'demo'" in err


def test_runs_are_named_after_their_sessions_and_an_earlier_lot_is_kept(tmp_path):
    a, b = tmp_path / "x" / "m1", tmp_path / "y" / "m1"
    out = tmp_path / "out"
    assert lot_outs([a, b], out, force=False) == [out / "m1", out / "m1-2"]
    assert lot_outs([a, b], None, force=False) == [None, None]
    out.mkdir()
    (out / "lot.csv").write_text("mine\n", encoding="utf-8")
    for force in (False, True):  # a lot.csv of the user's, not a lot this tool wrote
        with pytest.raises(UsageError, match="not a lot written by pmdc-bayes"):
            lot_outs([a, b], out, force=force)
    assert (out / "lot.csv").read_text(encoding="utf-8") == "mine\n"
    (tmp_path / "file").write_text("", encoding="utf-8")
    with pytest.raises(UsageError, match="--out is a file"):
        lot_outs([a, b], tmp_path / "file", force=False)


def test_a_lot_fits_every_motor_and_tables_them(tmp_path, capsys):
    lot, out = _lot(tmp_path), tmp_path / "runs"
    code = main(["fit", str(lot), "--no-mcmc", "--no-search", "--out", str(out),
                 "--allow-inadequate"])
    text = capsys.readouterr()
    assert code == 2  # m3's bad input; m1 and m2 were fitted all the same
    assert "m3/session.toml:line 1" in text.err
    assert "2 of 3 motors ok" in text.out
    rows = _rows(out / "lot.csv")
    assert [r["status"] for r in rows] == ["ok", "ok", "bad input"]
    for r in rows[:2]:
        assert (out / r["session"].split("/")[-1] / "summary.json").is_file()
        assert 0.05 < float(r["K"]) < 0.09 and float(r["K_sd"]) > 0
    assert rows[0]["K"] == rows[1]["K"]  # the same data give the same motor
    assert rows[2]["K"] == "" and "TOML syntax error" in rows[2]["error"]
    # without --allow-inadequate the paper's rejected model is each motor's status
    code = main(["fit", str(lot / "m1"), str(lot / "m2"), "--no-mcmc", "--no-search", "--quiet",
                 "--out", str(tmp_path / "strict")])
    assert code == 3
    rows = _rows(tmp_path / "strict" / "lot.csv")
    assert [r["status"] for r in rows] == ["model inadequate"] * 2
