"""Run directories: nothing of the user's lost, nothing half-written, readable by the group,
self-contained; interruptions and a full disk leave the earlier run as it was."""

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pmdc_bayes import _signals
from pmdc_bayes._errors import UsageError
from pmdc_bayes.rundir import (
    RUN_MARKER,
    changed_files,
    check_replaceable,
    copy_session,
    sweep_unfinished,
    write_atomically,
)


def _snapshot(root):
    return {p.relative_to(root): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _debris(parent: Path, name: str):
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(f".{name}."))


def _fill_with(text):
    def fill(tmp):
        (tmp / "summary.json").write_text(text)
        (tmp / "figures").mkdir()
        (tmp / "figures" / "a.png").write_bytes(b"png")

    return fill


def test_an_out_below_a_file_is_refused_before_any_work(tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(UsageError, match="is a file, not a directory"):
        check_replaceable(tmp_path / "notes.txt" / "run", force=False)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes in read-only directories")
def test_an_out_in_a_read_only_directory_is_refused_before_any_work(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir(mode=0o555)
    with pytest.raises(UsageError, match="cannot write in"):
        check_replaceable(ro / "run", force=False)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
@pytest.mark.parametrize(("sig", "raised"), [(signal.SIGTERM, _signals.Terminated),
                                             (signal.SIGINT, KeyboardInterrupt)])
def test_an_interrupt_whose_raise_python_ignored_still_stops_the_run(tmp_path, sig, raised):
    """A signal arriving in a finaliser (as in a garbage-collection callback) has its
    exception printed and dropped by Python; the earlier run must still stay whole."""
    write_atomically(tmp_path / "run", _fill_with("earlier"), force=False)
    before = _snapshot(tmp_path / "run")

    class Finalised:
        def __del__(self):
            os.kill(os.getpid(), sig)

    def fill(tmp):
        _fill_with("new")(tmp)
        obj = Finalised()
        del obj  # the handler runs inside __del__, where its raise is ignored

    with _signals.handled(), pytest.raises(raised):
        write_atomically(tmp_path / "run", fill, force=True)
    assert _snapshot(tmp_path / "run") == before
    assert _debris(tmp_path, "run") == []


@pytest.mark.parametrize(("sig", "raised"), [(signal.SIGTERM, _signals.Terminated),
                                             (signal.SIGINT, KeyboardInterrupt)])
def test_an_interrupt_lost_in_a_finaliser_prints_nothing_and_comes_again(capfd, sig, raised):
    """Python prints an exception it cannot raise (a traceback on the user's screen);
    the handlers drop it silently and deliver the signal again, so it stops the program
    without waiting for the next check."""

    class Finalised:
        def __del__(self):
            os.kill(os.getpid(), sig)

    with _signals.handled(), pytest.raises(raised):
        obj = Finalised()
        del obj  # the first raise is lost inside __del__
        for _ in range(200):  # ordinary code, no check(): the second delivery lands here
            time.sleep(0.01)
    err = capfd.readouterr().err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_an_interrupt_between_the_two_renames_puts_the_earlier_run_back(tmp_path,
                                                                       monkeypatch):
    import pmdc_bayes.rundir as rundir

    write_atomically(tmp_path / "run", _fill_with("earlier"), force=False)
    before = _snapshot(tmp_path / "run")
    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(Path(dst).name)
        if len(calls) == 2:  # the new run's rename, after the earlier one moved aside
            raise KeyboardInterrupt
        real(src, dst)

    monkeypatch.setattr(rundir.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        write_atomically(tmp_path / "run", _fill_with("new"), force=True)
    assert calls[:2] == [".run.pmdc-replaced", "run"]
    assert _snapshot(tmp_path / "run") == before
    assert _debris(tmp_path, "run") == []


def test_a_run_gets_the_modes_of_the_umask(tmp_path):
    old = os.umask(0o022)
    try:
        write_atomically(tmp_path / "run", _fill_with("{}"), force=False)
    finally:
        os.umask(old)
    run = tmp_path / "run"
    assert run.stat().st_mode & 0o777 == 0o755
    assert (run / "figures").stat().st_mode & 0o777 == 0o755
    assert (run / "summary.json").stat().st_mode & 0o777 == 0o644
    assert (run / RUN_MARKER).is_file() and _debris(tmp_path, "run") == []


@pytest.mark.parametrize("fault", [KeyboardInterrupt(), OSError(errno.ENOSPC, "No space left "
                                                                "on device")])
def test_a_failed_rewrite_leaves_the_earlier_run_and_no_debris(tmp_path, fault):
    run = tmp_path / "run"
    write_atomically(run, _fill_with("old"), force=False)
    before = _snapshot(run)

    def fill(tmp):
        (tmp / "summary.json").write_text("new")
        raise fault

    with pytest.raises(UsageError if isinstance(fault, OSError) else KeyboardInterrupt):
        write_atomically(run, fill, force=True)
    assert _snapshot(run) == before and _debris(tmp_path, "run") == []


def test_a_rewrite_after_a_crash_between_the_renames_still_works(tmp_path):
    run = tmp_path / "run"
    write_atomically(run, _fill_with("old"), force=False)
    (tmp_path / ".run.pmdc-replaced").mkdir()  # left by a power cut between the renames
    write_atomically(run, _fill_with("new"), force=True)
    assert (run / "summary.json").read_text() == "new" and _debris(tmp_path, "run") == []


_KILLED_MID_WRITE = """
import os, sys
from pathlib import Path
from pmdc_bayes.rundir import write_atomically

def fill(tmp):
    (tmp / "summary.json").write_text("half")
    if sys.argv[2] == "between":  # killed after the earlier run was moved aside
        os.replace(Path(sys.argv[1]), Path(sys.argv[1]).with_name(".run.pmdc-replaced"))
    os._exit(9)

write_atomically(Path(sys.argv[1]), fill, force=True)
"""


@pytest.mark.parametrize("when", ["mid-fill", "between"])
def test_what_a_killed_write_leaves_is_swept_and_nothing_of_the_users(tmp_path, when):
    """A process killed while it wrote a run (a lot's worker stopped mid-fit) runs no
    clean-up; the sweep removes what it was writing, puts back an earlier run it had
    moved aside, and leaves alone the user's own folders, whatever their names and
    contents, and what a live process is writing (while one writes, an earlier run set
    aside may be its own, and stays)."""
    run = tmp_path / "run"
    write_atomically(run, _fill_with("earlier"), force=False)
    before = _snapshot(run)
    mine = [tmp_path / n for n in (".run.notes", ".run.abcdefgh", ".run.old", ".run2.x")]
    for folder in mine:  # a backup of the run by the user, marker and all
        shutil.copytree(run, folder)
    live = tmp_path / f".run.pmdc-partial-{os.getpid()}-abcd1234"
    if when == "mid-fill":
        live.mkdir()
    code = subprocess.run([sys.executable, "-c", _KILLED_MID_WRITE, str(run), when],
                          check=False).returncode
    assert code == 9
    others = {p.name for p in mine} | ({live.name} if live.exists() else set())
    left = set(_debris(tmp_path, "run")) - others
    assert len(left) == (2 if when == "between" else 1), left  # the kill left debris
    removed = sweep_unfinished(run)
    assert len(removed) == 1 and removed[0].name.startswith(".run.pmdc-partial-")
    assert _snapshot(run) == before
    assert set(_debris(tmp_path, "run")) == others - {".run2.x"}
    assert all(_snapshot(folder) == before for folder in mine)
    assert sweep_unfinished(run) == [] and live.is_dir() == (when == "mid-fill")


def test_the_session_copy_keeps_places_and_detects_changes(session_dir, tmp_path):
    from pmdc_bayes.io.loader import load_session

    session = load_session(session_dir)
    hashes = copy_session(session, tmp_path)
    assert set(hashes) == {"session.toml", "step.csv", "sweep.csv"}
    copy = tmp_path / "session"
    assert changed_files(copy, hashes) == [] and changed_files(session_dir, hashes) == []
    assert load_session(copy).traces[0].speed.tolist() == session.traces[0].speed.tolist()
    with (session_dir / "step.csv").open("a") as fh:
        fh.write("1.51,1000.0,0.05\n")
    (session_dir / "sweep.csv").unlink()
    assert changed_files(session_dir, hashes) == ["step.csv", "sweep.csv"]


def test_report_names_the_damaged_file_of_the_runs_copy(session_dir, tmp_path, capsys):
    from pmdc_bayes.cli import main
    from pmdc_bayes.io.loader import load_session

    run = tmp_path / "run"
    hashes = copy_session(load_session(session_dir), run)
    (run / RUN_MARKER).write_text("", encoding="utf-8")
    (run / "summary.json").write_text(json.dumps(
        {"session": {"path": str(session_dir), "files": hashes}, "parameters": {}, "fit": {}}))
    with (run / "session" / "step.csv").open("a") as fh:
        fh.write("1.51,1000.0,0.05\n")
    session_dir.rename(tmp_path / "moved")
    assert main(["report", str(run), "--no-cache"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith(f"pmdc-bayes: error: {run / 'session' / 'step.csv'}: differs from "
                           "the SHA-256 the fit recorded"), line


# --- through the command line, on one fitted run of a small session ----------------------

def _fit_cli(pmdc, *args, **kw):
    return pmdc.start("fit", "--no-search", *args, **kw)


def _two_traces_one_figure_name(session_dir):
    """Add a second trace, 'Step', whose figure name differs from 'step' only in case."""
    text = (session_dir / "session.toml").read_text()
    block = text[text.index("[[trace]]"):]
    (session_dir / "session.toml").write_text(text + "\n" + block.replace('"step"', '"Step"', 1))
    return session_dir


@pytest.fixture(scope="module")
def fitted(tmp_path_factory, pmdc):
    """One `fit --no-mcmc` of a small session (compiling it takes a minute: the tests
    that use it are marked slow)."""
    from conftest import write_session

    root = tmp_path_factory.mktemp("rundir")
    session = _two_traces_one_figure_name(write_session(root / "sess"))
    out = root / "runs" / "run"
    proc = _fit_cli(pmdc, session, "--no-mcmc", "--out", out, "--allow-inadequate",
                    "--allow-unconverged", "--verbose")
    _, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err
    stages = [line.split("] ", 1)[1].split()[0] for line in err.splitlines()
              if line.startswith("pmdc-bayes: [")]
    # a program compiled for a session shape new to the cache is announced in its stage
    assert [s for s in stages if s != "compiling"] == [
        "loading", "closed", "MAP", "adequacy", "writing"], err
    assert "compiling" not in stages[:stages.index("MAP")], err
    return session, out


@pytest.mark.compiles
def test_quiet_prints_nothing_but_the_verdict_against_the_model(fitted, tmp_path, pmdc):
    """The small session's synthetic current is not a motor's: the model is inadequate,
    and even --quiet with --allow-inadequate says so, in one line."""
    session, _ = fitted
    proc = _fit_cli(pmdc, session, "--no-mcmc", "--out", tmp_path / "run", "--allow-inadequate",
                    "--allow-unconverged", "--quiet")
    out, err = proc.communicate(timeout=900)
    assert proc.returncode == 0 and out == "", (out, err)
    (line,) = err.splitlines()
    assert line.startswith("pmdc-bayes: error: model inadequate: ")
    assert (tmp_path / "run" / "report.html").is_file()


@pytest.mark.compiles
def test_figures_whose_names_collide_are_both_kept(fitted):
    _, out = fitted
    names = {p.name for p in (out / "figures").glob("trace_*.png")}
    assert {"trace_step.png", "trace_Step-2.png"} <= names
    html = (out / "report.md").read_text()
    assert "figures/trace_Step-2.png" in html and "figures/trace_step.png" in html


@pytest.mark.compiles
def test_the_run_holds_its_session_and_reports_after_the_original_changes(fitted, tmp_path, pmdc):
    import shutil

    session, out = fitted
    run = tmp_path / "run"
    shutil.copytree(out, run)
    summary = json.loads((run / "summary.json").read_text())
    assert set(summary["session"]["files"]) == {"session.toml", "step.csv", "sweep.csv"}
    assert (run / "session" / "step.csv").read_bytes() == (session / "step.csv").read_bytes()
    moved = tmp_path / "moved"
    shutil.copytree(session, moved)
    shutil.rmtree(session)
    try:
        proc = pmdc("report", run, timeout=600)
        assert proc.returncode == 0, proc.stderr
        # without its copy, a run whose session has gone or changed is refused by name
        shutil.rmtree(run / "session")
        proc = pmdc("report", run, timeout=600)
        assert proc.returncode == 2 and "changed or missing since the fit" in proc.stderr
        assert len(proc.stderr.splitlines()) == 1
    finally:
        shutil.copytree(moved, session)


def _wait_for_stage(parent: Path, name: str, file: str, proc, timeout=600):
    """Wait until the run being built beside ``parent/name`` holds ``file``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        for d in parent.glob(f".{name}.*"):
            if (d / file).exists():
                return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize(("sig", "code", "stage"), [(signal.SIGTERM, 143, RUN_MARKER),
                                                    (signal.SIGINT, 130, "summary.json")])
@pytest.mark.compiles
def test_an_interrupted_rewrite_leaves_the_earlier_run(fitted, sig, code, stage, pmdc):
    """SIGTERM as the new run starts being written, SIGINT once its summary is written and
    its report is being drawn: the earlier run stays whole, nothing else is left."""
    session, out = fitted
    before = _snapshot(out)
    proc = _fit_cli(pmdc, session, "--no-mcmc", "--out", out, "--force", "--allow-inadequate",
                    "--allow-unconverged")
    assert _wait_for_stage(out.parent, out.name, stage, proc), proc.communicate()
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert _snapshot(out) == before
    assert _debris(out.parent, out.name) == []


def _mount_tmpfs(where: Path, size: str, *opts) -> bool:
    where.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", ",".join((f"size={size}", *opts)),
                           "tmpfs", str(where)], capture_output=True)
    return proc.returncode == 0


@pytest.fixture
def small_disk(tmp_path):
    disk = tmp_path / "disk"
    if not _mount_tmpfs(disk, "64k"):
        pytest.skip("cannot mount a small file system here (needs root and mount)")
    yield disk
    subprocess.run(["umount", str(disk)], check=False)


@pytest.mark.compiles
def test_a_full_disk_is_one_line_and_leaves_nothing(fitted, small_disk, pmdc):
    session, _ = fitted
    proc = _fit_cli(pmdc, session, "--no-mcmc", "--out", small_disk / "run", "--allow-inadequate",
                    "--allow-unconverged")
    _, err = proc.communicate(timeout=900)
    assert proc.returncode == 2, err
    assert "No space left on device" in err and len(err.strip().splitlines()) == 1
    assert list(small_disk.iterdir()) == []


@pytest.fixture
def read_only_cache(tmp_path):
    cache = tmp_path / "cache"
    if not _mount_tmpfs(cache, "1m", "ro"):
        pytest.skip("cannot mount a read-only file system here (needs root and mount)")
    yield cache
    subprocess.run(["umount", str(cache)], check=False)


@pytest.mark.compiles
def test_a_read_only_compile_cache_does_not_stop_a_fit(fitted, read_only_cache, tmp_path, pmdc):
    session, _ = fitted
    env = dict(os.environ, PMDC_BAYES_CACHE=str(read_only_cache))
    proc = _fit_cli(pmdc, session, "--no-mcmc", "--out", tmp_path / "run", "--allow-inadequate",
                    "--allow-unconverged", env=env)
    _, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err
    assert (tmp_path / "run" / "summary.json").is_file()


@pytest.mark.compiles
def test_report_on_a_read_only_run_is_one_line(fitted, tmp_path, pmdc):
    import shutil

    _, out = fitted
    mount = tmp_path / "ro"
    if not _mount_tmpfs(mount, "50m"):
        pytest.skip("cannot mount a file system here (needs root and mount)")
    try:
        shutil.copytree(out, mount / "run")
        subprocess.run(["mount", "-o", "remount,ro", str(mount)], check=True)
        proc = pmdc("report", mount / "run", timeout=600)
        assert proc.returncode == 2, proc.stderr
        assert "cannot write in" in proc.stderr and len(proc.stderr.splitlines()) == 1
    finally:
        subprocess.run(["umount", str(mount)], check=False)


@pytest.mark.compiles
def test_report_without_the_cache_stores_nothing(fitted, tmp_path, pmdc):
    import shutil

    _, out = fitted
    shutil.copytree(out, tmp_path / "run")
    env = dict(os.environ, PMDC_BAYES_CACHE=str(tmp_path / "cache"))
    proc = pmdc("report", tmp_path / "run", "--no-cache", timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "cache").exists()
    proc = pmdc("report", tmp_path / "run", timeout=600, env=env)
    assert proc.returncode == 0 and any((tmp_path / "cache" / "export").rglob("*.jaxexport"))


@pytest.mark.compiles
def test_report_over_a_file_named_figures_is_one_line(fitted, tmp_path, pmdc):
    import shutil

    _, out = fitted
    run = tmp_path / "run"
    shutil.copytree(out, run)
    shutil.rmtree(run / "figures")
    (run / "figures").write_text("mine")
    proc = pmdc("report", run, timeout=600)
    assert proc.returncode == 2 and "where the report's figures go" in proc.stderr
    assert (run / "figures").read_text() == "mine"


def test_report_on_an_empty_summary_is_one_line(tmp_path, pmdc):
    run = tmp_path / "run"
    run.mkdir()
    (run / "summary.json").write_text("{}")
    proc = pmdc("report", run, timeout=600)
    assert proc.returncode == 2 and "not a summary written by 'pmdc-bayes fit'" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


@pytest.mark.compiles
def test_report_on_a_garbage_posterior_is_one_line(fitted, tmp_path, pmdc):
    import shutil

    _, out = fitted
    run = tmp_path / "run"
    shutil.copytree(out, run)
    (run / "posterior.nc").write_bytes(b"\x89HDF garbage" * 100)
    proc = pmdc("report", run, timeout=600)
    assert proc.returncode == 2, proc.stderr
    assert "cannot be read as this run's posterior" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_fit_into_a_read_only_place_is_refused_before_the_fit(session_dir, tmp_path, pmdc):
    mount = tmp_path / "ro"
    if not _mount_tmpfs(mount, "1m", "ro"):
        pytest.skip("cannot mount a read-only file system here (needs root and mount)")
    try:
        proc = _fit_cli(pmdc, session_dir, "--out", mount / "run", "--verbose")
        _, err = proc.communicate(timeout=600)
        lines = err.splitlines()
        assert proc.returncode == 2 and "cannot write in" in lines[-1], err
        assert "MAP fit" not in err and "Traceback" not in err  # refused before fitting
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def test_a_run_record_gives_back_the_unknown_loads_and_their_parts(tmp_path):
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.readback import _with_nuisances

    session = load_session("bench")
    info = {"nuisances": ["unknown_load"], "loaded_traces": ["step_6v"],
            "load_kinds": {"step_6v": "viscous"}}
    again = _with_nuisances(session, tmp_path, info)
    assert again.unknown_load_traces() == ("step_6v",) and again.load_kind("step_6v") == "viscous"
    info["load_kinds"] = {"step_6v": "eddy"}
    with pytest.raises(UsageError, match="session.load_kinds is"):
        _with_nuisances(session, tmp_path, info)
    del info["load_kinds"]  # a run written before the kinds were recorded: both parts
    assert _with_nuisances(session, tmp_path, info).load_kind("step_6v") == "both"


def test_a_run_record_gives_back_a_shared_dead_time(tmp_path):
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.readback import _with_nuisances

    session = load_session("bench")
    assert session.shared_dead_time
    info = {"nuisances": ["dead_time"], "dead_time": "per_trace"}
    assert not _with_nuisances(session, tmp_path, info).shared_dead_time
    info["dead_time"] = "shared"
    assert _with_nuisances(session, tmp_path, info).shared_dead_time
    del info["dead_time"]  # a run written before it was recorded: one per trace
    assert not _with_nuisances(session, tmp_path, info).shared_dead_time
    info["dead_time"] = "often"
    with pytest.raises(UsageError, match="session.dead_time is 'often'"):
        _with_nuisances(session, tmp_path, info)
