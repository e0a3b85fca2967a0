"""The cache of compiled programs: keyed on every traced library, robust to damaged or
unwritable entries, bounded, and cleared without touching anything else."""

import os
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes import cachedir, cli
from pmdc_bayes.inference import _runtime as cache


@pytest.fixture
def disk_cache(tmp_path, monkeypatch):
    """The package's disk cache in ``tmp_path``, restored afterwards."""
    monkeypatch.setenv("PMDC_BAYES_CACHE", str(tmp_path / "cache"))
    state, xla = dict(cache._STATE), jax.config.jax_compilation_cache_dir
    memory = dict(cache._IN_MEMORY)
    cache._IN_MEMORY.clear()
    assert cachedir.enable()
    yield tmp_path / "cache"
    cache._STATE.update(state)
    jax.config.update("jax_compilation_cache_dir", xla)
    cache._IN_MEMORY.clear()
    cache._IN_MEMORY.update(memory)


def _cubes():
    return cache.compiled(("test_cubes", 1), lambda: jax.jit(lambda x: x ** 3))


def test_the_key_changes_with_any_traced_library(monkeypatch):
    from importlib import metadata

    before = cache._source_hash()
    real = metadata.version
    for lib in ("jax", "jaxlib", "optimistix", "equinox", "lineax", "diffrax"):
        monkeypatch.setattr(metadata, "version",
                            lambda name, lib=lib: "0.0.0" if name == lib else real(name))
        assert cache._source_hash() != before, lib
    monkeypatch.setattr(metadata, "version", real)
    assert cache._source_hash() == before


def test_a_test_run_leaves_no_cache_directory_behind(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    tests = Path(__file__).resolve().parent
    env = {k: v for k, v in os.environ.items() if k != "PMDC_BAYES_CACHE"}
    env["TMPDIR"] = str(tmp_path)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
         f"{tests / 'test_format.py'}::test_without_an_sd_six_significant_digits"],
        cwd=tests.parents[1], env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert list(tmp_path.glob("pmdc-bayes-test-cache-*")) == []


def test_a_damaged_entry_is_rebuilt(disk_cache):
    x = jnp.arange(3.0)
    assert np.allclose(_cubes()(x), [0, 1, 8])
    (entry,) = disk_cache.glob("export/*/test_cubes-*.jaxexport")
    entry.write_bytes(b"not a program")
    cache._IN_MEMORY.clear()
    assert np.allclose(_cubes()(x), [0, 1, 8])
    assert entry.read_bytes() != b"not a program"


def test_a_stored_program_is_traced_once_and_then_dispatched_compiled(disk_cache,
                                                                      monkeypatch):
    """A program from the disk cache runs through one jit-compiled call: the exported
    module is traced once per shape, not called op by op on every call (which cost
    about 3 ms of Python per call of the sampler's log-posterior)."""
    from jax import export

    traced = []
    call = export.Exported.call
    monkeypatch.setattr(export.Exported, "call",
                        lambda self, *a: (traced.append(1), call(self, *a))[1])
    for _ in range(5):
        assert np.allclose(_cubes()(jnp.arange(3.0)), [0, 1, 8])
    assert len(traced) == 1
    cache._IN_MEMORY.clear()  # a later run: the program comes from disk
    for k in range(5):
        assert np.allclose(_cubes()(jnp.arange(3.0) + k), (np.arange(3.0) + k) ** 3)
    assert len(traced) == 2
    assert np.allclose(_cubes()(jnp.arange(4.0)), [0, 1, 8, 27])  # another shape
    assert len(traced) == 3


def test_a_program_compiled_for_the_first_time_is_announced_once(disk_cache):
    lines = []
    with cache.announcing(lines.append):
        for _ in range(3):
            _cubes()(jnp.arange(3.0))
        cache._IN_MEMORY.clear()
        _cubes()(jnp.arange(3.0))  # a later run: from disk, nothing compiles anew
        _cubes()(jnp.arange(5.0))  # another shape
    _cubes()(jnp.arange(7.0))  # outside the block: silent
    assert lines == ["compiling the test cubes program (first use of this session shape; "
                     "kept in the cache)"] * 2


def test_an_unwritable_cache_still_computes(disk_cache, monkeypatch):
    from pathlib import Path

    def refuse(self, data):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(Path, "write_bytes", refuse)
    assert np.allclose(_cubes()(jnp.arange(2.0)), [0, 1])
    assert list(disk_cache.glob("export/*/test_cubes-*")) == []


def _file(path, size, age):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x" * size)
    t = 1_700_000_000 - age
    os.utime(path, (t, t))
    return path


def test_prune_drops_the_least_recently_used_programs_first(tmp_path, monkeypatch):
    monkeypatch.setenv("PMDC_BAYES_CACHE", str(tmp_path))
    old = _file(tmp_path / "export" / "a" / "old.jaxexport", 600, age=300)
    mid = _file(tmp_path / "xla" / "mid", 600, age=200)
    new = _file(tmp_path / "export" / "a" / "new.jaxexport", 600, age=100)
    log = _file(tmp_path / "logs" / "error-1.log", 5000, age=400)  # not a program
    assert cachedir.prune(1300) == 600
    assert not old.exists() and mid.exists() and new.exists() and log.exists()
    assert cachedir.prune(0) == 1200 and log.exists()


def test_clear_deletes_only_what_the_tool_wrote(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PMDC_BAYES_CACHE", str(tmp_path))
    mine = _file(tmp_path / "notes.txt", 10, age=0)
    keep = _file(tmp_path / "project" / "data.csv", 10, age=0)
    _file(tmp_path / "export" / "a" / "p.jaxexport", 100, age=0)
    _file(tmp_path / "xla" / "q", 200, age=0)
    assert cli.main(["cache", "info"]) == 0
    out = capsys.readouterr().out
    assert str(tmp_path) in out and "export" in out and "xla" in out
    assert cli.main(["cache", "clear"]) == 0
    assert mine.exists() and keep.exists()
    assert not (tmp_path / "export").exists() and not (tmp_path / "xla").exists()
    assert "0.0 MB freed" in capsys.readouterr().out


def test_the_bound_comes_from_the_environment(monkeypatch):
    monkeypatch.setenv("PMDC_BAYES_CACHE_MAX_MB", "1.5")
    assert cachedir.max_bytes() == int(1.5 * 2**20)
    monkeypatch.setenv("PMDC_BAYES_CACHE_MAX_MB", "lots")
    assert cachedir.max_bytes() == 2000 * 2**20


def test_fit_says_when_it_compiles_for_a_new_session_shape(disk_cache, tmp_path, capsys):
    """``fit --verbose`` names each program it compiles on a fresh cache, and none on a
    second run of the same session shape."""
    cli.main(["fit", "paper", "--no-mcmc", "--no-search", "--out", str(tmp_path / "a"), "-v"])
    first = capsys.readouterr().err
    assert "compiling the MAP's (optimistix step) program (first use of this session shape" \
        in first
    cache._IN_MEMORY.clear()  # a new process: programs come from the disk cache
    cli.main(["fit", "paper", "--no-mcmc", "--no-search", "--out", str(tmp_path / "b"), "-v"])
    second = capsys.readouterr().err
    assert "MAP fit of" in second and "compiling the" not in second


@pytest.mark.parametrize("on_disk", [False, True])
def test_threads_that_reach_a_new_program_together_make_it_once(on_disk, request):
    import threading

    if on_disk:
        request.getfixturevalue("disk_cache")
    traces = []

    def body(x):
        traces.append(1)  # runs once per trace
        return jnp.sin(x) * 2.0

    fn = cache.compiled(("test_threads", on_disk), lambda: jax.jit(body))
    start = threading.Barrier(4)
    out = [None] * 4

    def call(k):
        start.wait()
        with jax.enable_x64(True):  # per thread, as the package's callers switch it on
            out[k] = np.asarray(fn(jnp.arange(5.0) + 0.0))

    workers = [threading.Thread(target=call, args=(k,)) for k in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    assert all(np.array_equal(o, 2.0 * np.sin(np.arange(5.0))) for o in out)
    assert len(traces) == 1
    assert len({id(p) for p in fn.programs.values()}) == 1


def test_compile_seconds_count_a_new_program_and_not_a_second_call():
    x, y = np.arange(7.0), np.arange(7.0) + 1.0  # NumPy: no eager JAX op to compile
    before = cache.compile_seconds()
    f = jax.jit(lambda x: jnp.cumsum(jnp.exp(x)) @ jnp.ones(7))
    f(x)
    made = cache.compile_seconds()
    assert made > before
    f(y)
    assert cache.compile_seconds() == made
    clock = cache.StageClock()
    with clock.stage("again"):
        f(x)
    with clock.stage("new"):
        jax.jit(lambda x: jnp.tanh(x) ** 3)(y)
    clock.total()
    assert clock.compile["again"] == 0.0 < clock.compile["new"] <= clock.compile["total"]
    assert set(clock.wall) == {"again", "new", "total"}


def test_a_stage_line_is_one_write_so_threads_cannot_split_it(monkeypatch):
    """The warm-up threads announce their compilations while the main thread announces
    its stages: each line goes out in one write (a print of the text and then of the
    newline could be split by another thread's line)."""
    import argparse
    import threading

    writes = []

    class Stream:
        def write(self, text):
            writes.append(text)

        def flush(self):
            pass

        def isatty(self):
            return False

    monkeypatch.setattr(sys, "stderr", Stream())
    say = cli._stage_printer(argparse.Namespace(quiet=False, verbose=True))
    threads = [threading.Thread(target=say, args=(f"compiling program {k}",))
               for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(writes) == 8
    assert all(w.startswith("pmdc-bayes: [") and w.endswith("\n") and w.count("\n") == 1
               for w in writes)


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="no /proc memory maps here")
def test_programs_are_let_go_when_the_process_nears_its_memory_map_limit(monkeypatch):
    """Each compiled program keeps memory maps; a process making hundreds would reach the
    system's limit and fail in the compiler, so past MAP_SHARE of it those kept are let
    go before the next is made (and made again when next asked for)."""
    cache.compiled(("map-test-a",), lambda: jax.jit(lambda x: x + 1))
    assert ("map-test-a",) in cache._IN_MEMORY
    monkeypatch.setattr(cache, "MAP_SHARE", 1.0)
    assert not cache._map_pressure()
    cache.compiled(("map-test-b",), lambda: jax.jit(lambda x: x + 2))
    assert ("map-test-a",) in cache._IN_MEMORY  # far from the limit: kept
    monkeypatch.setattr(cache, "MAP_SHARE", 0.0)
    assert cache._map_pressure()
    fn = cache.compiled(("map-test-c",), lambda: jax.jit(lambda x: 2 * x))
    assert set(cache._IN_MEMORY) == {("map-test-c",)}
    assert float(fn(3.0)) == 6.0


def test_one_structure_s_programs_are_let_go_and_made_again_when_asked(monkeypatch):
    """A model a search has dropped: its programs under every name are let go, another
    structure's kept; asked for again, a program is made anew."""
    monkeypatch.setattr(cache, "_IN_MEMORY", {})
    built = []

    def program(name, structure, k):
        return cache.compiled((name,) + structure,
                              lambda: built.append((name, structure)) or jax.jit(lambda x: x + k))

    for name in ("step", "predict"):
        program(name, ("dropped", 1), 1)(1.0)
        program(name, ("kept", 2), 2)(1.0)
    cache.release_structure(("dropped", 1))
    assert set(cache._IN_MEMORY) == {("step", "kept", 2), ("predict", "kept", 2)}
    assert float(program("step", ("kept", 2), 2)(1.0)) == 3.0 and len(built) == 4
    assert float(program("step", ("dropped", 1), 1)(1.0)) == 2.0
    assert built[-1] == ("step", ("dropped", 1))
