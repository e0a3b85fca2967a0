"""The tool's cache directory: compiled programs, and the logs of internal errors.

``$PMDC_BAYES_CACHE`` or ``~/.cache/pmdc-bayes``.  It holds only what this tool puts
there (``export/``, ``xla/``, ``logs/``), and only those are ever cleared: pointing the
variable at a folder of your own never deletes anything else in it.  Its compiled
programs are kept under a size bound (``$PMDC_BAYES_CACHE_MAX_MB``, default 2000 MB):
after a run, the least recently used are dropped until it is under the bound.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

__all__ = ["location", "enable", "use_cache", "save_traceback", "info", "clear", "prune",
           "max_bytes"]

_OWNED = ("export", "xla", "logs")
_PROGRAMS = ("export", "xla")
_DEFAULT_MAX_MB = 2000


def location() -> Path:
    return Path(os.environ.get("PMDC_BAYES_CACHE", Path.home() / ".cache" / "pmdc-bayes"))


def max_bytes() -> int:
    text = os.environ.get("PMDC_BAYES_CACHE_MAX_MB", str(_DEFAULT_MAX_MB))
    try:
        return max(0, int(float(text) * 2**20))
    except ValueError:
        return _DEFAULT_MAX_MB * 2**20


def enable() -> bool:
    """Keep compiled programs in the cache directory across runs (64-bit JAX on); False
    when the directory cannot be used (the run then compiles without storing)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from .inference import enable_cache

    try:
        enable_cache(location())
    except OSError:
        return False
    return True


def use_cache(path=None) -> Path:
    """From Python: keep compiled programs on disk, as ``pmdc-bayes fit`` does, so that
    a later interpreter (a restarted notebook, another script) fitting sessions of the
    same shape skips the compilation.

    Parameters
    ----------
    path : the cache directory; by default the command line's (``$PMDC_BAYES_CACHE`` or
        ``~/.cache/pmdc-bayes``), so ``pmdc-bayes cache info|clear`` see it.

    Returns the directory.  Call it before the first fit of the session's shape: what
    was compiled before stays in memory only.  It sets JAX's persistent compilation
    cache directory, a process-wide JAX setting, and nothing else (JAX's 64-bit mode is
    left as it is).  Raises ``OSError`` when the directory cannot be created.
    """
    from .inference import enable_cache

    root = location() if path is None else Path(path)
    enable_cache(root)
    return root


def save_traceback() -> str:
    """Write the current exception's traceback to a new log file in ``logs/`` (the
    system's temporary directory if that is not writable); its path."""
    prefix = time.strftime("error-%Y%m%d-%H%M%S-")
    try:
        logs = location() / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        fd, path = tempfile.mkstemp(prefix=prefix, suffix=".log", dir=logs)
    except OSError:
        fd, path = tempfile.mkstemp(prefix="pmdc-bayes-" + prefix, suffix=".log")
    with open(fd, "w", encoding="utf-8") as fh:
        fh.write(" ".join(sys.argv) + "\n\n" + traceback.format_exc())
    return path


def _files(sub: str):
    root = location() / sub
    if not root.is_dir():
        return []
    out = []
    for base, _dirs, names in os.walk(root):
        for name in names:
            path = Path(base) / name
            try:
                st = path.stat()
            except OSError:
                continue
            out.append((path, st.st_size, max(st.st_atime, st.st_mtime)))
    return out


def info() -> dict:
    """Where the cache is, and the files and bytes of each part."""
    parts = {sub: _files(sub) for sub in _OWNED}
    return {"location": str(location()), "max_bytes": max_bytes(),
            "parts": {sub: {"files": len(f), "bytes": sum(s for _, s, _ in f)}
                      for sub, f in parts.items()}}


def clear() -> int:
    """Delete the parts of the cache this tool writes; the bytes freed."""
    freed = sum(s for sub in _OWNED for _, s, _ in _files(sub))
    for sub in _OWNED:
        shutil.rmtree(location() / sub, ignore_errors=True)
    return freed


def prune(limit: int | None = None) -> int:
    """Drop the least recently used compiled programs until they take at most ``limit``
    bytes (default :func:`max_bytes`); the bytes freed."""
    limit = max_bytes() if limit is None else limit
    files = sorted((f for sub in _PROGRAMS for f in _files(sub)), key=lambda f: f[2])
    total, freed = sum(s for _, s, _ in files), 0
    for path, size, _ in files:
        if total - freed <= limit:
            break
        try:
            path.unlink()
            freed += size
        except OSError:
            continue
    return freed
