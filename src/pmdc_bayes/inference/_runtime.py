"""Compiled functions kept across calls and, when enabled, across runs.

In a process, a compiled function is built once per name and session *structure*
(what the compiled code depends on besides the data it is given).  With
:func:`enable_cache`, two caches on disk let a later run skip the expensive steps too:
XLA's persistent compilation cache, and the traced and lowered program (exported
with :mod:`jax.export`), so that neither tracing nor compilation is repeated.  The
disk key includes the versions of jax and of this package's source, so a stale entry
is never used.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import threading
import time
from pathlib import Path

import jax
from jax import export

from ..physics.solution import Experiment

__all__ = ["enable_cache", "compiled", "release", "release_structure", "cache_dir",
           "announcing", "compile_seconds", "StageClock", "MAP_SHARE"]

_IN_MEMORY: dict = {}
_STATE = {"dir": None, "announce": None}
_LAPACK = ("lapack_dormqr_ffi", "lapack_dgeqrf_ffi", "lapack_dorgqr_ffi", "lapack_dtrsm_ffi",
           "lapack_dpotrf_ffi", "lapack_dgesdd_ffi", "lapack_dsyevd_ffi", "lapack_dgetrf_ffi")
export.register_namedtuple_serialization(Experiment, serialized_name="pmdc_bayes.Experiment")


_WORDS = {"optimistix-step": "MAP's (optimistix step)", "predict": "prediction",
          "log_posterior_batch": "sampler's log-posterior",
          "pointwise-residuals": "pointwise log-likelihood"}  # names in the progress lines
_TRACED_PACKAGES = ("physics", "inference")
_TRACED_LIBRARIES = ("jax", "jaxlib", "optimistix", "equinox", "lineax", "diffrax")


def _source_hash() -> str:
    """The versions of every traced library and the source of every module of this
    package whose code gets traced (the physics and inference subpackages)."""
    from importlib import metadata

    h = hashlib.sha256()
    for lib in _TRACED_LIBRARIES:
        try:
            h.update(f"{lib}={metadata.version(lib)};".encode())
        except metadata.PackageNotFoundError:
            h.update(f"{lib}=none;".encode())
    root = Path(__file__).resolve().parents[1]
    for sub in _TRACED_PACKAGES:
        for file in sorted((root / sub).rglob("*.py")):
            h.update(file.relative_to(root).as_posix().encode())
            h.update(file.read_bytes())
    return h.hexdigest()[:16]


def enable_cache(path: str | Path) -> None:
    """Keep compiled programs under ``path`` (created if needed)."""
    path = Path(path)
    (path / "export").mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(path / "xla"))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
    _STATE["dir"] = path / "export" / _source_hash()
    _STATE["dir"].mkdir(exist_ok=True)


def cache_dir() -> Path | None:
    return _STATE["dir"]


@contextlib.contextmanager
def announcing(say):
    """While the block runs, ``say(line)`` as a program not in the disk cache starts
    compiling (the first use of a session shape), so that a long pause is explained."""
    previous, _STATE["announce"] = _STATE["announce"], say
    try:
        yield
    finally:
        _STATE["announce"] = previous


class _Compiled:
    """Calls a compiled function, one program per signature of its arguments, each
    made under a lock on its first call (so that a program a background thread is
    compiling, see :mod:`.warmup`, is waited for, never compiled twice).

    With a disk cache (``stem`` given) the program is exported there (an exported
    program has fixed shapes) or loaded from it, and called through ``jax.jit``,
    whose compilation XLA's persistent cache keeps."""

    def __init__(self, jitted, stem: Path | None):
        self.jitted, self.stem, self.programs = jitted, stem, {}
        self.lock = threading.Lock()

    def __call__(self, *args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        fast = (treedef, tuple((type(x), getattr(x, "shape", None), getattr(x, "dtype", None))
                               for x in leaves))
        program = self.programs.get(fast)
        if program is not None:
            return program(*args)
        with self.lock:  # threads (a warm-up, the sampler's ensembles) make it once
            program = self.programs.get(fast)
            if program is not None:
                return program(*args)
            signature = repr((treedef, [(jax.numpy.shape(x), str(jax.numpy.result_type(x)))
                                        for x in leaves]))
            program = self.programs.get(signature) or self._load(args, signature)
            out = program(*args)  # compiles it, or loads it from XLA's cache
            self.programs[signature] = self.programs[fast] = program
            return out

    def _load(self, args, signature: str):
        if self.stem is None:
            return self.jitted
        digest = hashlib.sha256(signature.encode()).hexdigest()[:16]
        file = self.stem.with_name(f"{self.stem.name}-{digest}.jaxexport")
        exp = None
        if file.is_file():
            try:
                exp = export.deserialize(bytearray(file.read_bytes()))
            except Exception:  # a damaged entry: rebuild it
                exp = None
        if exp is None:
            if _STATE["announce"] is not None:
                name = self.stem.name.rsplit("-", 1)[0]
                what = _WORDS.get(name, name.replace("_", " ").replace("-", " "))
                _STATE["announce"](f"compiling the {what} program (first use of this "
                                   "session shape; kept in the cache)")
            checks = [export.DisabledSafetyCheck.custom_call(n) for n in _LAPACK]
            exp = export.export(self.jitted, disabled_checks=checks)(*args)
            tmp = file.with_suffix(f".{os.getpid()}.tmp")
            try:
                tmp.write_bytes(exp.serialize())
                tmp.replace(file)
            except OSError:  # a read-only or full cache: run without storing the program
                with contextlib.suppress(OSError):
                    tmp.unlink(missing_ok=True)
        # Called through jit: one fast dispatch per call instead of an eager custom-VJP
        # call of the exported module (about 3 ms of Python per call).
        return jax.jit(exp.call)


_BUILDING = threading.Lock()


MAP_SHARE = 0.5  # of the system's limit on a process's memory maps: then programs are let go


def _map_pressure() -> bool:
    """Whether this process holds more than :data:`MAP_SHARE` of the memory maps the
    system allows one (Linux's ``vm.max_map_count``): every compiled program keeps its
    own, and a process that makes hundreds (a lot of motors of many shapes, a long model
    search) would otherwise fail in the compiler when the limit is reached.  False
    where the system does not say."""
    try:
        limit = int(Path("/proc/sys/vm/max_map_count").read_text())
        with open("/proc/self/maps", "rb") as maps:
            held = sum(1 for _ in maps)
    except (OSError, ValueError):
        return False
    return held > MAP_SHARE * limit


def release() -> None:
    """Let go of every compiled program this process keeps (made again, or loaded from
    the disk cache, when next asked for)."""
    _IN_MEMORY.clear()
    jax.clear_caches()
    _collect()


def release_structure(structure: tuple) -> None:
    """Let go of the compiled programs of one session structure, under every name (a
    model a search has dropped: a stick-slip model's programs hold about half a gigabyte
    each); made again, or loaded from the disk cache, if asked for again.  A program a
    thread is making or running meanwhile is finished, then dropped."""
    with _BUILDING:
        held = [k for k in _IN_MEMORY if k[1:] == structure]
        for key in held:
            del _IN_MEMORY[key]
    if held:
        _collect()


def _collect() -> None:
    """Collect what was let go, and hand the freed memory back to the system where its C
    library can (glibc's ``malloc_trim``), so that the process's size shows it."""
    import ctypes
    import gc

    gc.collect()
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6").malloc_trim(0)


def compiled(key: tuple, build):
    """The function ``build()`` returns (a ``jax.jit``-ed function of arrays), built once
    per ``key``; exported to and loaded from disk when :func:`enable_cache` was called.  When
    the process nears its limit of memory maps (:func:`_map_pressure`), the programs
    kept so far are let go first (:func:`release`)."""
    fn = _IN_MEMORY.get(key)
    if fn is None:
        with _BUILDING:
            fn = _IN_MEMORY.get(key)
            if fn is None and _map_pressure():
                release()
            if fn is None:
                digest = hashlib.sha256(repr(key).encode()).hexdigest()[:24]
                stem = None if _STATE["dir"] is None else _STATE["dir"] / f"{key[0]}-{digest}"
                fn = _IN_MEMORY[key] = _Compiled(build(), stem)
    return fn


# JAX's own timings of making a program: tracing a top-level function, lowering it to
# MLIR, and compiling it with XLA (or loading it from the persistent cache).
_COMPILE_EVENTS = frozenset({"/jax/core/compile/jaxpr_trace_duration",
                             "/jax/core/compile/jaxpr_to_mlir_module_duration",
                             "/jax/core/compile/backend_compile_duration"})
_CLOCK = {"seconds": 0.0, "listening": False}
_CLOCK_LOCK = threading.Lock()  # programs are made in several threads at once


def _on_duration(event: str, duration: float, **_) -> None:
    if event in _COMPILE_EVENTS:
        with _CLOCK_LOCK:
            _CLOCK["seconds"] += duration


def compile_seconds() -> float:
    """Seconds this process has spent making JAX programs (tracing, lowering, compiling
    or loading them from the persistent cache) since the first call (which starts the
    count by listening to :mod:`jax.monitoring`)."""
    with _CLOCK_LOCK:
        if not _CLOCK["listening"]:
            jax.monitoring.register_event_duration_secs_listener(_on_duration)
            _CLOCK["listening"] = True
        return _CLOCK["seconds"]


class StageClock:
    """Wall time and the part of it spent making JAX programs, per stage of a run
    (``wall`` and ``compile``, in seconds, keyed by stage)."""

    def __init__(self):
        self.wall, self.compile = {}, {}
        self._t0, self._c0 = time.perf_counter(), compile_seconds()

    @contextlib.contextmanager
    def stage(self, name: str):
        t0, c0 = time.perf_counter(), compile_seconds()
        try:
            yield
        finally:
            self.wall[name] = time.perf_counter() - t0
            self.compile[name] = compile_seconds() - c0

    def total(self) -> None:
        """Record the time since the clock started as ``total``."""
        self.wall["total"] = time.perf_counter() - self._t0
        self.compile["total"] = compile_seconds() - self._c0
