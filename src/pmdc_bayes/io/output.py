"""JSON for run summaries: NumPy scalars and arrays become plain numbers and lists."""

from __future__ import annotations

import json

import numpy as np

__all__ = ["dumps"]


def _default(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def dumps(obj) -> str:
    """``json.dumps`` with two-space indentation that also takes NumPy values."""
    return json.dumps(obj, indent=2, default=_default)
