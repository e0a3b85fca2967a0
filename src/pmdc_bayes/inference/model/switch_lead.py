"""When a logged input column's changes happened: the lead of the change over the sample
that first shows it.

A column says only that its input changed between the sample before and the first
sample that shows the new value.  Read as a schedule (a zero-order hold), the change is
placed at that sample; a driver that switched anywhere in the interval before it (a rig
whose switching is not timed by the logger's clock, an ADC reading of the driver's
output) then drives the motor up to a whole sample interval earlier than the model
does.  Where the current is logged and the armature's time constant is shorter than a
sample interval, the first current sample after a change reads a partly risen current
the model cannot reach, and a step's start, La and J absorb the difference.

A trace whose switching inputs all come from columns therefore carries one fitted lead,
``switch_lead_<trace>`` (s): every change of its inputs happened that long before the
sample that shows it (it subtracts from the trace's ``dead_time``, if fitted:
:meth:`.effects.RigEffects.inputs`).  Its prior stands for the uniform distribution over
the sample interval Δ before the change (Δ the trace's median sample interval): normal,
with that uniform's mean Δ/2 and standard deviation Δ/√12, fitted in value, so a lead of
0 (a rig timed by the logger's clock) lies 1.7 sd from its centre and a slightly
negative one (a change shown a sample late) is not excluded.

Where the armature's time constant is much shorter than Δ, the density in the lead is
a box: flat where the first current sample after a change reads the current risen (or
not yet moved), falling within a time constant of the lead at which the change reaches
that sample.  A fit started on the wrong flat part sees no slope towards the right one,
so a fit starts each lead at the best of :data:`SCAN_SHARES` × Δ (:func:`lead_scans`),
the rest of the parameters at their start.  The changes of one trace share the lead:
one where a trace steps once, the lead the changes have on average where it steps many
times.  A schedule written in ``session.toml`` states its own times; a trace with one
that changes keeps them.
"""

from __future__ import annotations

import numpy as np

from ...io.session import Session, Trace
from .params import ParamSpec, Prior, identifier

__all__ = ["lead_name", "lead_specs", "leading_traces", "lead_scans", "SCAN_SHARES"]

UNIFORM_MEAN, UNIFORM_SD = 0.5, 1.0 / np.sqrt(12.0)  # of U(0, 1)
SCAN_SHARES = np.array([-0.5, -0.2, 0.0, 0.1, 0.25, 0.5, 0.75, 0.95])  # of Δ


def lead_name(trace_name: str) -> str:
    """The parameter name of a trace's lead."""
    return f"switch_lead_{identifier(trace_name)}"


def _changes(values: np.ndarray) -> bool:
    values = np.asarray(values, dtype=float)
    return values.size > 1 and bool(np.any(values[1:] != values[:-1]))


def _leads(tr: Trace) -> bool:
    """Whether ``tr``'s switching inputs all come from columns, and one of them switches."""
    inputs = ((tr.voltage, tr.voltage_logged), (tr.load_torque, tr.load_logged))
    switching = [logged for schedule, logged in inputs if _changes(schedule.values)]
    return bool(switching) and all(switching)


def leading_traces(session: Session) -> tuple[str, ...]:
    """The traces that carry a fitted lead (module docstring)."""
    return tuple(tr.name for tr in session.traces if _leads(tr))


def lead_specs(session: Session) -> list[ParamSpec]:
    """One ``switch_lead_<trace>`` (s) per trace of :func:`leading_traces`: prior normal,
    centre Δ/2, sd Δ/√12 (Δ the trace's median sample interval; module docstring); fitted
    in value; seeded at Δ/2."""
    specs = []
    for tr in session.traces:
        if _leads(tr):
            dt = tr.dt
            specs.append(ParamSpec(lead_name(tr.name), "s", "trace",
                                   Prior("normal", UNIFORM_MEAN * dt, UNIFORM_SD * dt,
                                         "nuisance"),
                                   UNIFORM_MEAN * dt, transform="identity", trace=tr.name,
                                   description=f"how long before the first sample showing "
                                               f"it an input of trace {tr.name!r} changed"))
    return specs


def lead_scans(session: Session) -> dict[str, np.ndarray]:
    """Per lead of :func:`lead_specs`, the values (s) a fit's start is chosen among:
    :data:`SCAN_SHARES` × Δ."""
    return {lead_name(tr.name): SCAN_SHARES * tr.dt for tr in session.traces if _leads(tr)}
