"""What an encoder logs of the bench's angle: counts at the samples, or the time of
every edge (the bench simulator's encoder outputs)."""

from __future__ import annotations

import numpy as np

from ..io.position import speed_estimate

__all__ = ["ENCODER_OUTPUTS", "counted_angle", "edge_times", "encoder_trace_parts", "EDGE_FINE"]

ENCODER_OUTPUTS = ("speed", "position", "edges")
EDGE_FINE = 50  # integration points per sample interval when edges are located


def counted_angle(theta: np.ndarray, q: float) -> np.ndarray:
    """The angle an encoder of step ``q`` (rad) reports: counted down with ``floor``."""
    return np.floor(theta / q + 1e-9) * q


def edge_times(t_fine: np.ndarray, theta: np.ndarray, q: float, resolution: float) -> tuple:
    """Every edge of an encoder of step ``q`` (rad) on the angle ``theta`` at the times
    ``t_fine``: the times (s) at which the rotor crosses a count boundary ``k·q``, located
    by linear interpolation on the fine grid and rounded to the timer's ``resolution``
    (a later edge at least one tick after the one before), the boundary crossed (the
    angle at the edge: the one the rotor left by when it turns back) and the direction
    (1 forward, 0 backward)."""
    k = np.floor(theta / q + 1e-9).astype(np.int64)
    dk = np.diff(k)
    at = np.nonzero(dk)[0]
    if at.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, int)
    n = np.abs(dk[at])
    interval = np.repeat(at, n)
    forward = np.repeat(dk[at] > 0, n)
    # the j-th boundary crossed in its interval: k+1, k+2, ... forward; k, k−1, ... back
    j = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    boundary = np.where(forward, k[interval] + 1 + j, k[interval] - j) * q
    th0, th1 = theta[interval], theta[interval + 1]
    frac = np.clip((boundary - th0) / (th1 - th0), 0.0, 1.0)
    times = t_fine[interval] + frac * (t_fine[interval + 1] - t_fine[interval])
    ticks = np.round(times / resolution)
    for i in range(1, ticks.size):  # ties of the timer: one tick apart, in order
        ticks[i] = max(ticks[i], ticks[i - 1] + 1)
    return ticks * resolution, boundary, forward.astype(int)


def encoder_trace_parts(mode: str, t: np.ndarray, theta: np.ndarray, q: float,
                        fine=None, resolution: float = 1e-6) -> dict:
    """``time``, ``speed`` (estimated), ``position`` (NaN where not read) and the count
    of an encoder trace: ``mode`` ``"position"`` counts at the samples ``t``; ``"edges"``
    the edge times from ``fine = (t_fine, theta_fine)``, after a first, unread sample
    at ``t[0]`` (the rotor at rest), with each edge's ``direction`` when the rotor turns
    back."""
    if mode == "position":
        pos = counted_angle(theta, q)
        return {"time": t, "position": pos, "speed": speed_estimate(t, pos)}
    times, angles, forward = edge_times(*fine, q, resolution)
    time = np.concatenate([t[:1], times])
    pos = np.concatenate([[np.nan], angles])
    out = {"time": time, "position": pos, "speed": speed_estimate(time, pos)}
    if not forward.all():  # a rotor that turns back: the direction of each edge
        out["direction"] = np.concatenate([[1], forward])
    return out
