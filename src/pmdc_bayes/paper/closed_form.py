"""The reference paper's closed-form identification method (Section III).

Pure functions, one per equation of the method, with the paper's equation
numbers; then :func:`closed_form`, which picks the inputs it needs from a session
and says which it used.  The motor's own equations (steady state, τ, G, transfer
functions, state space) live in :mod:`pmdc_bayes.physics.motor` and are re-exported
here because the method is stated in their terms.  Everything is SI: Ra (Ω), La (H),
K = Kt = Kb (V·s/rad = N·m/A), B (N·m·s/rad), J (kg·m²), τ (s), G (rad/s per V).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._errors import NotApplicable, SessionError
from ..io.session import LA_ASSUMED, Session
from ..physics.load import drag_torque
from ..physics.motor import (
    gain,
    state_space,
    steady_state,
    tf_first_order,
    tf_full,
    tf_normalised,
    time_constant,
)
from .changes import responses
from .checks import check_physical, check_trace, step_of, traces_without_steady_current, turns

__all__ = [
    "only_assumed",
    "kb_from_chopper",
    "steady_rows_with_current",
    "b_from_steady",
    "j_from_tau",
    "time_constant",
    "gain",
    "tf_full",
    "tf_first_order",
    "tf_normalised",
    "state_space",
    "steady_state",
    "read_time_constant",
    "TimeConstantReading",
    "ClosedForm",
    "closed_form",
]


def kb_from_chopper(supply_voltage, duty, current, speed, Ra):
    """Back-emf constant from a chopper steady state.

    Notes
    -----
    Equation (20): ``Kb = (d·Va − Ia·Ra) / ω`` (V·s/rad).
    """
    return (duty * supply_voltage - current * Ra) / speed


def b_from_steady(K, current, speed, load=0.0):
    """Viscous friction from one steady state.

    Notes
    -----
    Equation (19): ``B = Kt·Ia / ω`` (N·m·s/rad) at no load; with a declared load
    torque TL the motor's own friction is what remains, ``(Kt·Ia − TL) / ω``.  All
    friction at that operating point, whatever its kind, is lumped into this one
    viscous coefficient.
    """
    return (K * current - load) / speed


def j_from_tau(tau, Ra, B, K):
    """Inertia from a measured time constant, equation (9) solved for J."""
    return tau * (B * Ra + K * K) / Ra


@dataclass(frozen=True)
class TimeConstantReading:
    """A 63.2 % reading of a step: levels, step time, crossing time and τ (SI)."""

    tau: float
    t_step: float
    t_cross: float
    initial: float
    final: float
    threshold: float
    dt: float


def read_time_constant(t, y, *, t_step=None, tail_fraction=0.1) -> TimeConstantReading:
    """Read the time constant of a step response at 63.2 % of the change.

    The initial level is the mean of the samples before the step (the first sample
    if the step is at the start), so a step from a non-zero speed works; the final
    level is the mean of the last ``tail_fraction`` of the samples.  The crossing
    is interpolated linearly between the samples on either side; with noise the
    reading is the mean of the first up-crossing and the last down-crossing.
    The result is uncertain by about one sampling interval (quantisation of the
    reading) plus noise/slope at the crossing.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t_step is None:
        t_step = float(t[0])
    before = y[t < t_step]
    initial = float(np.mean(before)) if before.size else float(y[0])
    n_tail = max(3, int(round(tail_fraction * y.size)))
    final = float(np.mean(y[-n_tail:]))
    threshold = initial + (1.0 - np.exp(-1.0)) * (final - initial)
    sign = 1.0 if final >= initial else -1.0
    after = t >= t_step
    ta, ya = t[after], sign * (y[after] - threshold)
    above = ya >= 0.0
    if not above.any() or above.all():
        raise ValueError("the trace never crosses 63.2 % of its change after the step")
    first = int(np.argmax(above))
    crossings = [first]
    below_idx = np.nonzero(~above)[0]
    last_below = int(below_idx[-1])
    if last_below + 1 < ya.size and last_below + 1 != first:
        crossings.append(last_below + 1)

    def _interp(k):
        if k == 0:
            return float(ta[0])
        y0, y1 = ya[k - 1], ya[k]
        return float(ta[k - 1] + (0.0 - y0) * (ta[k] - ta[k - 1]) / (y1 - y0))

    t_cross = float(np.mean([_interp(k) for k in crossings]))
    dt = float(np.median(np.diff(t)))
    return TimeConstantReading(t_cross - t_step, t_step, t_cross, initial, final, threshold, dt)


def _read_step(tr) -> TimeConstantReading:
    """The 63.2 % reading of a step trace: the response to its largest voltage change,
    up to the next change comparable to it (:func:`.changes.responses`; a staircase's
    one step), else the whole trace from its step."""
    found = responses(tr)
    if not found:
        return read_time_constant(tr.time, tr.speed, t_step=step_of(tr)[0])
    r = found[0]
    return read_time_constant(tr.time[r.start:r.stop], tr.speed[r.start:r.stop], t_step=r.time)


def only_assumed(used: dict, name: str) -> bool:
    """Whether the closed form's ``name`` was assumed rather than obtained (``used``:
    how it got each value, as in :attr:`ClosedForm.used` and a summary's
    ``closed_form.used``): an unmeasured La, not worth comparing with a fit."""
    return str(used.get(name, "")).startswith("assumed")


@dataclass(frozen=True)
class ClosedForm:
    """The closed-form estimates (SI) and where each input came from.

    ``applicable`` is False for a seed built from the data when the method cannot run
    on the session (``reason`` says why); its values then only start the fit.
    """

    Ra: float
    La: float
    K: float
    B: float
    J: float
    tau: float
    G: float
    used: dict = field(default_factory=dict)
    applicable: bool = True
    reason: str = ""
    warnings: tuple = ()

    def params(self) -> dict:
        return {"Ra": self.Ra, "La": self.La, "K": self.K, "B": self.B, "J": self.J}

    def known(self) -> dict:
        """:meth:`params` without what the method only assumed (an unmeasured La): the
        values worth comparing with a fit."""
        return {k: v for k, v in self.params().items() if not only_assumed(self.used, k)}

    def tf22(self):
        return tf_normalised(self.Ra, self.La, self.K, self.B, self.J)

    def as_json(self) -> dict:
        num, den = self.tf22()
        out = dict(self.params(), tau=self.tau, G=self.G)
        out["tf22"] = {"num": [float(v) for v in num], "den": [float(v) for v in den]}
        out["used"] = dict(self.used)
        out["applicable"] = self.applicable
        out["warnings"] = list(self.warnings)
        if not self.applicable:
            out["reason"] = self.reason
        return out


def steady_rows_with_current(session: Session):
    """(table name, V, I, ω arrays) of the first steady table's unloaded, turning rows
    with a current, or None."""
    for tab in session.steady_tables:
        if tab.current is None:
            continue
        keep = (tab.load_torque == 0) & (tab.speed != 0) & np.isfinite(tab.current)
        if keep.any():
            return tab.name, tab.voltage[keep], tab.current[keep], tab.speed[keep]
    return None


def closed_form(session: Session) -> ClosedForm:
    """Apply the paper's method to a session, choosing its inputs.

    Kb comes from the first operating point with a current (20), else from the
    settled end of a step trace with current (20) with d = 1, else from (20) at every
    unloaded row of a steady table with currents (averaged); Kt = Kb; B from (19)
    at the same point(s); τ from a step reading or the 63.2 % point of the first step
    trace; J from (9); G from (10).  ``session.closed_form_options["K_decimals"]``
    rounds K before it is used in (19) and (9), as the paper did.

    Raises
    ------
    NotApplicable
        When the session has no steady current or no step: the method cannot run.
    """
    Ra, La = session.Ra.value, session.La.value
    used = {"Ra": "bench measurement",
            "La": ("assumed, not measured (La/Ra = 1 ms)" if session.La.source == LA_ASSUMED
                   else "bench measurement")}
    steps = [t for t in session.traces if t.kind == "step"]

    op = next((p for p in session.operating_points if p.current is not None), None)
    if op is not None:
        Va, Ia, w, TL = op.voltage, op.current, op.speed, op.load_torque
        K = kb_from_chopper(op.supply_voltage, op.duty, Ia, w, Ra)
        used["K"] = f"equation (20) at operating point {op.name!r}"
    else:
        TL = 0.0
        with_current = [t for t in steps if t.current is not None and turns(t)]
        rows = steady_rows_with_current(session)
        if with_current:
            tr = with_current[0]
            n_tail = max(3, tr.n // 10)
            Va = float(tr.voltage.at(tr.time[-n_tail:]).mean())
            Ia = float(tr.current[-n_tail:].mean())
            w = float(tr.speed[-n_tail:].mean())
            TL = float(drag_torque(tr.drag, w))
            K = kb_from_chopper(Va, 1.0, Ia, w, Ra)
            used["K"] = f"equation (20) at the settled end of trace {tr.name!r}"
        elif rows is not None:
            name, Va, Ia, w = rows
            K = float(np.mean(kb_from_chopper(Va, 1.0, Ia, w, Ra)))
            used["K"] = f"equation (20) per row of steady table {name!r}, averaged"
        else:
            raise NotApplicable(session.root / "session.toml",
                                "the closed-form method needs a steady current: add an "
                                "[[operating_point]] with a current, a step trace with a "
                                "current column or a steady table with a current column"
                                + traces_without_steady_current(session), where="operating_point")
    digits = session.closed_form_options.get("K_decimals")
    if digits is not None:
        K = round(K, int(digits))
        used["K"] += f", rounded to {int(digits)} decimals as published"
    B = float(np.mean(b_from_steady(K, Ia, w, TL)))
    used["B"] = "equation (19) at the same point" + ("s, averaged" if np.size(Ia) > 1 else "")
    if TL:
        used["B"] += ", less its declared load torque"

    if session.step_readings:
        sr = session.step_readings[0]
        tau = sr.tau
        used["tau"] = f"step reading {sr.name!r}"
    elif steps:
        # the largest step that turns, one without a declared drag where there is one
        # (equation (9) knows no load)
        tr = max(steps, key=lambda s: (turns(s), not s.drag.nonzero,
                                       abs(step_of(s)[2] - step_of(s)[1])))
        try:
            tau = _read_step(tr).tau
        except ValueError as exc:
            raise SessionError(tr.file, f"cannot read a time constant from trace {tr.name!r}: "
                               f"{exc}; log the step until the speed settles") from None
        used["tau"] = f"63.2 % point of trace {tr.name!r}"
    else:
        raise NotApplicable(session.root / "session.toml",
                            "the closed-form method needs a step: add a [[trace]] with "
                            "kind = \"step\" or a [[step_reading]]", where="trace")
    J = j_from_tau(tau, Ra, B, K)
    used["J"] = "equation (9) from τ"
    check_physical(session, Ra, La, K, B, tau, used)
    if not session.step_readings:
        check_trace(session, tr, K, B, Ra)
    warnings = () if B > 0 else (
        f"B = {B:.3g} from {used['B']}: viscous friction cannot be negative or zero; the "
        "no-load current there is within its noise (or its sign is wrong), so (19) cannot "
        "resolve B: the fit does, from the traces",)
    return ClosedForm(Ra, La, K, B, J, tau, gain(Ra, K, B), used, warnings=warnings)
