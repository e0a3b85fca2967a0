"""The start of a step response: its shape and when it leaves its resting level.

Used by the diagnosis to tell a delay (dead time, a sensor lag) or a ramp (a
current-limited driver) from the exponential-like onset the ideal motor gives.  Every
comparison is made twice, on the data and on the model's prediction, so the onset the
motor's own inductance produces is never taken for a delay.
"""

from __future__ import annotations

import numpy as np

from ...io.robust import first_run

__all__ = ["crossing_time", "departure", "onset_shape", "rise_time", "smoothed", "step_time",
           "step_window"]


def _rise(t, y, t_step):
    """Samples from the step to 90 % of the change, normalised to 0 → 1."""
    before = y[t <= t_step]
    y0 = float(np.mean(before[-5:])) if before.size else float(y[0])
    yf = float(np.mean(y[-max(3, y.size // 10):]))
    if abs(yf - y0) < 1e-12:
        return None
    s = (y - y0) / (yf - y0)
    keep = t > t_step
    tt, ss = t[keep] - t_step, s[keep]
    reach = np.nonzero(ss >= 0.9)[0]
    if reach.size == 0 or reach[0] < 8:
        return None
    end = min(ss.size, int(reach[0] * 1.3) + 1)
    return tt[:end], ss[:end]


def _shapes(tt):
    """The candidate onsets as functions of their log-parameters."""
    def plain(q):
        return 1 - np.exp(-tt / np.exp(q[0]))

    def delayed(q):
        d, tau = np.exp(q)
        return np.where(tt > d, 1 - np.exp(-(tt - d) / tau), 0.0)

    def lagged(q):
        tau, lag = np.exp(q)
        if abs(tau - lag) < 1e-6 * tau:
            lag = tau * (1 - 1e-6)
        return 1 - (tau * np.exp(-tt / tau) - lag * np.exp(-tt / lag)) / (tau - lag)

    def ramp(q):
        T, tc = np.exp(q[0]), np.exp(q[1])
        tc = min(tc, 0.95 * T)
        return np.where(tt <= tc, tt / T, 1 - (1 - tc / T) * np.exp(-(tt - tc) / (T - tc)))

    return {"plain": plain, "delayed": delayed, "lagged": lagged, "ramp": ramp}


def onset_shape(t, y, t_step) -> dict | None:
    """Least-squares fit of the normalised rise by each shape: ``plain`` (exponential
    from the step), ``delayed`` (exponential after a dead time), ``lagged`` (exponential
    seen through a first-order sensor) and ``ramp`` (a straight line turning into an
    exponential with the same slope).  Returns each shape's error relative to the plain
    one (the noise's share added to both, so a shape only wins on the signal), the dead
    time and the ramp's length; None without a clear step."""
    from scipy.optimize import least_squares

    from ..model.noise import noise_scale

    r = _rise(np.asarray(t, float), np.asarray(y, float), t_step)
    if r is None:
        return None
    tt, ss = r
    t90 = float(tt[np.nonzero(ss >= 0.9)[0][0]])
    floor = ss.size * noise_scale(ss) ** 2
    starts = {"plain": [[np.log(t90 / 2.3)]],
              "delayed": [[np.log(f * t90), np.log((1 - f) * t90 / 2.3)] for f in (0.1, 0.3, 0.6)],
              "lagged": [[np.log(f * t90 / 2.3), np.log((1 - f) * t90 / 2.3)]
                         for f in (0.5, 0.7, 0.9)],
              "ramp": [[np.log(t90), np.log(f * t90)] for f in (0.1, 0.3, 0.6)]}
    # times between a tenth of a sample and ten times the rise read: beyond them every
    # shape is flat over it, and a search that wanders there stops at the bound
    lo, hi = np.log(float(np.median(np.diff(tt))) / 10), np.log(10 * float(tt[-1]))
    out, best = {}, {}
    for name, fn in _shapes(tt).items():
        # a delay past the record overflows the exponential of the branch np.where drops
        with np.errstate(over="ignore", invalid="ignore"):
            fits = [least_squares(lambda q, fn=fn: fn(np.clip(q, lo, hi)) - ss, q0,
                                  method="lm") for q0 in starts[name]]
        f = min(fits, key=lambda f: f.cost)
        out[name], best[name] = 2 * f.cost, np.exp(np.clip(f.x, lo, hi))
    base = out["plain"] + floor
    rel = {k: (v + floor) / base for k, v in out.items()}
    return dict(rel, dead_time=float(best["delayed"][0]),
                ramp_time=float(min(best["ramp"][1], 0.95 * best["ramp"][0])), t90=t90)


def departure(t, y, t_step, threshold) -> float | None:
    """Time after ``t_step`` at which ``y`` leaves its level at the step by more than
    ``threshold`` for :data:`~pmdc_bayes.io.robust.CONSECUTIVE` samples in a row; None
    if it never does."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    before = y[t <= t_step]
    y0 = float(np.mean(before[-5:])) if before.size else float(y[0])
    k = first_run((np.abs(y - y0) > threshold) & (t > t_step))
    return None if k is None else float(t[k] - t_step)


def step_time(trace) -> float:
    """Time of the trace's largest voltage change (its first sample when it starts from
    rest under a constant voltage)."""
    v, t = trace.voltage.values, trace.voltage.times
    if v.size < 2:
        return float(trace.time[0])
    k = int(np.argmax(np.abs(np.diff(v)))) + 1
    return float(max(t[k], trace.time[0]))


def _step_end(trace, t_step: float) -> float:
    """The time of the trace's first voltage change after ``t_step`` (infinite where
    none): the response to the step at ``t_step`` is read up to it."""
    later = trace.voltage.change_times()
    later = later[later > t_step]
    return float(later[0]) if later.size else np.inf


def step_window(trace) -> tuple[float, np.ndarray]:
    """The time of the trace's largest voltage change (:func:`step_time`) and which of
    its samples the response to it is read over: those before the next change
    (:func:`_step_end`), which a staircase's later step would otherwise stand in for."""
    t_step = step_time(trace)
    return t_step, np.asarray(trace.time) < _step_end(trace, t_step)


def smoothed(y) -> np.ndarray:
    """``y`` under a moving average long enough to quiet its noise (to a small share of
    its span), and no longer than a twentieth of it (an odd number of samples, centred
    on each; near either end, of the samples there are)."""
    from ..model.noise import noise_scale

    y = np.asarray(y, float)
    if y.size < 3:
        return y
    span = float(np.max(y) - np.min(y))
    need = (3 * noise_scale(y) / max(0.02 * span, 1e-300)) ** 2 if span > 0 else 1.0
    w = int(min(max(y.size // 200, np.ceil(need), 1), max(1, y.size // 20))) | 1  # centred
    if w == 1:
        return y
    box = np.ones(w)
    return np.convolve(y, box, mode="same") / np.convolve(np.ones_like(y), box, mode="same")


def crossing_time(t, ys, t_step, start, end, level: float = 0.632) -> float | None:
    """Time after ``t_step`` for ``ys`` to cover ``level`` of the way from ``start`` to
    ``end`` (the first sample after it that does); None when it never does."""
    if end == start:
        return None
    mark = start + level * (end - start)
    after = np.flatnonzero((t > t_step) & (np.sign(end - start) * (ys - mark) >= 0))
    return float(t[after[0]] - t_step) if after.size else None


def rise_time(t, y, t_step, level: float = 0.632) -> float | None:
    """Time after ``t_step`` for ``y`` (:func:`smoothed`) to cover ``level`` of its
    change from its value at the step (the mean of the last five samples at or before
    it) to the mean of its last tenth; None without a clear change."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    span = float(np.max(y) - np.min(y))
    ys = smoothed(y)
    before = y[t <= t_step]
    y0 = float(np.mean(before[-5:])) if before.size else float(y[0])
    yf = float(np.mean(y[-max(3, y.size // 10):]))
    if not abs(yf - y0) > 0.2 * span or span == 0:
        return None
    return crossing_time(t, ys, t_step, y0, yf, level)
