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

Each change of a trace whose switching inputs all come from columns therefore carries
a fitted lead, ``switch_lead_<trace>_<j>`` (s; ``switch_lead_<trace>`` where the trace
changes once, or more than :data:`MAX_CHANGES` times, when its changes share one): the
change happened that long before the sample that shows it, the segment it starts
beginning that much earlier (:meth:`.effects.RigEffects.inputs`; a dead time is added
on top).  A driver that switches at its own times puts each change at its own place in
the interval; one lead for all of them leaves the others' first current readings, or
a fast speed sensor's, off by up to the electrical time constant's share of the jump.
Its prior is normal with the mean and standard deviation of an even mixture of the
two ways a rig logs a column: switching at the sample that shows the change (a lead of
0: a logger that sets its command at a sample), and anywhere in the interval Δ before it
(uniform: a driver on its own clock, an ADC reading the driver's output), Δ the trace's
median sample interval: mean Δ/4, sd Δ·√(5/48).  Fitted in value, so a slightly
negative lead (a change shown a sample late) is not excluded.  A trace's first segment
is a change too where the trace starts from rest under a column already away from zero.
A column sampled from a switching driver places a change of duty only to several
samples (:func:`placement_sd`): that change's lead has its prior widened by as much.

Where the armature's time constant is much shorter than Δ, the density in the lead is
a box: flat where the first current sample after a change reads the current risen (or
not yet moved), falling within a time constant of the lead at which the change reaches
that sample.  A fit started on the wrong flat part sees no slope towards the right one,
so a fit starts each lead at the best of :data:`SCAN_SHARES` × Δ (:func:`lead_scans`),
the rest of the parameters at their start.  A schedule written in ``session.toml``
states its own times; a trace with one that changes keeps them.
"""

from __future__ import annotations

import numpy as np

from ...io.session import Session, Trace
from .params import ParamSpec, Prior, identifier

__all__ = ["lead_name", "lead_names", "lead_specs", "leading_traces", "lead_scans",
           "segment_leads", "lead_data", "placement_sd", "session_lead_names", "change_times",
           "SCAN_SHARES", "MAX_CHANGES", "TIMING", "PRIOR_MEAN", "PRIOR_SD"]

# an even mixture of a lead of 0 and a uniform one over the interval, as shares of it
PRIOR_MEAN, PRIOR_SD = 0.25, float(np.sqrt(5.0 / 48.0))
SCAN_SHARES = np.array([-0.5, -0.2, 0.0, 0.1, 0.25, 0.5, 0.75, 0.95])  # of Δ
MAX_CHANGES = 16  # per trace: more changes share one lead
AWAY = 3.0  # standard errors: a noisy column's first level this far from zero is a change
TIMING = "the sample interval"  # the prior's source: where the column shows the change


def lead_name(trace_name: str) -> str:
    """The parameter name of a trace's one lead (a trace that changes once, or more
    than :data:`MAX_CHANGES` times)."""
    return f"switch_lead_{identifier(trace_name)}"


def _inputs(tr: Trace):
    return ((tr.voltage, tr.voltage_logged), (tr.load_torque, tr.load_logged))


def _leads(tr: Trace) -> bool:
    """Whether ``tr``'s switching inputs all come from columns, and one of them switches."""
    switching = [logged for schedule, logged in _inputs(tr) if schedule.change_times().size]
    return bool(switching) and all(switching)


def change_times(tr: Trace) -> np.ndarray:
    """The times (s, the trace's clock) of ``tr``'s logged inputs' changes: each sample
    that shows a new value, and the trace's start where it starts from rest under a
    column away from zero (module docstring); none for a trace without a lead."""
    if not _leads(tr):
        return np.zeros(0)
    times = []
    for schedule, logged in _inputs(tr):
        if not logged or np.size(schedule.values) == 0:
            continue
        times.append(schedule.change_times())
        if isinstance(tr.initial, str) and tr.initial == "rest" and _away(schedule):
            times.append(np.asarray(schedule.times, dtype=float)[:1])
    return np.unique(np.concatenate(times)) if times else np.zeros(0)


def _away(schedule) -> bool:
    """Whether a column's first value is away from zero: not zero, and for a noisy
    column's level more than :data:`AWAY` standard errors from it."""
    first = float(schedule.values[0])
    se = 0.0 if schedule.se is None else float(schedule.se[0])
    return first != 0.0 and abs(first) > AWAY * se


def lead_names(tr: Trace) -> tuple[str, ...]:
    """The names of ``tr``'s leads: one per change, or one shared (:func:`lead_name`)
    where it changes once or more than :data:`MAX_CHANGES` times."""
    return _changes(tr)[1]


def _changes(tr: Trace) -> tuple[np.ndarray, tuple[str, ...]]:
    """:func:`change_times` of ``tr`` and :func:`lead_names` for them."""
    times = change_times(tr)
    n = times.size
    if n == 0:
        return times, ()
    if n == 1 or n > MAX_CHANGES:
        return times, (lead_name(tr.name),)
    return times, tuple(f"{lead_name(tr.name)}_{j}" for j in range(n))


def leading_traces(session: Session) -> tuple[str, ...]:
    """The traces that carry fitted leads (module docstring)."""
    return tuple(tr.name for tr in session.traces if lead_names(tr))


def lead_specs(session: Session) -> list[ParamSpec]:
    """The leads of every trace (:func:`lead_names`): prior normal, centre Δ/4, sd
    Δ·√(5/48) (Δ the trace's median sample interval; module docstring); fitted in value;
    seeded at the prior's centre."""
    specs = []
    for tr in session.traces:
        times, names = _changes(tr)
        for j, (name, spread) in enumerate(zip(names, _spreads(tr, times, names),
                                               strict=True)):
            when = "each change" if len(names) < times.size else \
                f"the change at {float(times[j]):.6g} s"
            sd = float(np.hypot(PRIOR_SD * tr.dt, spread))
            specs.append(ParamSpec(name, "s", "trace",
                                   Prior("normal", PRIOR_MEAN * tr.dt, sd, TIMING),
                                   PRIOR_MEAN * tr.dt, transform="identity", trace=tr.name,
                                   description=f"how long before the first sample showing "
                                               f"it trace {tr.name!r}'s input made "
                                               f"{when}"))
    return specs


def placement_sd(tr: Trace, times: np.ndarray) -> np.ndarray:
    """Per change of ``tr`` at ``times``, how far (sd, s) its column's readings leave
    where it fell, beyond the sample interval: 0 but for a change of a column sampled
    from a switching driver (:mod:`pmdc_bayes.io.held_levels`), whose readings show a
    change of duty only over the samples it takes the two duties' draws to differ.  The
    cut between two levels whose per-reading sds σ₁, σ₂ differ by δ falls about the
    change with the scale s = (σ₁² + σ₂²)/(2δ²) samples and the sd √26·s (the argmax of
    a two-sided random walk with drift, Hinkley 1970), at most half the shorter level."""
    out = np.zeros(np.size(times))
    col = tr.voltage
    if not (tr.voltage_logged and col.switched and col.se is not None
            and col.values.size > 1):
        return out
    start = np.asarray(col.times, dtype=float)
    n = np.diff(np.searchsorted(tr.time, np.append(start, np.inf))).clip(min=1)
    var = np.asarray(col.se, dtype=float) ** 2 * n  # each level's per-reading variance
    delta = np.diff(np.asarray(col.values, dtype=float))
    with np.errstate(divide="ignore"):
        samples = np.sqrt(26.0) * (var[:-1] + var[1:]) / (2.0 * delta**2)
    samples = np.minimum(samples, np.minimum(n[:-1], n[1:]) / 2.0)
    times = np.asarray(times, dtype=float)
    at = np.clip(np.searchsorted(start, times), 1, start.size - 1)
    hit = np.abs(start[at] - times) <= 1e-3 * tr.dt
    out[hit] = samples[at[hit] - 1] * tr.dt
    return out


def _spreads(tr: Trace, times: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """Per lead ``names`` of ``tr`` whose changes fall at ``times`` (:func:`_changes`),
    :func:`placement_sd` of its change; 0 for a lead its changes share (each change's
    misplacement is its own, which one lead cannot take up)."""
    return placement_sd(tr, times) if len(names) == times.size else np.zeros(len(names))


def lead_scans(session: Session) -> dict[str, np.ndarray]:
    """Per lead of :func:`lead_specs`, the values (s) a fit's start is chosen among:
    :data:`SCAN_SHARES` × Δ, and where a switched column places its change only to
    several samples, as many again across twice that sd either way."""
    out = {}
    for tr in session.traces:
        times, names = _changes(tr)
        for name, spread in zip(names, _spreads(tr, times, names), strict=True):
            wide = np.linspace(-2.0, 2.0, SCAN_SHARES.size) * spread if spread > tr.dt else []
            out[name] = np.concatenate([SCAN_SHARES * tr.dt, wide])
    return out


def segment_leads(session: Session, seg_t0, seg_trace) -> np.ndarray | None:
    """Per segment of an experiment of the session's traces (``seg_t0`` on each trace's
    clock, ``seg_trace`` its trace), the index among the session's leads (trace after
    trace, in :func:`lead_names`' order) of the lead of the change it starts with, −1 for
    a segment no change starts; None when no trace has a lead."""
    seg_t0, seg_trace = np.asarray(seg_t0, float), np.asarray(seg_trace, int)
    out = np.full(seg_t0.size, -1, dtype=np.int32)
    base = 0
    for k, tr in enumerate(session.traces):
        times, names = _changes(tr)
        if not names:
            continue
        mine = np.flatnonzero(seg_trace == k)
        x = seg_t0[mine]
        near = np.clip(np.searchsorted(times, x), 0, times.size - 1)
        before = np.maximum(near - 1, 0)  # the nearer of the changes either side
        j = np.where(np.abs(times[before] - x) < np.abs(times[near] - x), before, near)
        hit = np.abs(times[j] - x) <= 1e-3 * tr.dt  # changes lie a sample apart at least
        out[mine[hit]] = base + (j[hit] if len(names) > 1 else 0)
        base += len(names)
    return out if base else None


def lead_data(session: Session, exp) -> dict:
    """``lead_index``: each segment's lead (:func:`segment_leads`) of the experiment
    ``exp`` of the session's traces, where any trace has one
    (:meth:`.effects.RigEffects.inputs` reads it)."""
    index = segment_leads(session, exp.seg_t0, exp.seg_trace)
    return {} if index is None else {"lead_index": index}


def session_lead_names(session: Session) -> tuple[str, ...]:
    """Every lead of the session, trace after trace (:func:`segment_leads`' order)."""
    return tuple(name for tr in session.traces for name in lead_names(tr))
