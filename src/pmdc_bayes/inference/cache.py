"""Compiled functions kept across calls and, when enabled, across runs.

In a process, a compiled function is built once per name and session *structure*
(what the compiled code depends on besides the data it is given).  With
:func:`enable`, two caches on disk let a later run skip the expensive steps too:
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
from pathlib import Path

import jax
from jax import export

from ..physics.solution import Experiment

__all__ = ["enable", "compiled", "cache_dir", "announcing"]

_IN_MEMORY: dict = {}
_STATE = {"dir": None, "announce": None}
_LAPACK = ("lapack_dormqr_ffi", "lapack_dgeqrf_ffi", "lapack_dorgqr_ffi", "lapack_dtrsm_ffi",
           "lapack_dpotrf_ffi", "lapack_dgesdd_ffi", "lapack_dsyevd_ffi", "lapack_dgetrf_ffi")
export.register_namedtuple_serialization(Experiment, serialized_name="pmdc_bayes.Experiment")


_WORDS = {"gauss-newton": "MAP's (Gauss–Newton)", "predict": "prediction",
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
        for file in sorted((root / sub).glob("*.py")):
            h.update(file.name.encode())
            h.update(file.read_bytes())
    return h.hexdigest()[:16]


def enable(path: str | Path) -> None:
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


class _Exported:
    """Calls a program exported to disk, one per signature of its arguments (an
    exported program has fixed shapes); exports it on the first call if missing.  Each
    loaded program is called through ``jax.jit``, whose compilation XLA's persistent
    cache keeps."""

    def __init__(self, jitted, stem: Path):
        self.jitted, self.stem, self.programs = jitted, stem, {}
        self.lock = threading.Lock()

    def _program(self, args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        fast = (treedef, tuple((type(x), getattr(x, "shape", None), getattr(x, "dtype", None))
                               for x in leaves))
        if fast in self.programs:
            return self.programs[fast]
        with self.lock:  # threads (the sampler's ensembles) load or export it once
            return self._load(args, leaves, treedef, fast)

    def _load(self, args, leaves, treedef, fast):
        if fast in self.programs:
            return self.programs[fast]
        signature = repr((treedef, [(jax.numpy.shape(x), str(jax.numpy.result_type(x)))
                                    for x in leaves]))
        if signature in self.programs:
            self.programs[fast] = self.programs[signature]
            return self.programs[signature]
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
        self.programs[signature] = self.programs[fast] = jax.jit(exp.call)
        return self.programs[signature]

    def __call__(self, *args):
        return self._program(args)(*args)


def compiled(key: tuple, build):
    """The function ``build()`` returns (a ``jax.jit``-ed function of arrays), built once
    per ``key``; exported to and loaded from disk when :func:`enable` was called."""
    if key not in _IN_MEMORY:
        fn = build()
        if _STATE["dir"] is not None:
            digest = hashlib.sha256(repr(key).encode()).hexdigest()[:24]
            fn = _Exported(fn, _STATE["dir"] / f"{key[0]}-{digest}")
        _IN_MEMORY[key] = fn
    return _IN_MEMORY[key]
