"""Does the session reject the fitted model?  Adequacy checks at the MAP.

Integrating each channel's noise level out is right for a correct model; for a wrong
one it turns every misfit into "noise" and the intervals stay narrow.  These checks
look at the fit from outside the likelihood, per channel:

* **systematic misfit**: the slow part of the residual (a moving average) against what
  white noise leaves in it, and its size as a fraction of the signal's span;
* **residual whiteness**: the autocorrelation of the residuals, summarised by the
  Ljung–Box statistic, a strongly negative lag-1 autocorrelation, and the
  cross-correlation of the residuals with the input (the tests of MATLAB's ``resid``);
* **noise inflation**: the fitted noise sd against the model-free estimate from the
  data (second differences, quantisation-aware; see :mod:`.noise`);
* **fit percentage**: ``100·(1 − ‖y − ŷ‖/‖y − ȳ‖)`` (MATLAB's ``compare``) of the closed
  form and of the MAP;
* **steady readings**: the miss of a steady table's, operating points' and step
  readings' speeds and currents beyond their own scatter about a model-free line
  (:mod:`.steady`);
* **bench conflict**: each bench-measured quantity's fitted value in bench sd;
* **plausibility**: derived quantities against what the session itself measured (a
  rise time, a peak current, a no-load speed).

Every statistical check has a p-value from its statistic's distribution under the
fitted model (:mod:`.calibrate`: a known distribution, or a parametric bootstrap at the
MAP through the data's sensor path).  The checks that can fail the model form one
family, corrected by Holm's step-down so that a correct model is called inadequate in
at most :data:`~.calibrate.FAMILY_LEVEL` of sessions; a check fails when the family
rejects it *and* its effect is material (a systematic part above
:data:`~.trace_checks.MATERIAL_FRACTION` of the span, a fitted noise sd above
:data:`~.trace_checks.MATERIAL_INFLATION` times the data's own, the excess over it
:data:`~.trace_checks.MATERIAL_EXCESS` of the span at least, ...).  The warnings are a
family of their own at the same level.  Any failure makes the verdict "inadequate";
:mod:`.diagnosis` says what the pattern suggests and lists the non-idealities the
model lacks (``proposals``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..._x64 import x64
from ...io.channel import ChannelId
from ..model.channels import CoastDownBlock
from ..model.coloured import channel_rho
from .calibrate import FAMILY_LEVEL, holm, logged_quantum, session_rng
from .checks import bench_checks, search_checks, step_start_test
from .diagnosis import diagnose
from .findings import Check, Finding, Verdict
from .model_checks import bound_checks, coast_start_notes, drag_checks, solver_checks
from .plausibility import plausibility_tests
from .residual_stats import fit_percent, systematic_misfit, whiteness
from .steady import steady_tests
from .trace_checks import channel_tests

__all__ = ["Finding", "Verdict", "Adequacy", "assess", "whiteness", "fit_percent",
           "systematic_misfit", "DATA_FAULTS"]

DATA_FAULTS = frozenset({Check.OUTLYING_READING})  # checks that fail the data, not the model
NOTHING_TO_ADD = ("nothing: the check that fails finds a bad reading in the data, not a part "
                  "the model lacks; mend the reading and fit again")


@dataclass(frozen=True)
class Adequacy:
    """The :class:`Verdict`, the findings behind it, the
    per-channel figures, the diagnosis in words and ``proposals``, the non-idealities
    the diagnosis proposes to add (:class:`~.diagnosis.Proposal`, most specific first);
    ``level`` is the family-wise false-alarm level of the verdict, ``tests`` every
    statistical check that ran, with its p-value and whether the family rejected it."""

    verdict: Verdict
    findings: tuple = ()
    channels: dict = field(default_factory=dict)
    bench: dict = field(default_factory=dict)
    plausibility: dict = field(default_factory=dict)
    diagnosis: tuple = ()
    proposals: tuple = ()
    level: float = FAMILY_LEVEL
    tests: tuple = ()

    @property
    def ok(self) -> bool:
        return self.verdict is Verdict.ADEQUATE

    @property
    def faulty_data(self) -> bool:
        """Whether the verdict fails on the data alone: every failing check is one of
        :data:`DATA_FAULTS`, which no addition to the model mends (where others fail
        beside it, a model far off the data can leave a lone reading far off too)."""
        return _data_fault(self.findings)

    def failures(self) -> list[Finding]:
        return [f for f in self.findings if f.failed]

    def headline(self) -> str:
        """One line for the top of the CLI's output and the report."""
        if self.ok:
            n_warn = len(self.findings)
            extra = f" ({n_warn} warning{'s' * (n_warn != 1)})" if n_warn else ""
            return f"Model adequate: the data do not reject the fitted model{extra}."
        f = self.failures()[0]
        more = f" (and {len(self.failures()) - 1} more)" if len(self.failures()) > 1 else ""
        return f"MODEL INADEQUATE: {f.where}: {f.message}{more}."

    def as_json(self) -> dict:
        return {"verdict": str(self.verdict), "family_level": self.level,
                "findings": [f.as_json() for f in self.findings],
                "diagnosis": list(self.diagnosis),
                "proposals": [asdict(p) for p in self.proposals],
                "tests": list(self.tests), "channels": self.channels,
                "bench": self.bench, "plausibility": self.plausibility}


# -- the statistics --------------------------------------------------------------------
def _data_fault(findings) -> bool:
    """Whether some check fails and every one that does is one of :data:`DATA_FAULTS`,
    or the noise inflation of a channel one of them fails (a bad reading inflates it)."""
    fails = [f for f in findings if f.failed]
    faulty = {f.where for f in fails if f.check in DATA_FAULTS}
    return bool(faulty) and all(f.check in DATA_FAULTS or (
        f.check is Check.NOISE_INFLATION and f.where in faulty) for f in fails)


def _judge(tests: list, key: str) -> tuple[list, list]:
    """Holm's correction over ``tests``: the findings of those rejected with a material
    effect (their p-values attached), and the record of every test."""
    reject = holm([t.p_value for t in tests])
    found, record = [], []
    for t, r in zip(tests, reject, strict=True):
        f = t.finding
        record.append({"family": key, "check": str(f.check), "where": str(f.where),
                       "p_value": t.p_value, "material": t.material, "rejected": bool(r)})
        if r and t.material:
            found.append(replace(f, p_value=t.p_value))
    return found, record


@x64
def assess(model, fit, closed_form=None) -> Adequacy:
    """Every adequacy check of ``fit`` (a :class:`~.fit.FitResult` of ``model``)."""

    session = model.session
    rng = session_rng(session)
    channels, findings, fails, warns = {}, [], [], []
    preds = model.predict(fit.theta)
    preds_cf = None
    if closed_form is not None and session.traces:
        theta_cf = np.asarray(model.theta(dict(closed_form.params(), Tc=0.0)))
        try:
            preds_cf = model.predict(theta_cf)  # Tc ≈ 0: the viscous motor, one program
        except (ValueError, FloatingPointError):
            preds_cf = None
    by_id = {c.id: c for c in model.channels}
    rho = channel_rho(model, fit.theta)

    def channel(cid, y, yhat, ycf, u, quantum, time=None):
        ch = by_id[cid]
        sigma = float(fit.noise_sd.get(cid, ch.s0))
        row, f, w = channel_tests(cid, y, yhat, u, ch.s0, sigma, rng, quantum=quantum,
                                  rho=float(rho[cid]), time=time, unit=ch.unit)
        row["unit"] = ch.unit
        row["fit_percent_closed_form"] = None if ycf is None else fit_percent(y, ycf)
        channels[str(cid)] = {"trace": cid.trace, "signal": cid.signal, **row}
        fails.extend(f)
        warns.extend(w)
        return sigma

    for k, tr in enumerate(session.traces):
        ia, w = preds[k]
        cf = preds_cf[k] if preds_cf is not None else (None, None)
        u = tr.voltage.at(tr.time)
        for what, y, yhat, ycf in (("speed", tr.speed if tr.speed_logged else None, w, cf[1]),
                                   ("current", tr.current, ia, cf[0])):
            if y is None:
                continue
            y, yhat = np.asarray(y), np.asarray(yhat)
            quantum = logged_quantum(y)
            cid = ChannelId(tr.name, what)
            sigma = channel(cid, y, yhat, None if ycf is None else np.asarray(ycf), u,
                            quantum, tr.time)
            # a fitted dead time takes up a step's timing
            if "dead_time" not in session.nuisances:
                fails += step_start_test(tr, what, y, yhat, by_id[cid].s0, sigma=sigma,
                                         rng=rng, quantum=quantum, rho=rho[cid])
    for cid, y, yhat in _coast_down_pairs(model, fit):
        channel(cid, y, yhat, None, None, logged_quantum(y))
    for cid, y, yhat, q in _position_pairs(model, fit):
        channel(cid, y, yhat, None, None, q)
    rows, tests, found = steady_tests(model, fit)
    channels.update(rows)
    fails += tests
    findings += found
    bench, found, tests = bench_checks(model, fit)
    findings += found
    fails += tests
    plaus, found, tests = plausibility_tests(model, fit, preds, rng)
    findings += found
    fails += tests
    failed, record = _judge(fails, "verdict")
    warned, record_w = _judge(warns, "warnings")
    findings += failed + warned
    failing = {f.where for f in findings if f.failed}
    findings = [f for f in findings if f.failed or f.where not in failing]
    findings += search_checks(fit)
    findings += solver_checks(model, fit)
    findings += drag_checks(model)
    findings += bound_checks(model, fit)
    findings = coast_start_notes(model, findings)
    findings.sort(key=lambda f: not f.failed)
    verdict = Verdict.INADEQUATE if any(f.failed for f in findings) else Verdict.ADEQUATE
    if verdict is Verdict.ADEQUATE:
        diagnosis, proposals = (), ()
    elif _data_fault(findings):
        diagnosis, proposals = (NOTHING_TO_ADD,), ()
    else:
        diagnosis, proposals = diagnose(model, fit, preds, findings)
    return Adequacy(verdict, tuple(findings), channels, bench, plaus, tuple(diagnosis),
                    tuple(proposals), FAMILY_LEVEL, tuple(record + record_w))


def _coast_down_pairs(model, fit):
    """(channel, observed, predicted) for each coast-down's speed."""
    out = []
    for block in model.blocks:
        if isinstance(block, CoastDownBlock):
            d = model.data[block.key]
            r = np.asarray(block.residuals(model, np.asarray(fit.theta), d)[0])
            for k, tr in enumerate(model.session.coast_downs):
                out.append((ChannelId(tr.name, "speed"), tr.speed, tr.speed - r[k, :tr.n]))
    return out


def _position_pairs(model, fit):
    """(channel, observed, predicted, encoder count) for each trace's angle, where
    read (from the compiled prediction the trace channels use)."""
    out = []
    angles = model.predict_angles(np.asarray(fit.theta)) if model.exp is not None else []
    for tr, angle in zip(model.session.traces, angles, strict=True):
        if tr.position is not None:
            ok = np.isfinite(tr.position)
            out.append((ChannelId(tr.name, "position"), tr.position[ok], np.asarray(angle)[ok],
                        float(tr.encoder_step or 0.0)))
    return out

