"""Locate the sessions bundled with pmdc-bayes (``data/paper``, ``data/demo``,
``data/bench``)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["bundled_session_dir", "session_path", "passed_over", "BUNDLED", "DEFAULT_SESSION"]

BUNDLED = ("paper", "demo", "bench")
DEFAULT_SESSION = "demo"


def bundled_session_dir(name: str) -> Path:
    """Directory of a bundled session, from the installed wheel or a source checkout."""
    here = Path(__file__).resolve().parents[1]
    for candidate in (here / "_data" / name, here.parents[1] / "data" / name):
        if (candidate / "session.toml").is_file():
            return candidate
    raise FileNotFoundError(f"bundled session {name!r} is missing from this installation")


def session_path(arg) -> Path:
    """A session directory, or the bundled session of that name (``"demo"``,
    ``"paper"``, ``"bench"``) when nothing of that name here holds a session.toml (a run
    directory ``demo/`` written by ``pmdc-bayes fit demo --out demo`` is no session); the
    default session for None.  ``./demo`` names the local directory whatever it holds."""
    if arg is None:
        return bundled_session_dir(DEFAULT_SESSION)
    if _names_bundled(arg):
        return bundled_session_dir(str(arg))
    return Path(arg)


def _names_bundled(arg) -> bool:
    return str(arg) in BUNDLED and not (Path(arg) / "session.toml").exists()


def passed_over(arg) -> Path | None:
    """The local path that ``arg``, a bundled session's name, also names but which is not
    a session (so the bundled session is used instead); None when there is none."""
    if arg is None or not _names_bundled(arg):
        return None
    p = Path(arg)
    return p if p.exists() or p.is_symlink() else None
