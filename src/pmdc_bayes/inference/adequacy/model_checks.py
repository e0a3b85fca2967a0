"""Checks of the model itself at the MAP rather than of its fit to the data: a motor
parameter pressed against zero (its physical bound), a segment whose regime changes
more often than the exact solution follows, a trace that outruns its known load's
curve; a coast-down whose misfit is a hold before the armature was opened."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...io.channel import ChannelId
from ...io.run_down import hold_then_fall
from ...io.units import display_unit, unit_factor
from ...physics.limited import PHASES
from .findings import Check, Finding, Severity

__all__ = ["bound_checks", "solver_checks", "drag_checks", "coast_start_notes", "BOUND_Z",
           "CURVE_REACH"]

BOUND_Z = 2.0  # a motor parameter this many prior sd below its prior's centre, prior-bound
CURVE_REACH = 1.05  # a trace this much faster than its drag curve's last point is warned


def solver_checks(model, fit) -> list:
    """Input segments whose regime (stuck, moving, clamped; the current's sign under a
    voltage drop) changes at the MAP more often than the regime-switching solution
    follows: after the last change it follows its prediction is not exact, so the fit
    cannot be trusted there."""
    out = []
    for tr, starts in zip(model.session.traces, model.beyond_phases(fit.theta), strict=True):
        if not starts.size:
            continue
        out.append(Finding(
            Check.SOLVER, tr.name, Severity.FAIL, f"{starts.size} segment(s)",
            f"{tr.name}: between input changes the motor changes regime more than "
            f"{PHASES} times (first in the segment from t = {starts[0]:.6g} s: the current "
            "ringing through zero under a voltage drop, or a rotor sticking and slipping "
            "again and again); the exact solution follows the first "
            f"{PHASES}, so the model's prediction after them is not exact",
            "log the voltage as a column (each sample starts a segment of its own) or "
            "shorten the trace's constant stretches"))
    return out


def drag_checks(model) -> list:
    """Traces that run faster than their declared drag curve reaches: beyond its last
    point the drag is extended along its last slope, which the curve does not measure."""
    out = []
    for tr in model.session.traces:
        if not tr.drag.curve or tr.speed is None or not np.any(np.isfinite(tr.speed)):
            continue
        last, top = tr.drag.curve[-1][0], float(np.nanmax(np.abs(tr.speed)))
        if top > CURVE_REACH * last:
            out.append(Finding(
                Check.KNOWN_LOAD, tr.name, Severity.WARN, f"{top / last:.3g}x its last point",
                f"{tr.name}: the speed reaches {top:.4g} rad/s, {top / last:.3g} times the "
                f"last point of its drag curve ({last:.4g} rad/s); beyond it the drag is "
                "its last slope extended, which nothing measured: the fit there rests on "
                "that guess", "extend the curve to the trace's top speed"))
    return out


def bound_checks(model, fit) -> list:
    """Motor parameters pressed against zero, their physical bound: the MAP lies more
    than :data:`BOUND_Z` prior sd below its prior's centre and only the prior holds it
    there (posterior as wide as the prior), so the data want less than none of it and
    another part of the model does its work."""
    out = []
    centre, scale = model.registry.prior_arrays()
    width = np.asarray(model.prior_sd)
    sd_log = np.sqrt(np.clip(np.diag(fit.cov_log), 0.0, None))
    for k, spec in enumerate(model.registry.specs):
        if (spec.block not in ("motor", "friction") or spec.prior.kind != "lognormal"
                or spec.prior.source == "bench"):
            continue
        z = (float(fit.theta[k]) - centre[k]) / scale[k]
        if z < -BOUND_Z and sd_log[k] > 0.8 * width[k]:
            value = float(np.exp(fit.theta[k]))
            out.append(Finding(
                Check.PHYSICAL_BOUND, spec.name, Severity.FAIL,
                f"{-z:.2g} prior sd below its centre",
                f"{spec.name} is pressed against zero: the fit puts it at {value:.3g} "
                f"{display_unit(spec.unit)}, {-z:.2g} prior sd below its prior's centre "
                f"({np.exp(centre[k]):.3g}), where only the prior holds it: the data want "
                f"less than none of it, and another part of the model does its work",
                _bound_suggestion(spec.name)))
    return out


def _bound_suggestion(name: str) -> str:
    """What to do about parameter ``name`` pressed against zero."""
    if name == "La":  # less than no electrical lag: the response leads its logged voltage
        return ("the response starts earlier than the session's voltage says (a voltage "
                "column shows each change at the first sample after it happened; a "
                "trigger offset): --add dead-time, whose negative value is a response "
                "leading its log; if La is truly negligible, measure it ([bench.La]) or "
                "rerun with --allow-inadequate")
    return ("check what else carries it (a declared load too strong, a friction model "
            "the data do not need: --friction viscous for Tc); if it is truly "
            "negligible, rerun with --allow-inadequate")


def coast_start_notes(model, findings: list) -> list:
    """``findings`` with the first one on each coast-down's speed told, where its record
    holds at its first level and then falls faster (:func:`...io.run_down.hold_then_fall`,
    as a coasting rotor cannot), when the armature was most likely opened.  The loader
    refuses such a record only where its time starts before 0 (an oscilloscope's
    trigger); one from 0 is fitted, and a hold there misfits as much as a lagging
    sensor's, so it is named only once the fit has missed it."""
    held = {}
    for tr in model.session.coast_downs:
        h = hold_then_fall(tr.time, tr.speed)
        if h is not None:
            held[ChannelId(tr.name, "speed")] = (tr, h)
    out = []
    for f in findings:
        tr, h = held.pop(f.where, (None, None)) if isinstance(f.where, ChannelId) else (None, None)
        if h is None:
            out.append(f)
            continue
        per_unit = unit_factor("time", tr.time_unit)
        opened = f"{h.opened / per_unit:.4g}"
        note = (f"{tr.name}: the speed holds its first level until t = {opened} "
                f"{tr.time_unit} and then falls {h.ratio:.3g}x as much as over the same time "
                "before, as a coasting rotor cannot: if the armature was opened then, give "
                f"trace['{tr.name}'].opened = {opened} or remove the rows before it; a "
                "lagging speed sensor also holds its reading at first (--add speed-lag)")
        out.append(replace(f, suggestion="; ".join(x for x in (f.suggestion, note) if x)))
    return out
