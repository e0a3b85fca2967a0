"""The report's figures drawn in worker processes: the same PNG bytes as drawn in this
process, a fallback here for what cannot go to a worker (an unpicklable figure, a
worker that dies), no second run of a user's script, and workers that import none of
the fitting stack."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from pmdc_bayes.report import _render
from pmdc_bayes.report._plot import STYLE, png, styled, subplots


@pytest.fixture
def fresh_pool(monkeypatch):
    """A pool of two workers of this test's own (the module's pool is put back after)."""
    monkeypatch.setenv(_render.WORKERS_ENV, "2")
    monkeypatch.setattr(_render, "_pool", None)
    monkeypatch.setattr(_render, "_broken", False)
    yield
    if _render._pool is not None:
        _render._pool.shutdown(wait=True, cancel_futures=True)


@styled
def line_figure(n: int, formatter=None):
    """A figure function of the kind :func:`_render.later` takes (module level)."""
    fig, ax = subplots(figsize=(4, 3))
    x = np.linspace(0.0, 1.0, n)
    ax.plot(x, np.sin(7 * x), label="sine")
    ax.set(xlabel="time (s)", ylabel="speed (rad/s)", title=f"{n} samples")
    if formatter is not None:
        ax.xaxis.set_major_formatter(formatter)
    ax.legend()
    return png(fig)


def die_in_a_worker(n: int):
    """Kills the worker process that runs it; in the test's own process, draws."""
    if multiprocessing.parent_process() is not None:
        os._exit(3)
    return line_figure(n)


def test_a_figure_drawn_in_a_worker_is_the_one_drawn_here(fresh_pool, monkeypatch):
    remote = [line_figure(200), _render.later(line_figure, 300)]
    assert all(d.in_worker for d in remote)
    got = [d.png() for d in remote]
    monkeypatch.setenv(_render.WORKERS_ENV, "0")
    here = [line_figure(200), _render.later(line_figure, 300)]
    assert not any(d.in_worker for d in here)
    assert [d.png() for d in here] == got
    assert got[0] != got[1] and got[0][:8] == b"\x89PNG\r\n\x1a\n"


def test_an_unpicklable_figure_is_drawn_here_with_the_same_result(fresh_pool, monkeypatch):
    d = line_figure(50, formatter=lambda v, _: f"{v:.1f} s")
    assert not d.in_worker  # a lambda does not pickle: no worker gets it
    got = d.png()
    monkeypatch.setenv(_render.WORKERS_ENV, "0")
    assert line_figure(50, formatter=lambda v, _: f"{v:.1f} s").png() == got


def test_a_worker_that_dies_leaves_the_figure_to_this_process(fresh_pool, monkeypatch):
    d = _render.later(die_in_a_worker, 120)
    assert d.in_worker
    got = d.png()  # the worker died: drawn here instead
    monkeypatch.setenv(_render.WORKERS_ENV, "0")
    assert got == line_figure(120).png()
    monkeypatch.setenv(_render.WORKERS_ENV, "2")
    assert _render.start_drawing() is None  # the broken pool is not used again
    assert not line_figure(10).in_worker


def test_a_script_without_a_main_guard_runs_once(tmp_path):
    log = tmp_path / "ran.txt"
    script = tmp_path / "user_script.py"
    script.write_text(textwrap.dedent(f"""
        from pmdc_bayes.report._plot import png, subplots
        with open({str(log)!r}, "a") as fh:
            fh.write("ran\\n")
        fig, ax = subplots()
        ax.plot([0, 1], [1, 0])
        d = png(fig)
        assert d.in_worker
        assert d.png()[:4] == b"\\x89PNG"
        """), encoding="utf-8")
    env = {**os.environ, _render.WORKERS_ENV: "2"}
    subprocess.run([sys.executable, str(script)], check=True, env=env, timeout=120)
    assert log.read_text(encoding="utf-8") == "ran\n"


def test_the_figures_a_worker_builds_import_none_of_the_fitting_stack():
    code = ("import sys\n"
            "import pmdc_bayes.report._render, pmdc_bayes.report._view\n"
            "import pmdc_bayes.report.fig_traces, pmdc_bayes.report.fig_chains\n"
            "import pmdc_bayes.report.fig_params\n"
            "print(sorted(m for m in ('jax', 'arviz', 'xarray', 'emcee', 'scipy')"
            " if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, timeout=120).stdout
    assert out.strip() == "[]"


def test_the_report_style_applies_in_the_worker(fresh_pool):
    assert STYLE["savefig.dpi"] == 110
    d = line_figure(20)
    assert d.in_worker
    raw = d.png()
    width, height = np.frombuffer(raw[16:24], dtype=">u4")
    assert (int(width), int(height)) == (4 * 110, 3 * 110)


def test_workers_end_when_the_process_they_draw_for_is_killed(tmp_path):
    import signal
    import time

    script = tmp_path / "killed.py"
    script.write_text(textwrap.dedent("""
        import time
        from pmdc_bayes.report import _render
        from pmdc_bayes.report._plot import png, subplots
        fig, ax = subplots()
        ax.plot([0, 1], [1, 0])
        assert png(fig).png()[:4] == b"\\x89PNG"  # the workers are up
        print(*_render._pool._processes, flush=True)
        time.sleep(120)
        """), encoding="utf-8")
    env = {**os.environ, _render.WORKERS_ENV: "2"}
    with subprocess.Popen([sys.executable, str(script)], env=env, stdout=subprocess.PIPE,
                          text=True) as proc:
        pids = [int(p) for p in proc.stdout.readline().split()]
        assert len(pids) == 2
        proc.send_signal(signal.SIGKILL)  # no clean-up of any kind in the parent
        proc.wait(timeout=30)

    def alive(pid):
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        with open(f"/proc/{pid}/stat", encoding="ascii") as fh:  # a zombie has ended
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"

    deadline = time.monotonic() + 20
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(p) for p in pids)


def _draw_in_child(queue):
    """In a forked or daemonic child: draw a figure and report its first bytes."""
    queue.put(line_figure(30).png()[:8])


def test_a_daemonic_child_draws_its_own_figures(fresh_pool):
    """A daemonic process may not have children: it draws in-process."""
    assert line_figure(10).in_worker  # the parent's pool is up
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    child = ctx.Process(target=_draw_in_child, args=(queue,), daemon=True)
    child.start()
    try:
        assert queue.get(timeout=60) == b"\x89PNG\r\n\x1a\n"
    finally:
        child.join(timeout=60)
        if child.is_alive():
            child.kill()
    assert child.exitcode == 0


def test_a_fork_of_a_process_whose_pool_runs_draws_its_own_figures(tmp_path):
    """The parent's pool is not the child's to use (it would wait forever), and a child
    multiprocessing started must not leave a pool behind that it waits for at exit.
    In a process of its own: forking a test process that has imported JAX is unsafe."""
    script = tmp_path / "forked.py"
    script.write_text(textwrap.dedent("""
        import multiprocessing
        from pmdc_bayes.report._plot import png, subplots

        def figure():
            fig, ax = subplots()
            ax.plot([0, 1], [1, 0])
            return png(fig)

        def child(queue):
            d = figure()
            queue.put((d.in_worker, d.png()[:4]))

        if __name__ == "__main__":
            assert figure().in_worker  # the parent's pool is up
            ctx = multiprocessing.get_context("fork")
            queue = ctx.Queue()
            p = ctx.Process(target=child, args=(queue,))
            p.start()
            print(queue.get(timeout=60))
            p.join(timeout=60)
            print(p.exitcode)
        """), encoding="utf-8")
    env = {**os.environ, _render.WORKERS_ENV: "2"}
    out = subprocess.run([sys.executable, str(script)], env=env, capture_output=True,
                         text=True, timeout=180).stdout.split("\n")
    assert out[:2] == ["(False, b'\\x89PNG')", "0"]


def test_the_callers_rcparams_change_neither_path(fresh_pool, monkeypatch):
    import matplotlib

    with matplotlib.rc_context({"lines.linewidth": 6.0, "axes.facecolor": "0.8",
                                "font.size": 15}):
        remote = line_figure(40)
        assert remote.in_worker
        got = remote.png()
        monkeypatch.setenv(_render.WORKERS_ENV, "0")
        here = line_figure(40).png()
        assert matplotlib.rcParams["lines.linewidth"] == 6.0  # left as the caller set it
    assert got == here
    assert got == line_figure(40).png()  # and as under matplotlib's defaults
