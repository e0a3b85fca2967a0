"""Where a fit starts: the paper's closed form when it applies, else a seed read from
the data (speed-only sessions, sessions without a step's steady current)."""

from __future__ import annotations

import numpy as np

from ..._errors import NotApplicable, SessionError
from ...io.robust import AT_REST, smallest_step
from ...io.session import LA_ASSUMED
from ...paper.changes import RESPONSE_SHARE, responses
from ...paper.closed_form import ClosedForm, closed_form, j_from_tau, read_time_constant
from ...physics.motor import gain
from .first_order import first_order
from .levels import settled, unloaded_levels, voltage_intercept
from .noise import noise_scale

__all__ = ["fit_seed", "seed_from_data", "motor_seed", "drop_seed",
           "FRICTION_SHARE"]

FRICTION_SHARE = 0.1  # without a current, viscous friction is taken as this share of Ra·B + K²
CLEAR_CHANGE = 10.0  # noise levels a response must move by to read its 63.2 % point
MIN_RESPONSE = 20  # samples after a change to read its response from
STEP_SHARE = 0.5  # of a trace's voltage range, a change whose rise is read as a step's
REACH = 2.0  # time constants a rise's level is extrapolated over, at most, per span seen
RICH = 8  # input changes of a trace whose whole record reads better than one step's rise
SHARE_MOVED = 0.25  # of its share of the voltage range a change's response moves the speed


def fit_seed(session) -> ClosedForm:
    """The closed form of ``session``, or, when the method cannot run on it, a seed
    from the data (``applicable`` False, the reason kept)."""
    try:
        return closed_form(session)
    except NotApplicable as exc:
        return seed_from_data(session, exc.message)


def _holds(tr, r, which: str) -> bool:
    """Whether the input ``which`` stays near the level a change took it to over the
    change's response: nine in ten of its samples there within
    :data:`~pmdc_bayes.paper.changes.RESPONSE_SHARE` of the change (a step, not the
    first move of a sweep whose response is no step's)."""
    t = tr.time[r.start:r.stop]
    x = getattr(tr, which).at(t[t >= r.time])
    return x.size == 0 or bool(np.quantile(np.abs(x - r.after), 0.9)
                               <= RESPONSE_SHARE * r.size)


def _changes(session, held: bool = True) -> list:
    """``(trace, response, sign)`` for every change of a driven trace's voltage (sign
    +1: the speed follows it), largest first over all traces, then every change of a
    load (sign −1) (:func:`pmdc_bayes.paper.changes.responses`: each with the span until
    the next change comparable to it); with ``held`` those after which the input holds
    (:func:`_holds`), else the others."""
    out = []
    for which, sign in (("voltage", 1.0), ("load_torque", -1.0)):
        out += sorted(((tr, r, sign) for tr in session.traces for r in responses(tr, which)
                       if _holds(tr, r, which) == held),
                      key=lambda pair: -pair[1].size)
    return out


def _share(tr, r) -> float:
    """The share of trace ``tr``'s voltage range that its voltage change ``r`` spans."""
    span = float(np.ptp(tr.voltage.at(tr.time)))
    return abs(r.after - r.before) / span if span > 0 else 0.0


def _complete(read, tr, r, sign: float, t: np.ndarray, y: np.ndarray) -> bool:
    """Whether a 63.2 % reading of the response ``y`` at ``t`` (of trace ``tr``) to the
    change ``r`` is of a whole response: over :data:`MIN_RESPONSE` samples, its speed
    moves the way the change drives it (``sign``) by :data:`CLEAR_CHANGE` noise levels (a
    quantised speed's at least its quantum's) and, for a voltage's change, by at least
    :data:`SHARE_MOVED` of the share of the trace's speed range that the change is of its
    voltage range (a motor's speed follows its voltage in proportion once settled);
    it settles, and reaches 63.2 % of its change within a third of the span after the
    change (a first-order response is at 95 % after three τ; a ramp cut short, as a
    sweep's or a short pulse's, crosses late)."""
    after = y[t >= read.t_step]
    moved = (read.final - read.initial) * sign * np.sign(r.after - r.before)
    noise = max(noise_scale(y), smallest_step(y) / np.sqrt(12.0))
    if after.size < MIN_RESPONSE or moved < CLEAR_CHANGE * noise:
        return False
    if sign > 0 and moved < SHARE_MOVED * _share(tr, r) * np.ptp(tr.speed[np.isfinite(tr.speed)]):
        return False
    return bool(settled(after) and read.tau <= (t[-1] - read.t_step) / 3.0)


def _read_changes(pairs) -> tuple[tuple[float, str] | None, list, tuple | None]:
    """The τ of the first of ``pairs`` whose response settles before the next change
    comparable to it, the readings of those that cross 63.2 % of their change without
    settling, and the first failure to read one."""
    readings, failure = [], None
    for tr, r, sign in pairs:
        t, y = tr.time[r.start:r.stop], tr.speed[r.start:r.stop]
        try:
            read = read_time_constant(t, y, t_step=r.time)
        except ValueError as exc:
            failure = failure or (tr, exc)
            continue
        where = f"63.2 % point of trace {tr.name!r} after its change at {r.time:g} s"
        if _complete(read, tr, r, sign, t, y):
            return (read.tau, where), readings, failure
        readings.append((read.tau, where))
    return None, readings, failure


def _time_constant(session, toml) -> tuple[float, str]:
    """τ and where it was read: a step reading; the largest input change of a driven
    trace whose response settles before the next change comparable to it; a first-order
    model fitted to a trace's whole record (:func:`.first_order.first_order`); a
    coast-down's 63.2 % decay time; or, last, the 63.2 % point of the largest
    response that does not settle (one after which the input holds, else any)."""
    if session.step_readings:
        return session.step_readings[0].tau, f"step reading {session.step_readings[0].name!r}"
    got, unsettled, failure = _read_changes(_changes(session))
    if got is not None:
        return got
    mixed = first_order(session)
    if mixed is not None:
        return mixed[1], mixed[2]
    for cd in session.coast_downs:
        try:
            return (read_time_constant(cd.time, cd.speed).tau,
                    f"63.2 % decay of coast-down {cd.name!r} (J/B, the viscous part)")
        except ValueError:
            continue
    got, unheld, other = _read_changes(_changes(session, held=False))
    if got is not None or unsettled or unheld:
        return got or (unsettled + unheld)[0]
    if (failure or other) is not None:
        tr, exc = failure or other
        raise SessionError(tr.file, f"cannot read a time constant from trace {tr.name!r}: "
                           f"{exc}; log the response until the speed settles")
    raise SessionError(toml, "no response to read a time constant from: add a [[trace]] "
                       "whose voltage or load changes, a coast-down, or a [[step_reading]]",
                       where="trace")


def _extrapolated(session, held: bool = True) -> tuple[float, float, str] | None:
    """The steady gain and τ of the largest voltage change of a driven trace with a
    logged speed, a step (:data:`STEP_SHARE` of its voltage range or more; after which
    the input holds, or with ``held`` False does not), from a
    first-order rise fitted to its response (the level it heads for and its time
    constant, at most :data:`REACH` times the span it is read over), for a session in
    which no level settles; None without one that rises at all."""
    for tr, r, sign in _changes(session, held):
        if (sign < 0 or r.stop - r.start < 8
                or _share(tr, r) < STEP_SHARE):
            continue  # not a step: a sweep's next level
        t, y = tr.time[r.start:r.stop], tr.speed[r.start:r.stop]
        pre, post = t < r.time, t >= r.time
        y0 = float(np.mean(y[pre])) if pre.any() else float(y[0])
        tt, yy = t[post] - r.time, y[post] - y0
        if tt.size < 8 or tt[-1] <= 0:
            continue
        # y = level + c·exp(−t/τ) past the first tenth (the current's own rise, which
        # a first-order curve does not follow, is over by then): level and c by least
        # squares at each τ of a grid
        keep = tt >= 0.1 * tt[-1]
        tk, yk = tt[keep], yy[keep]
        best = None
        for tau in np.geomspace(tt[-1] / 200, tt[-1] * 20, 160):
            basis = np.column_stack([np.ones_like(tk), np.exp(-tk / tau)])
            coef, *_ = np.linalg.lstsq(basis, yk, rcond=None)
            cost = float(np.sum((yk - basis @ coef) ** 2))
            if best is None or cost < best[0]:
                best = (cost, float(coef[0]), float(tau))
        _, delta, tau = best
        if delta * (r.after - r.before) <= 0 or tau > REACH * tt[-1]:
            continue  # falling, or a level extrapolated from too little of its rise
        return (delta / (r.after - r.before), tau,
                f"a first-order rise fitted to trace {tr.name!r} after its change at "
                f"{r.time:g} s (it does not settle)")
    return None


def _turning(rows: np.ndarray) -> np.ndarray:
    """The steady levels at which the motor turns: a voltage and a speed both above
    :data:`AT_REST` of the largest (a held 0 V, or a logged one's noise, is not a
    level to read a gain or (20) from)."""
    if not rows.size:
        return rows
    v, w = np.abs(rows[:, 0]), np.abs(rows[:, 1])
    return rows[(v > AT_REST * v.max()) & (w > AT_REST * w.max())]


def seed_from_data(session, reason: str = "") -> ClosedForm:
    """Starting values from the session's own numbers, for when the closed form
    cannot run.

    The steady gain G comes from the unloaded steady levels at which the motor turns,
    every held plateau of every trace included (a line through the origin of speed
    against voltage).  With currents at those levels, K and B follow from (20) and
    (19); without, K = 1/(G·(1 + f)) and B = f·K²/Ra with f =
    :data:`FRICTION_SHARE` (speed alone cannot split the damping between friction and
    back-emf; the fit's priors are wide and the identifiability section says what the
    data decide).  τ is a step reading's, or the 63.2 % time of the response to the
    largest voltage (else load) change of any driven trace that settles before the next
    change comparable to it (:func:`_complete`), and J follows from (9); with neither,
    τ from a first-order model fitted to a trace's whole record
    (:func:`.first_order.first_order`), else J = B·τ from a coast-down's decay.  Where
    no level settles, G and τ come from that first-order model where its trace's input
    changes :data:`RICH` times or more (a sweep, a random sequence), else from a
    first-order rise fitted to the largest voltage step's response.
    """
    toml = session.root / "session.toml"
    Ra, La = session.Ra.value, session.La.value
    used = {"Ra": "bench measurement",
            "La": ("assumed, not measured (La/Ra = 1 ms)" if session.La.source == LA_ASSUMED
                   else "bench measurement")}
    rows = _turning(unloaded_levels(session, held=True)[0])
    if not rows.size:  # only traces with a declared drag settle: a rougher start from them
        rows = _turning(unloaded_levels(session, with_drag=True, held=True)[0])
    extrapolated = None
    if not rows.size:  # no level settles: where the largest step's rise is heading
        mixed, rise = first_order(session), _extrapolated(session)
        if rise is not None and (mixed is None
                                 or mixed[3].voltage.change_times().size < RICH):
            mixed = None  # a step's rise, where no trace holds a richer input
        extrapolated = mixed or rise or _extrapolated(session, held=False)
        if extrapolated is None:
            raise SessionError(toml, "no steady speed to start the fit from: log a step "
                               "until the speed settles, or add a [[steady_table]]",
                               where="trace")
        G, tau_x, where_x = extrapolated[:3]
        rows = np.empty((0, 3))
    else:
        G = float(np.sum(rows[:, 0] * rows[:, 1]) / np.sum(rows[:, 0] ** 2))
    cur = rows[np.isfinite(rows[:, 2])]
    if cur.size:
        K = float(np.mean((cur[:, 0] - cur[:, 2] * Ra) / cur[:, 1]))
        B = float(np.mean(K * cur[:, 2] / cur[:, 1]))
        used["K"] = "equation (20) at the session's steady levels with a current"
        used["B"] = "equation (19) at the same levels"
    else:
        K = 1.0 / (G * (1.0 + FRICTION_SHARE))
        B = FRICTION_SHARE * K**2 / Ra
        used["K"] = (f"steady gain {G:.4g} rad/s/V of the unloaded levels, viscous friction "
                     f"assumed {100 * FRICTION_SHARE:.0f} % of the damping (no current)")
        used["B"] = "the same assumption"
    if extrapolated is not None:
        tau, used["tau"] = tau_x, where_x
        used["K"] += ("; the gain read with τ by the same first-order model" if mixed
                      else "; the gain extrapolated from the same rise") + " (no level settles)"
    else:
        tau, used["tau"] = _time_constant(session, toml)
    if used["tau"].startswith("63.2 % decay"):  # a run-down: J/B, the circuit open
        J = B * tau
        used["J"] = "B × the coast-down's time constant"
    else:
        J = j_from_tau(tau, Ra, B, K)
        used["J"] = "equation (9) from tau"
    return ClosedForm(Ra, La, K, B, J, tau, gain(Ra, K, B), used, applicable=False,
                      reason=reason)


def motor_seed(cf: ClosedForm, session, steady: dict) -> dict:
    """K, B, J and Tc to start from and centre the priors on (SI).

    K, B, J are the closed form's (or the data seed's), except where it gave a
    non-physical value (B ≤ 0 when the no-load current is within its noise, say), which
    is replaced by a rough magnitude: K from the steady speeds, B from a mechanical time
    constant ten times the electrical damping's, J from a 0.1 s time constant.  Tc is a
    third of the friction torque B·ω at the fastest steady point (``steady`` as
    :func:`pmdc_bayes.io.readings.steady_points` gives it).
    """
    K, B, J = cf.K, cf.B, cf.J
    Ra = session.Ra.value
    w = steady["w"]
    if not (np.isfinite(K) and K > 0):
        K = float(np.median(steady["v"] / w)) if w.size else 0.05
    if not (np.isfinite(B) and B > 0):
        B = 0.1 * K * K / Ra
    if not (np.isfinite(J) and J > 0):
        J = 0.1 * (B * Ra + K * K) / Ra
    w_ref = float(w.max()) if w.size else 100.0
    return {"K": float(K), "B": float(B), "J": float(J), "Tc": max(float(B) * w_ref / 3.0, 1e-9)}


def drop_seed(session) -> float:
    """Where a fitted voltage drop starts: the zero-speed intercept of the session's
    steady speed-voltage line when it has one, else 0 V."""
    if "voltage_drop" not in session.nuisances:
        return 0.0
    icpt = voltage_intercept(session)
    return float(icpt["voltage"]) if icpt and icpt["voltage"] > 0 else 0.0
