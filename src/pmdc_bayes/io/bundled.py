"""Locate the sessions bundled with pmdc-bayes (``data/paper``, ``data/demo``,
``data/bench``)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["bundled_session_dir", "BUNDLED", "DEFAULT_SESSION"]

BUNDLED = ("paper", "demo", "bench")
DEFAULT_SESSION = "demo"


def bundled_session_dir(name: str) -> Path:
    """Directory of a bundled session, from the installed wheel or a source checkout."""
    here = Path(__file__).resolve().parents[1]
    for candidate in (here / "_data" / name, here.parents[1] / "data" / name):
        if (candidate / "session.toml").is_file():
            return candidate
    raise FileNotFoundError(f"bundled session {name!r} is missing from this installation")
