"""A trace's known load: a drag that depends on the speed, which need not be affine in it.

A drag opposes the motion: ``constant·sign(ω) + viscous·ω`` (its affine part, solved
exactly by the stick-slip solution) plus ``f(ω) = sign(ω)·g(|ω|)``, its curved part:
``g(s) = quadratic·s² + curve(s)`` (a fan or a propeller, a measured brake curve), where
``curve`` is piecewise linear through the user's points ``(speed, torque)`` (``g(0) = 0``)
and extended beyond the last point along its last slope.

The curved part has no closed-form solution, so the exact solution replaces it on
each short segment by its tangent at the segment's starting speed ``ω0``: a load torque
``f(ω0) − f′(ω0)·ω0`` and a viscous drag ``f′(ω0)`` (an exponential Rosenbrock step),
plus the mean over the segment of what the tangent leaves out of the quadratic part
(:func:`curved_start`); :func:`linearisation_cuts` gives the segments.
The same formula serves NumPy (the simulators, the closed form) and JAX (the model).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._x64 import to_device
from ..io.drag import Drag

__all__ = ["drag_torque", "with_drags", "curved_start", "curve_torque", "curve_tangent",
           "curve_arrays", "linearisation_cuts", "drag_cuts", "GROWTH", "ALONG_SPEED"]

GROWTH = 1.25  # each linearisation segment after an input change this much longer
ALONG_SPEED = 100  # a linearisation segment ends where the speed moved 1/100 of its range
ZERO_SAMPLES = 8  # every sample this close to the speed's sign change or a kink cuts too


def drag_torque(drag: Drag, w):
    """The whole drag ``drag`` at speed ``w`` (rad/s, NumPy), signed as a load torque."""
    w = np.asarray(w, dtype=float)
    q, kw, kt = curve_arrays([drag])
    return (drag.constant * np.sign(w) + drag.viscous * w
            + curve_torque(w, q[0], kw[0], kt[0], np))


def curve_arrays(drags):
    """Per drag its ``quadratic`` and its curve's speeds and torques, padded to a common
    number of points (at least 2) along the last slope: ``(q (n,), speeds (n, M),
    torques (n, M))``, NumPy."""
    m = max([2] + [len(d.curve) for d in drags])
    q = np.array([float(d.quadratic) for d in drags])
    kw, kt = np.zeros((len(drags), m)), np.zeros((len(drags), m))
    for k, d in enumerate(drags):
        pts = np.asarray(d.curve, dtype=float).reshape(-1, 2) if d.curve else \
            np.array([[0.0, 0.0], [1.0, 0.0]])
        w, t = pts[:, 0], pts[:, 1]
        slope = (t[-1] - t[-2]) / (w[-1] - w[-2])
        extra = w[-1] + (1.0 + np.arange(m - w.size)) * max(w[-1], 1.0)
        kw[k] = np.concatenate([w, extra])
        kt[k] = np.concatenate([t, t[-1] + slope * (extra - w[-1])])
    return q, kw, kt


def _piece(w, q, kw, kt, xp):
    """``(|ω|, g(|ω|), g′(|ω|))`` of the curved part's ``g`` (the right-hand slope at a
    point of the curve)."""
    s = xp.abs(w)
    i = xp.clip(xp.searchsorted(kw, s, side="right") - 1, 0, kw.shape[-1] - 2)
    slope = (kt[i + 1] - kt[i]) / (kw[i + 1] - kw[i])
    return s, q * s * s + kt[i] + slope * (s - kw[i]), 2.0 * q * s + slope


def curve_torque(w, q, kw, kt, xp=np):
    """The curved part of the drag at speed ``w``: ``sign(ω)·(q·ω² + curve(|ω|))``."""
    return xp.sign(w) * _piece(w, q, kw, kt, xp)[1]


def curve_tangent(w0, q, kw, kt, xp=np):
    """The tangent of the curved part at ``w0``: ``(b, t0)`` with ``f(ω) ≈ t0 + b·ω``
    near ``w0`` (``b = f′(ω0)``, the right-hand slope at a point of the curve)."""
    _, g, b = _piece(w0, q, kw, kt, xp)
    return b, xp.sign(w0) * g - b * w0


def linearisation_cuts(time, breaks, speed=None, *, kinks=(), first: float | None = None,
                       ratio: float = GROWTH, longest: float | None = None,
                       per_range: int = ALONG_SPEED) -> np.ndarray:
    """The times inside a curved trace (samples ``time``) where its drag's tangent is
    taken again.  After each of the input's breakpoints ``breaks`` (and the trace's
    start), where the speed changes fastest, a geometric grid: its first step ``first``
    (default: the trace's span / 4000), each step ``ratio`` times the last, none longer
    than ``longest`` (default: the span / 40).  With the trace's observed ``speed``,
    also a cut wherever the (smoothed) speed has moved by another ``1/per_range`` of its
    range, so that a fast transient the inputs do not explain is cut finely too, and at
    every sample within :data:`ZERO_SAMPLES` of where it changes sign or its size
    crosses one of the ``kinks`` (the speeds where the curve's slope changes)."""
    t = np.asarray(time, dtype=float)
    t0, t1 = float(t[0]), float(t[-1])
    span = t1 - t0
    if span <= 0:
        return np.zeros(0)
    first = span / 4000 if first is None else first
    longest = span / 40 if longest is None else longest
    starts = np.unique(np.concatenate([[t0], np.asarray(breaks, dtype=float)]))
    starts = starts[(starts >= t0) & (starts < t1)]
    ends = np.append(starts[1:], t1)
    cuts = []
    for a, b in zip(starts, ends, strict=True):
        if b - a <= 2 * first:  # inputs that change every sample cut finely already
            continue
        h, x = first, a
        while True:
            x += h
            if x >= b - 0.25 * h:
                break
            cuts.append(x)
            h = min(h * ratio, longest)
    if speed is not None:
        cuts.extend(_along(t, np.asarray(speed, dtype=float), per_range, kinks))
    return np.unique(np.asarray(cuts))


def drag_cuts(drag: Drag, time, breaks, speed=None, **grid) -> np.ndarray:
    """:func:`linearisation_cuts` of a trace with the curved ``drag`` (its kinks: the
    curve's inner points); ``grid`` as there."""
    return linearisation_cuts(time, breaks, speed, kinks=[w for w, _ in drag.curve[1:-1]],
                              **grid)


def _along(t, w, per_range: int, kinks=()) -> np.ndarray:
    """The times where the trace's smoothed speed has moved by another ``1/per_range``
    of its range, and the samples around those where it changes sign or its size
    crosses a speed of ``kinks`` (NaN readings skipped)."""
    ok = np.isfinite(w)
    t, w = t[ok], w[ok]
    if t.size < 3:
        return np.zeros(0)
    n = max(1, t.size // 200)
    if n > 1:  # a moving mean, the ends padded with their own values (not zeros)
        padded = np.concatenate([np.full(n // 2, w[0]), w, np.full(n - 1 - n // 2, w[-1])])
        smooth = np.convolve(padded, np.ones(n) / n, mode="valid")
    else:
        smooth = w
    spread = float(np.ptp(smooth))
    if not spread > 0:
        return np.zeros(0)
    moved = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(smooth)))]) / spread
    marks = np.arange(1, int(moved[-1] * per_range)) / per_range
    # where the speed changes sign (the quadratic part's curvature changes sign) or its
    # size crosses a kink of the curve, a segment's tangent cannot follow the curve: the
    # samples around it cut too
    flips = np.flatnonzero(np.sign(smooth[1:]) * np.sign(smooth[:-1]) < 0)
    size = np.abs(smooth)
    for k in kinks:
        flips = np.concatenate([flips, np.flatnonzero((size[1:] - k) * (size[:-1] - k) < 0)])
    near = (flips[:, None] + np.arange(-ZERO_SAMPLES, ZERO_SAMPLES + 2)[None, :]).ravel()
    near = near[(near > 0) & (near < t.size - 1)]
    return np.concatenate([t[np.searchsorted(moved, marks)], t[near]])


def with_drags(exp, drags):
    """The :class:`~.experiment.Experiment` ``exp`` with each trace's known drag
    (:class:`~pmdc_bayes.io.drag.Drag`, one per trace in order) on its segments: the
    affine part as ``seg_tc`` and ``seg_b``, a curved part as ``seg_q``, ``seg_kw``,
    ``seg_kt`` (each only when some trace has it).  A curved trace must have been cut
    (:func:`linearisation_cuts`)."""
    trace = np.asarray(exp.seg_trace)
    if any(d.constant or d.viscous for d in drags):
        tc, b = (np.array([float(d[k]) for d in drags]) for k in (0, 1))
        exp = exp._replace(seg_b=to_device(b[trace]), seg_tc=to_device(tc[trace]))
    if any(d.curved for d in drags):
        q, kw, kt = curve_arrays(drags)
        exp = exp._replace(seg_q=to_device(q[trace]), seg_kw=to_device(kw[trace]),
                           seg_kt=to_device(kt[trace]))
    return exp


_STEADY_ITERATIONS = 8  # Newton steps of a steady start under a curved drag


def curved_start(start, seen, curve):
    """For a segment with a curved drag ``curve`` (its ``(q, speeds, torques)``, or
    None): ``along(b, tc, tl, x, length)``, the viscous drag and load that replace it on
    a segment of ``length`` from the state ``x`` (unchanged without one), and ``begin(b,
    tc, va, tl, mode, x0)``, ``start`` (of :func:`~.solution._pass`) under the
    segment's drag ``(b, tc)`` and the curve, a steady state solved by Newton steps on
    the tangent.

    ``along`` takes the curve's tangent at ``x``'s speed and adds the mean over the
    segment of what the tangent leaves out of its quadratic part, ``q·(ω − ω0)²``, with
    the speed moving at its rate at ``x``: ``q·(ω̇·length)²/3``.  Without that term the
    tangent's error has one sign all along a speed's rise, and the speed's error adds
    up in an angle; with it, the error is third order in the segment's length."""
    if curve is None:
        return (lambda b, tc, tl, x, length: (b, tl),
                lambda b, tc, va, tl, mode, xg: start(seen(b, tc), va, tl, mode, xg))

    def along(b, tc, tl, x, length):
        db, dt = curve_tangent(x[1], *curve, jnp)
        ps = seen(b + db, tc)
        drive = ps.K * x[0] - tl - dt
        held = (x[1] == 0) & (jnp.abs(drive) <= ps.Tc)
        way = jnp.where(x[1] != 0, jnp.sign(x[1]), jnp.sign(drive))  # friction opposes it
        rate = jnp.where(held, 0.0, (drive - ps.B * x[1] - ps.Tc * way) / ps.J)
        moved = rate * length
        return b + db, tl + dt + way * curve[0] * moved * moved / 3.0

    def begin(b, tc, va, tl, mode, xg):
        x = start(seen(b, tc), va, tl, mode, xg)
        for _ in range(_STEADY_ITERATIONS):
            db, dt = curve_tangent(x[1], *curve, jnp)
            x = start(seen(b + db, tc), va, tl + dt, mode, xg)
        return x

    return along, begin
