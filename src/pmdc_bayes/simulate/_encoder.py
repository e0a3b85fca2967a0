"""What an encoder logs of the bench's angle: counts at the samples, or the time of
every edge (the bench simulator's encoder outputs)."""

from __future__ import annotations

import numpy as np

from ..io._position import speed_estimate

__all__ = ["ENCODER_OUTPUTS", "counted_angle", "edge_times", "encoder_trace_parts", "EDGE_FINE"]

ENCODER_OUTPUTS = ("speed", "position", "edges")
EDGE_FINE = 50  # integration points per sample interval when edges are located


def counted_angle(theta: np.ndarray, q: float) -> np.ndarray:
    """The angle an encoder of step ``q`` (rad) reports: counted down with ``floor``."""
    return np.floor(theta / q + 1e-9) * q


def edge_times(t_fine: np.ndarray, theta: np.ndarray, q: float, resolution: float) -> tuple:
    """The times (s) at which a forward-turning rotor crosses each count ``k·q``
    (k ≥ 1), located by linear interpolation on the fine grid and rounded to the
    timer's ``resolution``; with the angle at each edge."""
    top = np.maximum.accumulate(theta)
    k = np.arange(1, int(np.floor(top[-1] / q + 1e-9)) + 1)
    if k.size == 0:
        return np.zeros(0), np.zeros(0)
    up = np.concatenate([[True], np.diff(top) > 0])
    times = np.interp(k * q, top[up], t_fine[up])
    times = np.round(times / resolution) * resolution
    keep = np.concatenate([[True], np.diff(times) > 0])
    return times[keep], (k * q)[keep]


def encoder_trace_parts(mode: str, t: np.ndarray, theta: np.ndarray, q: float,
                        fine=None, resolution: float = 1e-6) -> dict:
    """``time``, ``speed`` (estimated), ``position`` (NaN where not read) and the count
    of an encoder trace: ``mode`` ``"position"`` counts at the samples ``t``; ``"edges"``
    the edge times from ``fine = (t_fine, theta_fine)``, after a first, unread sample
    at ``t[0]`` (the rotor at rest)."""
    if mode == "position":
        pos = counted_angle(theta, q)
        return {"time": t, "position": pos, "speed": speed_estimate(t, pos)}
    times, angles = edge_times(*fine, q, resolution)
    time = np.concatenate([t[:1], times])
    pos = np.concatenate([[np.nan], angles])
    return {"time": time, "position": pos, "speed": speed_estimate(time, pos)}
