"""Run directories: written whole or not at all, and never over anything of the user's.

A run is built in a temporary sibling and renamed into place once complete; its marker
file tells a later ``--force`` that the directory is an earlier run it may replace.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import tempfile
from datetime import datetime
from importlib import metadata
from pathlib import Path

from . import _signals
from ._errors import UsageError
from .io.output import default_mode

__all__ = ["versions", "default_out_dir", "RUN_MARKER", "SESSION_COPY", "is_run_dir",
           "check_replaceable", "write_atomically",
           "copy_session", "changed_files", "check_writable", "write_model",
           "sweep_unfinished"]


RUN_MARKER = ".pmdc-bayes-run"
_STORAGE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM,
                   errno.EFBIG}
SESSION_COPY = "session"
"""The run's own copy of the session's files, so that the run outlives the original."""


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def copy_session(session, dest: Path) -> dict[str, str]:
    """Copy the files of ``session`` into ``dest/session``, keeping their places relative
    to its session.toml; return ``{relative path: sha256}``.  A file outside the session
    directory is hashed but not copied (the copy then is incomplete and not used)."""
    root = Path(session.root).resolve()
    hashes = {}
    for f in session.files():
        rel = os.path.relpath(Path(f).resolve(), root)
        hashes[rel] = _sha256(f)
        if not rel.startswith(".."):
            target = dest / SESSION_COPY / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, target)
    return hashes


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(map(_toml_value, value)) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{json.dumps(k)} = {_toml_value(v)}"
                                for k, v in value.items()) + " }"
    return repr(float(value))


def _with_model(text: str, table: dict, friction: str) -> str:
    """``session.toml``'s text with its ``[model]`` table (and sub-tables) replaced by
    ``table`` and ``[motor] friction`` set to ``friction``."""
    out, skip, in_motor = [], False, False
    for line in text.splitlines():
        head = line.strip()
        if head.startswith("["):
            name = head.strip("[]").strip()
            skip = name == "model" or name.startswith("model.")
            in_motor = name == "motor"
            if in_motor and not skip:
                out += [line, f"friction = {_toml_value(friction)}"]
                continue
        if skip or (in_motor and head.split("=")[0].strip() == "friction"):
            continue
        out.append(line)
    if table:
        out += ["", "[model]"] + [f"{k} = {_toml_value(v)}" for k, v in table.items()]
    return "\n".join(out) + "\n"


def write_model(session, dest: Path, table: dict, friction: str) -> dict[str, str] | None:
    """Write the model a search chose (``table``, the ``[model]`` keys, and ``friction``)
    into the run's copy of ``session.toml`` under ``dest``, so that reading the copy gives
    the chosen model; ``{"session.toml": sha256}`` of the rewritten copy, or None when
    the copy is incomplete or the rewritten text would not read back as that model (the
    copy is then left as it was).  The record of the original files' hashes is kept."""
    from .io.loader import load_session
    from .terms import model_table, terms_of

    toml = dest / SESSION_COPY / "session.toml"
    if not toml.is_file():
        return None
    original = toml.read_text(encoding="utf-8")
    toml.write_text(_with_model(original, table, friction), encoding="utf-8")
    try:
        back = load_session(toml.parent)
        same = model_table(back, terms_of(back)) == (table, friction)
    except Exception:  # a text the edit could not keep valid: the copy stays the original
        same = False
    if not same:
        toml.write_text(original, encoding="utf-8")
        return None
    return {"session.toml": _sha256(toml)}


def changed_files(root: Path, hashes: dict[str, str]) -> list[str]:
    """The files of ``hashes`` (relative to ``root``) that are missing or differ now."""
    out = []
    for rel, digest in hashes.items():
        path = Path(root) / rel
        try:
            same = path.is_file() and _sha256(path) == digest
        except OSError:
            same = False
        if not same:
            out.append(rel)
    return out


def is_run_dir(path: Path) -> bool:
    """Whether ``path`` is a directory this tool wrote as a run: it holds the marker file
    (a summary.json alone proves nothing: a folder of the user's may have one)."""
    path = Path(path)
    return path.is_dir() and not path.is_symlink() and (path / RUN_MARKER).is_file() \
        and not (path / "session.toml").exists()


def check_writable(out: Path, *, what: str = "choose another --out") -> None:
    """Refuse an ``out`` that cannot be written in (an existing directory) or created:
    below a regular file, or in a read-only place (checked by creating and removing a
    probe directory, so read-only mounts are found whoever runs)."""
    base = out if out.is_dir() else out.parent
    while not base.exists() and base != base.parent:
        base = base.parent
    if not base.is_dir():
        raise UsageError(f"{out}: {base} is a file, not a directory; {what}")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".pmdc-bayes-probe.", dir=base))
    except OSError as exc:
        raise UsageError(f"{out}: cannot write in {base} ({exc.strerror}); {what}") from None


def _publish_modes(root: Path) -> None:
    for base, _dirs, files in os.walk(root):
        os.chmod(base, default_mode(True))
        for f in files:
            os.chmod(os.path.join(base, f), default_mode())


def check_replaceable(out: Path, force: bool) -> None:
    """Refuse, before any work, an ``out`` that cannot be written, or that exists unless
    ``force`` is given and it is a previous run: never a session, a regular file or a
    folder of the user's."""
    if len(os.fsencode(out.name)) > 200:
        raise UsageError(f"{out.name[:40]}...: the name is {len(out.name)} characters long, "
                         "more than a file system takes; choose a shorter --out")
    check_writable(out.parent if out.is_dir() else out)
    if not (out.exists() or out.is_symlink()):
        return
    if not force:
        raise UsageError(f"{out}: already exists; choose another --out or pass --force to "
                         "replace it")
    if not is_run_dir(out):
        what = ("a session directory" if (out / "session.toml").exists()
                else "not a directory" if not out.is_dir() else "not a pmdc-bayes run directory")
        raise UsageError(f"{out}: {what}; --force only replaces an earlier run, so choose "
                         "another --out")


def write_atomically(out: Path, fill, *, force: bool):
    check_replaceable(out, force)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f"{_partial_prefix(out)}{os.getpid()}-", dir=out.parent))
    try:
        (tmp / RUN_MARKER).write_text("a run directory written by pmdc-bayes fit\n")
        fill(tmp)
        _publish_modes(tmp)
        _signals.check()
        if out.exists():
            check_replaceable(out, force)
            old = _aside(out)
            shutil.rmtree(old, ignore_errors=True)
            os.replace(out, old)
            try:
                os.replace(tmp, out)
            except BaseException:  # interrupted between the two renames: put it back
                if not out.exists():
                    os.replace(old, out)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if exc.errno not in _STORAGE_ERRORS:
            raise
        raise UsageError(f"{out}: could not be written ({exc.strerror}); free some space or "
                         "choose another --out (nothing was left behind, an earlier run "
                         "there is intact)") from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _partial_prefix(out: Path) -> str:
    """The start of the name of a run being written to ``out`` (then the writer's pid)."""
    return f".{out.name}.pmdc-partial-"


def _aside(out: Path) -> Path:
    """Where an earlier run waits while its replacement is renamed into place."""
    return out.with_name(f".{out.name}.pmdc-replaced")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def sweep_unfinished(out: Path) -> list[Path]:
    """Put right what a :func:`write_atomically` of ``out`` left when its process was
    killed (a lot's worker stopped mid-fit), on this machine: the runs it was writing
    removed where their writer (the pid in the name) is gone, and an earlier run it had
    moved aside put back, or removed when ``out`` was replaced.  Touches only the names
    that function gives; the paths removed."""
    out = Path(out)
    if not out.parent.is_dir():
        return []
    removed = []
    prefix = _partial_prefix(out)
    for entry in out.parent.iterdir():
        pid = entry.name[len(prefix):].split("-", 1)[0]
        if entry.name.startswith(prefix) and pid.isdigit() and not _alive(int(pid)) \
                and entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
            removed.append(entry)
    old = _aside(out)
    writing = any(e.name.startswith(prefix) for e in out.parent.iterdir())
    if old.is_dir() and not old.is_symlink() and not writing:  # no writer between renames
        if out.exists() or out.is_symlink():
            shutil.rmtree(old, ignore_errors=True)
            removed.append(old)
        else:
            try:
                os.replace(old, out)
            except OSError:  # another process took the name meanwhile: leave both
                pass
    return removed


_LIBRARIES = ("pmdc-bayes", "jax", "jaxlib", "diffrax", "optimistix", "emcee", "arviz", "numpy")


def versions() -> dict:
    out = {}
    for lib in _LIBRARIES:
        try:
            out[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:
            out[lib] = None
    return out


def default_out_dir(session_name: str, root: Path | None = None) -> Path:
    """``reports/<session>-<timestamp>`` under the current directory (or ``root``)."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    return (root or Path.cwd() / "reports") / f"{session_name}-{stamp}"
