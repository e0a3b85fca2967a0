"""A non-ideality asked for with nothing in the session to act on."""

from __future__ import annotations

import numpy as np

from .lattice import analogue_channels

__all__ = ["inert_nuisance"]


def inert_nuisance(session, names) -> tuple[str, str] | None:
    """The first of ``names`` with nothing in ``session`` to act on, and why: a speed
    sensor's lag, gain or offset without a logged speed (an angle an encoder counts is
    not read through them), a current sensor's without a logged current, a dead time
    without a driven trace, a dead zone without a commanded voltage, coloured noise
    without an analogue speed or current on the traces it names (a quantised reading's
    errors are its quantisation's), a driver that opens the armature at a zero command
    without a trace commanding zero after driving the motor.  A coast-down's speed is
    read by the speed sensor too."""
    speed = (any(tr.speed is not None and tr.speed_logged for tr in session.traces)
             or bool(session.coast_downs))
    current = any(tr.current is not None for tr in session.traces)
    for name in names:
        if name.startswith("speed_") and not speed:
            return name, ("no trace logs a speed (a position or encoder trace is a "
                          "counted angle, which a speed sensor's lag, gain or offset "
                          "does not touch)")
        if name.startswith("current_") and name != "current_limit" and not current:
            return name, "no driven trace logs a current"
        if name == "dead_time" and not session.traces:
            return name, "the session has no driven trace"
        if name == "dead_zone" and not (session.traces or session.steady_tables
                                        or session.operating_points):
            return name, "the session commands no voltage (a driver's dead zone acts on it)"
        if name == "open_at_zero" and not any(_zero_after_drive(tr) for tr in session.traces):
            return name, ("no driven trace commands zero after driving the motor (the "
                          "driver's state at a zero command acts only on a turning rotor)")
        if name == "coloured_noise":
            named = session.coloured_traces or tuple(
                t.name for t in session.traces + session.coast_downs)
            if not set(named) & set(analogue_channels(session).values()):
                return name, ("no trace it names logs an analogue speed or current (a "
                              "counted angle's or a quantised reading's errors are its "
                              "quantisation's)")
    return None


def _zero_after_drive(trace) -> bool:
    """Whether ``trace`` commands zero while its rotor may turn: after a nonzero
    command, or from a start that is not at rest."""
    v = np.asarray(trace.voltage.values, float)
    driven = np.cumsum(v != 0) > 0
    started = not (isinstance(trace.initial, str) and trace.initial == "rest")
    return bool(np.any((v == 0) & (driven | started)))
