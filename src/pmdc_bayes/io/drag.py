"""A trace's known load, ``drag = { ... }`` of a ``[[trace]]``: the record the numerics see
(:class:`Drag`, SI) and its reader, which the session loader and the simulation plans
share (a plan gives SI units)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .toml_tables import Table, describe
from .units import from_si

__all__ = ["Drag", "NO_DRAG", "read_drag", "check_curve_reach"]


class Drag(NamedTuple):
    """A trace's known load that depends on the speed, opposing the motion (SI):
    ``constant`` (N·m, friction-like: it holds a rotor at rest), ``viscous`` (N·m·s/rad),
    ``quadratic`` (N·m·s²/rad²: a torque ``quadratic·ω·|ω|``, a fan's or a propeller's)
    and ``curve``, points ``((speed rad/s, torque N·m), ...)`` of increasing speed from
    ``(0, 0)`` through which the torque is piecewise linear (a measured brake or
    dynamometer curve), or ``()`` (:mod:`pmdc_bayes.physics.load`)."""

    constant: float = 0.0
    viscous: float = 0.0
    quadratic: float = 0.0
    curve: tuple = ()

    @property
    def curved(self) -> bool:
        """Whether the drag has a part that is not affine in the speed."""
        return self.quadratic != 0.0 or len(self.curve) > 0

    @property
    def nonzero(self) -> bool:
        """Whether there is any drag at all."""
        return self.constant != 0.0 or self.viscous != 0.0 or self.curved


NO_DRAG = Drag()


def _curve(sub: Table, u: dict) -> tuple:
    """A drag's ``curve = [[speed, torque], ...]`` in the trace's speed and load-torque
    units: points of increasing speed from 0, the torque 0 at speed 0, each ≥ 0."""
    pairs = sub.data["curve"]
    example = "curve = [[0, 0], [100, 0.004], [200, 0.015]]"
    if not isinstance(pairs, list) or len(pairs) < 2:
        got = (f"{len(pairs)} point(s)" if isinstance(pairs, list) else describe(pairs))
        sub.fail("curve", f"expected a list of at least two [speed, torque] points, got "
                 f"{got}; write e.g. {example} (speed and torque in the trace's units)")
    points = []
    for i, pair in enumerate(pairs):
        if not isinstance(pair, list) or len(pair) != 2:
            sub.fail(f"curve[{i}]", f"expected a [speed, torque] point, got "
                     f"{describe(pair)}; write e.g. {example}")
        pt = Table(sub.file, {"speed": pair[0], "torque": pair[1]}, sub.path(f"curve[{i}]"))
        points.append((pt.number("speed", "speed", u["speed"], low=0.0),
                       pt.number("torque", "torque", u["load_torque"], low=0.0)))
        if i and points[i][0] <= points[i - 1][0]:
            sub.fail(f"curve[{i}]", "the curve's speeds must increase strictly from 0; list "
                     "its points in order of speed")
    if points[0] != (0.0, 0.0):
        sub.fail("curve[0]", "the curve must start at [0, 0] (no torque at rest); a torque "
                 "that holds the rotor at rest goes in drag.constant")
    return tuple(points)


def read_drag(t: Table, u: dict) -> Drag:
    """A known speed-dependent load ``drag = { constant = N·m, viscous = N·m·s/rad,
    quadratic = N·m·s²/rad², curve = [[speed, torque], ...] }`` (the coefficients SI, the
    curve in the trace's units; any may be left out), each ≥ 0."""
    if "drag" not in t.data:
        return NO_DRAG
    sub = t.table("drag")
    sub.check_keys(("constant", "viscous", "quadratic", "curve"))
    if not sub.data:
        t.fail("drag", "give constant = <N·m>, viscous = <N·m·s/rad>, quadratic = "
               "<N·m·s²/rad²> and/or curve = [[speed, torque], ...]")
    return Drag(sub.number("constant", "torque", default=0.0, low=0.0),
                sub.number("viscous", "damping", default=0.0, low=0.0),
                sub.number("quadratic", default=0.0, low=0.0),
                _curve(sub, u) if "curve" in sub.data else ())


def check_curve_reach(t: Table, drag: Drag, speed, u: dict) -> None:
    """A curve whose last slope falls so far that, extended to the speed the trace
    reaches (``speed``, rad/s), it would drive the motor (a negative drag): refused,
    since a drag opposes the motion and the curve says nothing there."""
    if len(drag.curve) < 2 or speed is None or not np.any(np.isfinite(speed)):
        return
    (w1, t1), (w2, t2) = drag.curve[-2:]
    top = float(np.nanmax(np.abs(speed)))
    if top > w2 and t2 + (t2 - t1) / (w2 - w1) * (top - w2) < 0:
        reach = f"{from_si(top, 'speed', u['speed']):.4g} {u['speed']}"
        t.fail("drag.curve", f"the curve's last slope, extended to {reach} (the trace's top "
               "speed), gives a negative torque, a load that drives the motor; extend the "
               "curve with points measured up to that speed")
