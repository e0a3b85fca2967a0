"""What the package writes: JSON that takes NumPy values, files with the mode a new file
of the user's gets, each written whole through a temporary file beside it."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np

__all__ = ["dumps", "default_mode", "write_whole"]


def _default(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def dumps(obj) -> str:
    """``json.dumps`` with two-space indentation that also takes NumPy values."""
    return json.dumps(obj, indent=2, default=_default)


def default_mode(directory: bool = False) -> int:
    """The mode a new file (0644 under the usual umask 022) or directory (0755) gets;
    temporary files are created private, and take this mode when they become the run."""
    mask = os.umask(0)
    os.umask(mask)
    return (0o777 if directory else 0o666) & ~mask


def write_whole(path: Path, data: bytes | str) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` via a temporary file in the same
    directory and ``os.replace``: the file is the old one or the new one, never half."""
    raw = data.encode("utf-8") if isinstance(data, str) else data
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(raw)
        os.chmod(tmp, default_mode())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
