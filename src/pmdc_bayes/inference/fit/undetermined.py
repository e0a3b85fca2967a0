"""What the data can and cannot determine, read off the Laplace approximation.

Findings are plain sentences backed by numbers: the condition number of the
correlation matrix, the combinations of parameters the data fix far more tightly
than their parts (near-zero eigenvalues of the correlation matrix: the parts trade off
against one another along the rest),
parameters whose posterior is as wide as their prior, strongly correlated pairs, and
whether any trace samples the current fast enough to see La.
"""

from __future__ import annotations

import numpy as np

from ..._format import row_format
from ...io.lattice import clock_tick
from ...io.session import LA_ASSUMED
from ..model.column_levels import READINGS
from ..model.objective import SessionModel
from ..model.switch_lead import TIMING
from .joint import FitResult

__all__ = ["identifiability"]

PRIOR_DOMINATED = 0.8
STRONG_CORRELATION = 0.95
TIED_EIGENVALUE = 1e-3  # of the largest: a combination tied far more than its parts


def identifiability(model: SessionModel, fit: FitResult) -> dict:
    """Condition number, tied combinations and findings (a dict ready for JSON)."""
    names = list(fit.names)
    corr = np.asarray(fit.corr)
    sd_log = np.sqrt(np.clip(np.diag(fit.cov_log), 0.0, None))
    eig, vec = np.linalg.eigh(corr)
    cond = float(eig.max() / max(eig.min(), 1e-300))
    findings = []
    tied = []
    for k in np.argsort(eig):
        if eig[k] >= TIED_EIGENVALUE * eig.max():
            break
        # the eigenvector weighs the standardised θ_j/sd_j: the combination of θ is v/sd
        c = np.divide(vec[:, k], sd_log, out=np.zeros_like(sd_log), where=sd_log > 0)
        v = c / c[np.argmax(np.abs(c))]  # its largest part +1
        terms = [f"{v[j]:+.2f}·{_coordinate(model, names[j])}" for j in np.argsort(-np.abs(v))
                 if abs(v[j]) > 0.1]
        tied.append({"eigenvalue": float(eig[k]),
                     "direction": dict(zip(names, map(float, v), strict=True))})
        if len(terms) < 2:  # one part shown: no trade-off among parts to word
            continue
        findings.append(f"The data fix the combination {' '.join(terms)} far more tightly "
                        f"than its parts (correlation-matrix eigenvalue {eig[k]:.1e}): they "
                        "trade off against one another while it stays fixed, so each is "
                        "known only to its own sd.")
    ratio = sd_log / np.asarray(model.prior_sd)
    prior_bound = [names[j] for j in range(len(names)) if ratio[j] > PRIOR_DOMINATED]
    for j, name in enumerate(names):
        if name in prior_bound and name != "La" and model.registry[name].prior.source \
                not in (READINGS, TIMING):  # what the column's readings and rate fix
            which = ("its bench measurement" if model.registry[name].prior.source == "bench"
                     else "its prior")
            findings.append(f"{name} is determined by {which} alone: its posterior width is "
                            f"{100 * ratio[j]:.0f} % of the prior width.")
    la_finding = _la_finding(model, fit, "La" in prior_bound, ratio[names.index("La")])
    if la_finding:
        findings.append(la_finding)
    tick = _la_tick(model)
    stamps = None if "La" in prior_bound else _stamp_finding(model, fit, tick)
    if stamps:
        findings.append(stamps)
    scale = _speed_scale_finding(model.session)
    if scale:
        findings.append(scale)
    mech = [n for n in ("K", "B", "J", "Tc") if n in names]
    for a in range(len(mech)):
        for b in range(a + 1, len(mech)):
            i, j = names.index(mech[a]), names.index(mech[b])
            if abs(corr[i, j]) >= STRONG_CORRELATION:
                findings.append(
                    f"{mech[a]} and {mech[b]} are correlated {corr[i, j]:+.2f}: "
                    f"{_separate_hint(model, mech[a], mech[b])}")
    return {"condition_number": cond, "tied_combinations": tied,
            "prior_dominated": prior_bound,
            "posterior_to_prior_width": dict(zip(names, map(float, ratio), strict=True)),
            "clock_tick_s": tick, "findings": findings}


def _coordinate(model: SessionModel, name: str) -> str:
    """How a parameter enters the fit's coordinates: ``log K`` for a positive one, the
    parameter itself for one that may be zero or negative (a dead time, an offset)."""
    return f"log {name}" if model.registry[name].transform == "log" else name


def _la_prior(model: SessionModel) -> str:
    return ("its assumed prior" if model.session.La.source == LA_ASSUMED
            else "the bench prior")


def _la_finding(model: SessionModel, fit: FitResult, prior_bound: bool, ratio: float):
    tau_e = fit.values["La"] / fit.values["Ra"]
    with_current = [tr for tr in model.session.traces if tr.current is not None]
    if not prior_bound:
        if with_current:
            dt = min(tr.dt for tr in with_current)
            if dt < tau_e:
                return None
            prior = _la_prior(model)
            return (
                f"La is informed by the traces (posterior width {100 * ratio:.0f} % of "
                f"{prior}) although the fastest current sampling ({dt * 1e3:.3g} ms) is "
                f"slower than τe = {tau_e * 1e3:.3g} ms.")
        if model.session.La.source != LA_ASSUMED or not model.session.traces:
            return None
        fitted = [words for key, words in (("dead_time", "the fitted dead time"),
                                           ("speed_lag", "the fitted speed-sensor lag"))
                  if key in model.session.nuisances]
        against = (f"; here it trades against {' and '.join(fitted)}" if fitted else
                   ", and this model fits neither")
        la = row_format(fit.values["La"], fit.sd["La"])
        return (f"La = {la.value(fit.values['La'])} {la.suffix}H is read from the shape of "
                f"the speed's rise "
                f"alone (no trace logs the current and La was not measured): a dead time or "
                f"a lag of the speed sensor of about τe = La/Ra = {tau_e * 1e3:.2g} ms shapes "
                f"the rise the same way{against}. Unless the rig has neither, La is an upper "
                f"bound on the armature inductance; a logged current or a measured La "
                f"separates them.")
    if not with_current:
        return (f"La is determined by {_la_prior(model)} alone: no trace logs the current "
                f"(τe = {tau_e * 1e3:.2g} ms).")
    dt = min(tr.dt for tr in with_current)
    return (f"La is determined by {_la_prior(model)} alone: no trace samples the current fast "
            f"enough (τe = {tau_e * 1e3:.2g} ms, sampling {dt * 1e3:.3g} ms).")


def _la_tick(model: SessionModel) -> float:
    """The finest clock tick (s) among the traces La is read from (those that log the
    current, else every driven trace): 0 where one of them has exact times
    (:func:`~pmdc_bayes.io.lattice.clock_tick`)."""
    traces = model.session.traces
    traces = [tr for tr in traces if tr.current is not None] or traces
    return min((clock_tick(tr.time) for tr in traces), default=0.0)


def _stamp_finding(model: SessionModel, fit: FitResult, tick: float) -> str | None:
    """That La, fitted from traces whose rows are stamped by a clock of ``tick`` at
    their loop's own pace, is uncertain beyond its sd: each row was read up to a tick
    after (or, by another convention, about) its stamp, a shift of the response against
    its inputs that the model takes as exact and τe = La/Ra absorbs, so La may be off by
    up to Ra·tick, which no sd shows (nothing said where that is within its sd)."""
    bound = tick * fit.values["Ra"]
    if not (tick > 0.0 and bound > fit.sd["La"]):
        return None
    lag = [words for key, words in (("dead_time", "a dead time"), ("_lag", "a sensor's lag"))
           if any(n.startswith(key) or n.endswith(key) for n in fit.names)]
    also = f"; so may {' and '.join(lag)}, by up to the tick" if lag else ""
    la = row_format(fit.values["La"], bound)
    return (f"La = {la.value(fit.values['La'])} {la.suffix}H is read from times on the "
            f"scale of τe = La/Ra = {fit.values['La'] / fit.values['Ra'] * 1e3:.2g} ms, "
            f"but the traces' rows are stamped to {tick * 1e3:.3g} ms by a clock that "
            "does not set their pace: each row's time may be off by up to that tick, "
            "which the model takes as exact, so La may be off by up to Ra·tick = "
            f"{la.value(bound)} {la.suffix}H beyond its sd{also}. Stamps of a finer clock "
            "(micros()) or rows at a steady rate fix it.")


def _speed_scale_finding(session) -> str | None:
    """That nothing in the session fixes the scale of the traces' speed sensor (a tacho,
    a driver's output): a gain g on every logged speed fits as well as the true motor
    with K/g, B/g², J/g² (and Tc/g), Ra, La and the voltage equation unchanged, so K, B
    and J carry it.  What fixes it: a trace that counts its angle (an encoder), a
    measured K, B or J, a steady reading (read by another instrument, without the
    traces' gain), a known load torque that Tc or B cannot take up (one that changes
    within a trace or from trace to trace, a curved drag; with viscous friction any);
    with ``speed_gain`` fitted, its width says the same."""
    traces = session.traces
    if (not any(tr.speed_logged for tr in traces) or "speed_gain" in session.nuisances
            or any(tr.position is not None or tr.encoder_step > 0.0 for tr in traces)
            or any(name in session.bench for name in ("K", "B", "J"))
            or session.operating_points or session.steady_tables or session.step_readings):
        return None
    constants = {float(v) for tr in traces
                 for v in np.append(np.asarray(tr.load_torque.values, float), tr.drag.constant)}
    changing = any(np.ptp(np.asarray(tr.load_torque.values, float)) > 0.0 or tr.drag.curved
                   for tr in traces)
    absorbed = constants <= {0.0} or (session.friction == "coulomb" and len(constants) == 1)
    if changing or not absorbed:
        return None
    tc = " and Tc/g" if session.friction == "coulomb" else ""
    return ("The speed sensor's scale is taken as exact: an error g in it (a tacho "
            "constant a few per cent off) fits these data as well as the true motor, with "
            f"K/g, B/g² and J/g²{tc} in place of the motor's own, Ra and La unchanged, so "
            "K, B and J carry any such error. A measured K, B or J, a steady reading, a "
            "known load torque, or speeds counted by an encoder fix the scale; "
            "`--add speed-gain` fits it, as wide as its prior.")


def _separate_hint(model: SessionModel, a: str, b: str) -> str:
    kinds = {tr.kind for tr in model.session.traces}
    has_load = any(np.ptp(tr.load_torque.values) > 0 for tr in model.session.traces)
    if {a, b} & {"J"} and not has_load and not model.session.coast_downs:
        return "a load step or a coast-down would separate them."
    if {a, b} == {"B", "J"} and model.session.coast_downs and model.session.traces:
        return ("the coast-down fixes their ratio J/B; their common scale follows Ra "
                "(speed-only traces determine Ra·J and Ra·B, not each): a logged current or "
                "a tighter bench Ra would separate them.")
    if "Tc" in (a, b):
        return "steady points over a wider range of speeds would separate them."
    if not model.session.traces:
        return "a logged step response would separate them."
    return f"the traces ({', '.join(sorted(kinds))}) do not excite them independently."
