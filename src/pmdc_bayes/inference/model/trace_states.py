"""A trace's own starting state as fitted parameters: a coast-down's speed at its first
sample and a position trace's angle there (their registry entries)."""

from __future__ import annotations

import numpy as np

from ...io.session import Session
from .noise import noise_scale
from .params import ParamSpec, Prior, identifier

__all__ = ["coast_down_specs", "initial_speed_name", "position_specs", "position_offset_name"]


def initial_speed_name(trace_name: str) -> str:
    """The parameter name of a coast-down's speed at its first sample."""
    return f"initial_speed_{identifier(trace_name)}"


def coast_down_specs(session: Session) -> list[ParamSpec]:
    """Per coast-down trace, ``initial_speed_<trace>`` (rad/s): the speed at its first
    sample, fitted rather than read off one noisy sample.  Prior normal, centred on the
    median of the first three samples, sd 10 % of it plus ten times the trace's
    model-free noise level (the data decide it)."""
    specs = []
    for tr in session.coast_downs:
        w0 = float(np.median(tr.speed[:3]))
        sd = 0.1 * abs(w0) + 10.0 * noise_scale(tr.speed)
        specs.append(_start_spec(initial_speed_name(tr.name), "rad/s", w0, sd, "first samples",
                                 f"speed at the start of coast-down {tr.name!r}", tr.name))
    return specs


def position_offset_name(trace_name: str) -> str:
    """The parameter name of a position trace's angle at its first sample."""
    return f"position_offset_{identifier(trace_name)}"


def position_specs(session: Session) -> list[ParamSpec]:
    """Per trace with an angle, ``position_offset_<trace>`` (rad): the sensor's reading
    at the trace's first sample (the angle is otherwise only known up to it).  Prior
    normal, centred on the first reading (for an encoder trace starting at rest before
    its first edge, half a count before that edge), sd one count plus ten times the
    angle's model-free noise level."""
    specs = []
    for tr in session.traces:
        if tr.position is None:
            continue
        ok = np.isfinite(tr.position)
        y = tr.position[ok]
        first = float(y[0])
        if not ok[0]:
            first -= 0.5 * tr.encoder_step * float(np.sign(y[1] - y[0]) if y.size > 1 else 1.0)
        sd = tr.encoder_step + 10.0 * noise_scale(y)
        specs.append(_start_spec(position_offset_name(tr.name), "rad", first, sd,
                                 "first reading", f"angle read at the start of trace {tr.name!r}",
                                 tr.name))
    return specs


def _start_spec(name: str, unit: str, centre: float, sd: float, source: str,
                description: str, trace: str) -> ParamSpec:
    """A trace's starting value fitted in value, its prior normal around what the data
    read there (``source``), its seed that reading."""
    return ParamSpec(name, unit, "trace", Prior("normal", centre, sd, source), centre,
                     transform="identity", description=description, trace=trace)
