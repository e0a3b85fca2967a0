"""Where a trace's inputs change: the plateaus an input is held on, and the span of the
response to each change.

A schedule written in ``session.toml`` changes where its value does.  An input logged at
every sample (a driver's PWM-averaged output, with its noise, ripple and a sagging
supply) is read through a running median of :data:`WINDOW` samples: it changes where
that median leaves the level it held by more than :data:`CHANGE_OVER_NOISE` times the
median's own noise (or three times the typical sample-to-sample change, for an input
quantised coarser than its noise), and a level held for fewer than :data:`WINDOW`
samples (a slew, a driver's overshoot) belongs to the change that follows it, as it
does in a noisy column the loader read as its levels (:mod:`pmdc_bayes.io.held_levels`).  The
response to a change lasts until the next change comparable to it: one that moves the
input at least :data:`RESPONSE_SHARE` of the change away from the level it went to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

from ..io.robust import AT_REST, MAD_SD

__all__ = ["WINDOW", "CHANGE_OVER_NOISE", "RESPONSE_SHARE", "AT_REST", "Plateau", "Response",
           "plateaus", "responses"]

WINDOW = 9  # samples of the running median a logged input is read through
CHANGE_OVER_NOISE = 8.0  # a logged input's change stands this far above its median's noise
RESPONSE_SHARE = 0.25  # a later change this share of the one read ends its response


@dataclass(frozen=True)
class Plateau:
    """Samples ``start:stop`` of a trace over which an input holds ``level`` (the median
    of the plateau's second half); ``time`` is when it began (s): the schedule's
    breakpoint, or the first sample of the new level of a logged input."""

    start: int
    stop: int
    level: float
    time: float


@dataclass(frozen=True)
class Response:
    """The response to one change of an input, from ``before`` to ``after`` at ``time``
    (s): samples ``start:stop`` of its trace, from the level before it (the trace's
    first plateau whole, as the trace was started on it; a later one's last tenth, at
    least three samples; none for a change at the first sample) up to the next change
    comparable to it."""

    time: float
    before: float
    after: float
    start: int
    stop: int

    @property
    def size(self) -> float:
        return abs(self.after - self.before)


def _logged(schedule, n: int) -> bool:
    """Whether an input has a breakpoint at (nearly) every sample: a logged column, or a
    schedule written out sample by sample."""
    return schedule.values.size >= max(8, n // 2)


def _written(schedule, time) -> list[tuple[int, float]]:
    """(first sample, breakpoint time) where a written schedule's value changes."""
    starts = [(0, float(time[0]))]
    for k in range(1, schedule.values.size):
        if schedule.values[k] == schedule.values[k - 1] or schedule.times[k] <= time[0]:
            continue
        i = int(np.searchsorted(time, schedule.times[k], side="left"))
        if i >= time.size:
            break
        if i == starts[-1][0]:
            starts[-1] = (i, max(float(schedule.times[k]), float(time[0])))
        else:
            starts.append((i, float(schedule.times[k])))
    return starts


def _departures(x: np.ndarray) -> list[int]:
    """First samples of each level a logged input holds (see the module's notes)."""
    n = x.size
    if n <= WINDOW:
        return [0]
    med = median_filter(x, size=WINDOW, mode="nearest")
    noise = MAD_SD * float(np.median(np.abs(med[WINDOW:] - med[:-WINDOW]))) / np.sqrt(2.0)
    moving = np.abs(np.diff(x))
    moving = moving[moving > 0]
    # a quantised input's flicker moves it at many samples; a clean column's few
    # moves are its changes, not a jitter to stand above
    jitter = float(np.median(moving)) if moving.size > max(3, n // 50) else 0.0
    tol = max(CHANGE_OVER_NOISE * noise, 3.0 * jitter, 1e-12 * float(np.max(np.abs(x))))
    starts, level = [0], med[0]
    for k, m in enumerate(med.tolist()):
        if abs(m - level) > tol:
            starts.append(k)
            level = med[min(k + WINDOW - 1, n - 1)]
    return _merged(starts)


def _merged(starts: list[int]) -> list[int]:
    """``starts`` with each run of levels too short to hold (fewer than :data:`WINDOW`
    samples: a slew, a driver's overshoot) taken as one change, at its first sample."""
    merged, j = [0], 1
    while j < len(starts):
        merged.append(starts[j])
        j += 1
        while j < len(starts) and starts[j] - starts[j - 1] < WINDOW:
            j += 1
    return merged


def plateaus(trace, which: str = "voltage") -> list[Plateau]:
    """The plateaus the input ``which`` (``"voltage"`` or ``"load_torque"``) of
    ``trace`` is held on, in order; one for a constant input."""
    schedule, time = getattr(trace, which), trace.time
    x = schedule.at(time)
    if _logged(schedule, time.size):
        starts = [(i, float(time[i])) for i in _departures(x)]
    else:
        starts = _written(schedule, time)
        if schedule.se is not None:  # a noisy column read as its levels
            kept = set(_merged([i for i, _ in starts]))
            starts = [(i, t) for i, t in starts if i in kept]
    stops = [s for s, _ in starts[1:]] + [time.size]
    return [Plateau(i, j, float(np.median(x[(i + j) // 2:j])), t)
            for (i, t), j in zip(starts, stops, strict=True)]


def responses(trace, which: str = "voltage") -> list[Response]:
    """Every change of the input ``which`` of ``trace`` with the span of its response,
    largest first.  A trace starting at rest under a non-zero voltage (above
    :data:`AT_REST` of its largest) counts the step from 0 V at its first sample; one
    starting elsewhere has no change there.  A response also ends where the other
    input changes at all."""
    held = plateaus(trace, which)
    other = [p.start for p in plateaus(trace, "load_torque" if which == "voltage"
                                       else "voltage")[1:]]
    out, top = [], max(abs(p.level) for p in held)
    held_from_start = trace.initial in ("rest", "steady")
    if which == "voltage" and trace.initial == "rest" and abs(held[0].level) > AT_REST * top:
        held, held_from_start = [Plateau(0, 0, 0.0, float(trace.time[0])), *held], False
    for k in range(1, len(held)):
        prev, cur = held[k - 1], held[k]
        size = abs(cur.level - prev.level)
        stop = next((p.start for p in held[k + 1:]
                     if abs(p.level - cur.level) > RESPONSE_SHARE * size), trace.time.size)
        stop = min([stop, *(s for s in other if s > cur.start)])
        whole = k == 1 and held_from_start
        tail = prev.stop - prev.start if whole else max(3, (prev.stop - prev.start) // 10)
        out.append(Response(cur.time, prev.level, cur.level, max(prev.start, prev.stop - tail),
                            stop))
    return sorted(out, key=lambda r: -r.size)
