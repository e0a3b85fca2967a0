"""Noise bookkeeping for the objective: model-free noise levels and channel records."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Channel", "noise_scale", "typical_level"]


def noise_scale(y: np.ndarray) -> float:
    """Model-free noise level of a sampled signal (robust, from second differences).

    For white noise σ, second differences have standard deviation σ·√6; the median
    absolute deviation ignores the few samples where the signal itself bends.  A
    quantised signal whose differences are mostly zero gets the quantisation noise
    q/√12 of its smallest step as a floor.
    """
    y = np.asarray(y, dtype=float)
    d2 = np.diff(y, 2)
    mad = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
    steps = np.abs(np.diff(y))
    steps = steps[steps > 1e-12 * max(1.0, np.abs(y).max())]
    quantum = steps.min() / np.sqrt(12.0) if steps.size else 0.0
    return float(max(mad, quantum, 1e-9 * max(1e-12, np.abs(y).max())))


@dataclass(frozen=True)
class Channel:
    """A group of observations sharing one unknown noise level."""

    name: str
    unit: str
    n: int
    s0: float


def typical_level(x, mask) -> float:
    """Mean absolute value of the masked entries (1 when there are none)."""
    vals = np.abs(np.asarray(x)[np.asarray(mask)])
    return float(np.mean(vals)) if vals.size else 1.0
