"""Run directories: written whole or not at all, and never over anything of the user's.

A run is built in a temporary sibling and renamed into place once complete; its marker
file tells a later ``--force`` that the directory is an earlier run it may replace.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ._errors import UsageError

__all__ = ["RUN_MARKER", "is_run_dir", "check_replaceable", "write_atomically"]


RUN_MARKER = ".pmdc-bayes-run"


def is_run_dir(path: Path) -> bool:
    """Whether ``path`` is a directory this tool wrote as a run (its marker file, or the
    summary.json of a run written before the marker existed, and no session.toml)."""
    path = Path(path)
    return path.is_dir() and not path.is_symlink() and not (path / "session.toml").exists() \
        and ((path / RUN_MARKER).is_file() or (path / "summary.json").is_file())


def check_replaceable(out: Path, force: bool) -> None:
    """Refuse, before any work, an ``out`` that exists unless ``force`` is given and it
    is a previous run: never a session, a regular file or a folder of the user's."""
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
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        (tmp / RUN_MARKER).write_text("a run directory written by pmdc-bayes fit\n")
        fill(tmp)
        if out.exists():
            check_replaceable(out, force)
            old = out.with_name(f".{out.name}.old")
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
