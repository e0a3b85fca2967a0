"""The levels a noisy logged input column held, fitted: each level's value known from
its readings only to their standard error.

A noisy column (an ADC reading of the driver's output, a torque sensor) is read as the
levels it held (:mod:`pmdc_bayes.io.held_levels`), each the mean of its readings.  Taken
as exact, a level's error (the column's noise over the square root of its readings)
moves every prediction that level drives as if the motor had made it: on a session
whose speeds fix K/B to a part in 10⁴, a voltage level known to a part in 2,000 puts
K and B several standard deviations off with intervals that do not show it.  So each
such level is a parameter, ``voltage_level_<trace>_<j>`` (V) or
``load_level_<trace>_<j>`` (N·m), its prior normal about the level's mean with its
standard error (what the column's readings say of it; source :data:`READINGS`), fitted
in value; the segments the level drives take its value (:func:`segment_levels`,
:meth:`.effects.RigEffects.held`), and the Laplace approximation and the posterior
carry its uncertainty into the motor's parameters.  A level read as zero (the driver's
zero command: its se 0) is not fitted: it is zero.  A column of more than
:data:`MAX_LEVELS` levels (a drifting supply cut into many) keeps them as read.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...io.session import Schedule, Session, Trace
from .params import ParamSpec, Prior, identifier

__all__ = ["INPUTS", "READINGS", "MAX_LEVELS", "level_names", "level_specs",
           "segment_levels", "level_data"]

READINGS = "column readings"  # the prior's source: the level's own readings
MAX_LEVELS = 16  # per column: more are kept as read


class Input(NamedTuple):
    """An input a column may log: its unit, the trace's attributes of its schedule and of
    whether a column logged it, and the experiment's field of its segments' values."""

    unit: str
    schedule: str
    logged: str
    segments: str


INPUTS = {"voltage": Input("V", "voltage", "voltage_logged", "seg_va"),
          "load": Input("N*m", "load_torque", "load_logged", "seg_tl")}


def _schedule(tr: Trace, what: str) -> Schedule:
    return getattr(tr, INPUTS[what].schedule)


def _fitted(tr: Trace, what: str) -> np.ndarray:
    """The indices of ``tr``'s ``what`` levels fitted: every level of a noisy column read
    as levels but one read as zero, none of a column of more than :data:`MAX_LEVELS`."""
    s = _schedule(tr, what)
    if not (getattr(tr, INPUTS[what].logged) and s.se is not None
            and 1 <= s.values.size <= MAX_LEVELS):
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.asarray(s.se) > 0)


def level_names(session: Session, what: str) -> tuple[str, ...]:
    """The parameter names of every fitted ``what`` (``"voltage"`` or ``"load"``) level
    of the session, trace after trace, each named by its index among its column's."""
    return tuple(f"{what}_level_{identifier(tr.name)}_{j}" for tr in session.traces
                 for j in _fitted(tr, what))


def level_specs(session: Session) -> list[ParamSpec]:
    """A ``<input>_level_<trace>_<j>`` per level of each noisy input column (module
    docstring): prior normal, centre the level's mean, sd its standard error; fitted in
    value; seeded at the mean."""
    specs = []
    for what, spec in INPUTS.items():
        for tr in session.traces:
            s = _schedule(tr, what)
            for j in _fitted(tr, what):
                m, se = s.values[j], s.se[j]
                specs.append(ParamSpec(
                    f"{what}_level_{identifier(tr.name)}_{j}", spec.unit, "trace",
                    Prior("normal", float(m), float(se), READINGS), float(m),
                    transform="identity", trace=tr.name,
                    description=f"the level of trace {tr.name!r}'s {what} column from "
                                f"{float(s.times[j]):.6g} s"))
    return specs


def segment_levels(session: Session, seg_t0, seg_len, seg_trace,
                   what: str) -> np.ndarray | None:
    """Per segment of an experiment of the session's traces (``seg_t0`` on each trace's
    clock, lasting ``seg_len``, ``seg_trace`` its trace), the index of its fitted
    ``what`` level in :func:`level_names` (the level holding at the segment's middle: a
    level's segments lie within it), −1 for a segment no fitted level drives (a level
    read as zero among them); None when no trace has one."""
    middle = np.asarray(seg_t0, float) + 0.5 * np.asarray(seg_len, float)
    seg_trace = np.asarray(seg_trace, int)
    out = np.full(middle.size, -1, dtype=np.int32)
    base = 0
    for k, tr in enumerate(session.traces):
        fitted = _fitted(tr, what)
        if not fitted.size:
            continue
        s = _schedule(tr, what)
        rank = np.full(s.values.size, -1, dtype=np.int32)
        rank[fitted] = base + np.arange(fitted.size)
        mine = seg_trace == k
        j = np.searchsorted(s.times, middle[mine], side="right") - 1
        out[mine] = rank[np.clip(j, 0, s.values.size - 1)]
        base += fitted.size
    return out if base else None


def level_data(session: Session, exp) -> dict:
    """``level_<input>``: each segment's fitted level of a noisy ``<input>`` column
    (:func:`segment_levels`) of the experiment ``exp`` of the session's traces, for the
    inputs that have one (:meth:`.effects.RigEffects.held` reads them)."""
    out = {}
    for what in INPUTS:
        index = segment_levels(session, exp.seg_t0, exp.seg_len, exp.seg_trace, what)
        if index is not None:
            out[f"level_{what}"] = index
    return out
