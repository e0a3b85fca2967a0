"""``pmdc-bayes lot``: the motors fitted on a local Dask cluster of two workers, one's bad
input passed over, the lot pooled and its files written."""

from __future__ import annotations

import csv
import json
import socket
from pathlib import Path

import pytest
from conftest import plan, plan_toml, step, sweep

from pmdc_bayes._batch import LOT_MARKER, claim_lot, lot_outs
from pmdc_bayes._cores import usable_cores
from pmdc_bayes._errors import UsageError
from pmdc_bayes.cli import main
from pmdc_bayes.simulate.session import simulate_session


def _plan(K: float) -> str:
    return plan_toml(plan(
        seed=1, motor="lot motor", friction="viscous",
        truth={"Ra": 2.0, "La": 1.5e-3, "K": K, "B": 2e-5, "J": 2e-5},
        bench={"Ra": (0.02, "ohm"), "La": (0.05, "mH")},
        steady=(sweep([3.0, 6.0, 9.0, 12.0], 0.5, 0.005),),
        traces=(step("step", 12.0, duration=0.5, rate=1000.0, at=0.05, initial="rest",
                     record_current=True, speed_noise=0.5, current_noise=0.01),)))


@pytest.mark.compiles
@pytest.mark.skipif(usable_cores() < 2, reason="two workers need two usable cores")
def test_a_lot_on_two_dask_workers_pools_the_motors_that_passed(tmp_path, capsys):
    lot = tmp_path / "lot"
    for k, gain in enumerate((0.050, 0.052, 0.049), start=1):
        folder = lot / f"m{k}"
        folder.mkdir(parents=True)
        (folder / "plan.toml").write_text(_plan(gain), encoding="utf-8")
        simulate_session(folder / "plan.toml", folder, seed=10 + k)
    (lot / "m4").mkdir()
    (lot / "m4" / "session.toml").write_text("[motor\n", encoding="utf-8")
    out = tmp_path / "runs"
    code = main(["lot", str(lot), "--out", str(out), "--no-mcmc", "--workers", "2"])
    text = capsys.readouterr()
    assert code == 2, text.err  # m4's bad input; the others fitted all the same
    assert "motor m4" in text.err and "TOML" in text.err
    with (out / "lot.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [r["motor"] for r in rows] == ["m1", "m2", "m3", "m4"]
    assert [r["status"] for r in rows] == ["ok", "ok", "ok", "bad input"]
    for r, gain in zip(rows[:3], (0.050, 0.052, 0.049), strict=False):
        sd = (float(r["K_hi"]) - float(r["K_lo"])) / (2 * 1.645)  # of a 90 % interval
        assert abs(float(r["K"]) - gain) < 4 * sd
        assert r["outlier"] == "false" and 0.0 < float(r["p_value"]) <= 1.0
        assert (out / r["motor"] / "summary.json").is_file()
    assert rows[3]["K"] == "" and rows[3]["outlier"] == ""
    doc = json.loads((out / "lot.json").read_text(encoding="utf-8"))
    k = doc["population"]["K"]
    assert k["median_interval"][0] < k["median"] < k["median_interval"][1]
    assert 0.045 < k["median"] < 0.056 and k["spread"] > 0
    assert set(doc["parameters"]) >= {"Ra", "La", "K", "B", "J"}
    assert (out / "population.nc").is_file() and (out / "lot.png").is_file()
    # an earlier lot is never replaced without --force
    assert main(["lot", str(lot / "m1"), "--out", str(out), "--no-mcmc"]) == 2


def _lot(folder, gains):
    for k, gain in enumerate(gains, start=1):
        session = folder / f"m{k}"
        session.mkdir(parents=True)
        (session / "plan.toml").write_text(_plan(gain), encoding="utf-8")
        simulate_session(session / "plan.toml", session, seed=20 + k)
    return folder


def _refused_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("address, says", [
    ("tcp://127.0.0.1:{port}", "no scheduler answers there"),
    ("127.0.0.1", "missing port"),
    ("htp://127.0.0.1:8786", "not htp://"),
    ("tls://127.0.0.1:8786", "only tcp:// addresses"),
])
def test_a_scheduler_address_that_cannot_serve_is_bad_input_before_any_fit(
        tmp_path, capsys, address, says):
    lot = _lot(tmp_path / "lot", (0.050, 0.051))
    address = address.format(port=_refused_port())
    out = tmp_path / "runs"
    code = main(["lot", str(lot), "--out", str(out), "--no-mcmc", "--scheduler", address])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and f"--scheduler {address}" in err[0] and says in err[0], err
    assert "drop --scheduler" in err[0]
    assert not out.exists()


@pytest.mark.compiles
def test_a_lot_runs_on_an_existing_dask_cluster_given_by_its_address(tmp_path, capsys):
    from dask.distributed import Client, LocalCluster

    lot = _lot(tmp_path / "lot", (0.050, 0.051))
    out = tmp_path / "runs"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, Client(cluster):
        code = main(["lot", str(lot), "--out", str(out), "--no-mcmc",
                     "--scheduler", cluster.scheduler_address])
        ran = set(cluster.scheduler.task_prefixes)  # what this cluster was given to run
    assert "fit_motor" in ran
    assert code == 0, capsys.readouterr().err
    with (out / "lot.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [(r["motor"], r["status"]) for r in rows] == [("m1", "ok"), ("m2", "ok")]
    assert json.loads((out / "lot.json").read_text(encoding="utf-8"))["population"]["K"]


def test_a_scheduler_that_never_answers_is_bad_input_and_nothing_is_written(
        tmp_path, capsys, monkeypatch):
    import pmdc_bayes.lot as lot_module

    monkeypatch.setattr(lot_module, "connect_timeout", lambda: 0.5)
    lot = _lot(tmp_path / "lot", (0.050, 0.051))
    out = tmp_path / "runs"
    with socket.socket() as silent:  # accepts a connection, never speaks Dask's protocol
        silent.bind(("127.0.0.1", 0))
        silent.listen(4)
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        code = main(["lot", str(lot), "--out", str(out), "--no-mcmc", "--scheduler", address])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "no Dask scheduler answered" in err[0], err
    assert not out.exists()


def _refused(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_the_lots_folder_is_never_a_users_folder_or_a_sessions(tmp_path, capsys):
    lot = _lot(tmp_path / "lot", (0.050, 0.051))
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "lot.json").write_text("the user's own", encoding="utf-8")
    (tmp_path / "afile").write_text("x", encoding="utf-8")
    for out, says in ((mine, "not a lot written by pmdc-bayes"),
                      (lot, "--out holds the session"),
                      (lot / "m1" / "runs", "--out lies inside the session"),
                      (tmp_path / "afile" / "runs", "is a file")):
        for command in ("lot", "fit"):
            assert says in _refused(capsys, [command, str(lot), "--out", str(out),
                                             "--no-mcmc"])
    assert (mine / "lot.json").read_text(encoding="utf-8") == "the user's own"
    assert sorted(p.name for p in mine.iterdir()) == ["lot.json"]
    assert sorted(p.name for p in (lot / "m1").iterdir()) == \
        sorted(p.name for p in (lot / "m2").iterdir())
    assert not (lot / LOT_MARKER).exists() and not (lot / "lot.csv").exists()
    other = _lot(tmp_path / "other", (0.05,)) / "m1"  # a session not of this lot
    assert "lies inside the session" in _refused(
        capsys, ["lot", str(lot), "--out", str(other / "runs"), "--no-mcmc"])


def test_an_earlier_lot_is_replaced_only_with_force_and_run_names_never_collide(tmp_path):
    from pmdc_bayes.rundir import RUN_MARKER

    sessions = []
    for parent, name in (("x", "m1"), ("y", "m1"), ("z", "m1-2"), ("w", "lot.csv"),
                         ("v", "M1")):
        (tmp_path / parent / name).mkdir(parents=True)
        sessions.append(tmp_path / parent / name)
    out = tmp_path / "runs"
    outs = lot_outs(sessions, out, force=False)
    names = [o.name for o in outs]
    assert len({n.casefold() for n in names}) == 5 and names[0] == "m1"
    assert "lot.csv" not in names
    claim_lot(out)
    assert lot_outs(sessions, out, force=False) == outs  # claimed, nothing in it yet
    outs[0].mkdir()  # a run an earlier lot wrote
    (outs[0] / RUN_MARKER).write_text("run\n", encoding="utf-8")
    with pytest.raises(UsageError, match="holds an earlier lot"):
        lot_outs(sessions, out, force=False)
    assert lot_outs(sessions, out, force=True) == outs
    (outs[1]).mkdir()
    (outs[1] / "notes.txt").write_text("not a run", encoding="utf-8")
    with pytest.raises(UsageError, match="not a pmdc-bayes run directory"):
        lot_outs(sessions, out, force=True)  # --force replaces runs, nothing else


def test_a_lot_written_before_the_marker_and_a_linked_folder_are_lots(tmp_path):
    from pmdc_bayes.rundir import RUN_MARKER

    sessions = [tmp_path / "s" / "m1"]
    sessions[0].mkdir(parents=True)
    old = tmp_path / "old"
    (old / "m1").mkdir(parents=True)
    (old / "m1" / RUN_MARKER).write_text("run\n", encoding="utf-8")
    (old / "lot.csv").write_text("motor,session,status,exit_code\n", encoding="utf-8")
    with pytest.raises(UsageError, match="holds an earlier lot"):
        lot_outs(sessions, old, force=False)
    assert lot_outs(sessions, old, force=True) == [old / "m1"]
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    link = tmp_path / "link"
    link.symlink_to(scratch, target_is_directory=True)
    for _ in range(2):  # the linked folder is the lot's, the second time too
        assert lot_outs(sessions, link, force=True) == [link / "m1"]
        claim_lot(link)
        (link / "lot.csv").write_text("motor\n", encoding="utf-8")


def test_an_earlier_lots_population_does_not_outlive_a_lot_without_one(tmp_path):
    from pmdc_bayes._batch import LotEntry, write_lot
    from pmdc_bayes._lot_command import write_lot_files
    from pmdc_bayes.lot import MotorRun

    out = tmp_path / "runs"
    claim_lot(out)
    for name in ("lot.json", "population.nc", "lot.png"):
        (out / name).write_text("an earlier lot's", encoding="utf-8")
    write_lot_files(out, [MotorRun(tmp_path / "m1", "m1", 2, error="bad input")], None, None)
    assert json.loads((out / "lot.json").read_text(encoding="utf-8"))["population"] is None
    assert not (out / "population.nc").exists() and not (out / "lot.png").exists()
    (out / "lot.png").write_text("an earlier lot's", encoding="utf-8")
    write_lot(out, [LotEntry(tmp_path / "m1", 2, error="bad input")])  # a plain fit's lot
    assert sorted(p.name for p in out.iterdir()) == [LOT_MARKER, "lot.csv"]


def test_a_workers_internal_error_is_its_motors_with_the_traceback_saved(
        tmp_path, monkeypatch):
    import pmdc_bayes.pipeline as pipeline
    from pmdc_bayes.lot import fit_motor

    monkeypatch.setenv("PMDC_BAYES_CACHE", str(tmp_path / "cache"))

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a fault of the tool")

    monkeypatch.setattr(pipeline, "run_fit", broken)
    run = fit_motor(tmp_path / "m1", tmp_path / "runs" / "m1", name="m1", cache=False)
    assert run.status == 4 and "ZeroDivisionError: a fault of the tool" in run.error
    log = Path(run.error.rsplit("saved to ", 1)[1])
    assert log.is_file() and "ZeroDivisionError" in log.read_text(encoding="utf-8")


def test_a_link_loop_a_session_named_twice_and_too_many_workers_are_bad_input(
        tmp_path, capsys):
    lot = _lot(tmp_path / "lot", (0.050, 0.051))
    loop = tmp_path / "loop"
    loop.symlink_to(loop)
    out = str(tmp_path / "runs")
    assert "leads back to itself" in _refused(capsys, ["lot", str(loop), str(lot / "m1"),
                                                       "--out", out])
    assert "leads back to itself" in _refused(capsys, ["lot", str(lot), "--out",
                                                       str(loop / "runs")])
    assert "named twice" in _refused(capsys, ["lot", str(lot / "m1" / "session.toml"),
                                              str(lot / "m1"), "--out", out])
    assert "usable cores" in _refused(capsys, ["lot", str(lot), "--out", out,
                                               "--workers", "4096"])
    assert not (tmp_path / "runs").exists()


@pytest.mark.compiles
@pytest.mark.skipif(usable_cores() < 2, reason="two workers need two usable cores")
def test_a_lot_stopped_by_ctrl_c_says_one_line_and_leaves_only_whole_runs(tmp_path, pmdc):
    """Ctrl-C at a terminal reaches every process of the group, the workers too: the
    command says it was interrupted, in one line, no worker's traceback or log, and
    leaves no temporary folder of a motor whose worker it stopped mid-fit."""
    import os
    import signal
    import time

    lot = _lot(tmp_path / "lot", (0.050, 0.051, 0.049, 0.052))
    out = tmp_path / "runs"
    env = dict(os.environ, PMDC_BAYES_CACHE=str(tmp_path / "cache"))
    proc = pmdc.start("lot", lot, "--out", out, "--no-mcmc", "--workers", "2", env=env,
                      start_new_session=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if out.is_dir() and any(p.name.startswith(".m") for p in out.iterdir()):
            break  # a worker is writing a motor's run
        time.sleep(0.1)
    assert proc.poll() is None, proc.communicate()
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines() == ["pmdc-bayes: interrupted (no partial output is "
                                           "left)"], stderr
    hidden = [p.name for p in out.iterdir() if p.name.startswith(".m")]
    assert hidden == [], hidden
    for run in out.iterdir():
        if not run.name.startswith("."):
            assert (run / "summary.json").is_file(), sorted(run.iterdir())
