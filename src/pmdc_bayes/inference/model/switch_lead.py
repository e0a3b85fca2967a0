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
sample that shows it.  A lead is positive (a response later than its logged input is a
dead time, the model's ``dead_time``, to which the lead adds:
:meth:`.effects.RigEffects.inputs`), fitted in log; its prior stands for the uniform
distribution over the sample interval Δ before the change (Δ the trace's median sample
interval): half-normal, with that uniform's root mean square, Δ/√3, as its scale.  The
fit starts it at :data:`SEED_SHARE` × Δ, the change at the sample as near as makes no
difference.  Where the armature's time constant is much shorter than Δ, the density is
flat in the lead over most of the interval (the first current sample after a change
reads the current risen whatever the lead) and falls within a time constant of the lead
at which the change reaches that sample: from the interval's middle a fit would see no
slope towards a change the logger timed, while from near 0 it climbs to a lead the
samples show.  The changes of one trace share the lead: one where a trace steps once,
the lead the changes have on average where it steps many times.  A schedule written in
``session.toml`` states its own times; a trace with one that changes keeps them.
"""

from __future__ import annotations

import numpy as np

from ...io.session import Session, Trace
from .params import ParamSpec, Prior, identifier

__all__ = ["lead_name", "lead_specs", "leading_traces"]

UNIFORM_RMS = 1.0 / np.sqrt(3.0)  # root mean square of U(0, 1)
SEED_SHARE = 1e-6  # where a fit starts a lead, as a share of the sample interval


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
    """One ``switch_lead_<trace>`` (s) per trace of :func:`leading_traces`: prior
    half-normal, scale Δ/√3 (Δ the trace's median sample interval; module docstring);
    fitted in log; seeded at :data:`SEED_SHARE` × Δ."""
    specs = []
    for tr in session.traces:
        if _leads(tr):
            dt = tr.dt
            specs.append(ParamSpec(lead_name(tr.name), "s", "trace",
                                   Prior("half_normal", 0.0, UNIFORM_RMS * dt, "nuisance"),
                                   SEED_SHARE * dt, trace=tr.name,
                                   description=f"how long before the first sample showing "
                                               f"it an input of trace {tr.name!r} changed"))
    return specs
