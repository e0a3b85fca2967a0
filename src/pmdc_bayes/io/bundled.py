"""Locate the sessions bundled with pmdc-bayes (``data/paper``, ``data/demo``,
``data/bench``)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["bundled_session_dir", "session_path", "BUNDLED", "DEFAULT_SESSION"]

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
    ``"paper"``, ``"bench"``) when no such directory exists here; the default session
    for None."""
    if arg is None:
        return bundled_session_dir(DEFAULT_SESSION)
    p = Path(arg)
    if not p.exists() and str(arg) in BUNDLED:
        return bundled_session_dir(str(arg))
    return p
