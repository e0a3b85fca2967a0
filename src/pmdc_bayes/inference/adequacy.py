"""Does the session reject the fitted model?  Adequacy checks at the MAP.

Integrating each channel's noise level out is right for a correct model; for a wrong
one it turns every misfit into "noise" and the intervals stay narrow.  These checks
look at the fit from outside the likelihood, per channel:

* **noise inflation**: the fitted noise sd against the model-free estimate from the
  data (sample-to-sample differences, quantisation-aware; see :mod:`.noise`);
* **residual whiteness**: the autocorrelation of the normalised residuals over lags
  1..M against the ±z/√n band, summarised by the Ljung–Box statistic, and the
  cross-correlation of the residuals with the input (the tests of MATLAB's ``resid``);
* **systematic misfit**: the slow part of the residual (a moving average, less what
  white noise leaves in it) as a fraction of the signal's span: the size that decides
  whether a statistically detectable misfit matters;
* **fit percentage**: ``100·(1 − ‖y − ŷ‖/‖y − ȳ‖)`` (MATLAB's ``compare``) of the closed
  form and of the MAP;
* **bench conflict**: each bench-measured quantity's fitted value in bench sd;
* **plausibility**: derived quantities against what the session itself measured.

A channel *fails* when its misfit is both detectable (noise inflated beyond what the
model-free estimate's own uncertainty allows, or residuals far from white) and
material (a systematic part above ``MATERIAL_FRACTION`` of the span), or when its
noise is strongly anti-correlated (a differenced, quantised signal).  Any failure
makes the verdict "inadequate"; :mod:`.diagnosis` says what the pattern suggests.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.special import gammaincc

from .._x64 import x64
from .channels import CoastDownBlock

__all__ = ["Finding", "Adequacy", "assess", "whiteness", "fit_percent", "systematic_misfit"]

MATERIAL_FRACTION = 0.015  # systematic misfit that matters, as a fraction of the span
LJUNG_BOX_P = 1e-3  # residuals are "not white" below this p-value
ANTI_CORRELATION = -0.3  # lag-1 autocorrelation of a differenced, quantised signal
BENCH_FAIL_Z = 4.0  # a bench quantity this many bench sd away: the data contradict it
BENCH_WARN_Z = 3.0
STEADY_MATERIAL = 0.03  # steady readings missed by 3 % of the largest reading (rms)
RISE_RATIO = 1.5  # the model's rise time against the observed one, either way
PEAK_RATIO = 2.0  # the model's peak current against the largest logged one


@dataclass(frozen=True)
class Finding:
    """One thing the checks found: ``severity`` is ``"fail"`` or ``"warn"``."""

    check: str
    where: str
    severity: str
    size: str
    message: str
    suggestion: str = ""


@dataclass(frozen=True)
class Adequacy:
    """The verdict (``"adequate"`` or ``"inadequate"``), the findings behind it, the
    per-channel figures, and the diagnosis in words (what to add to the model)."""

    verdict: str
    findings: tuple = ()
    channels: dict = field(default_factory=dict)
    bench: dict = field(default_factory=dict)
    plausibility: dict = field(default_factory=dict)
    diagnosis: tuple = ()

    @property
    def ok(self) -> bool:
        return self.verdict == "adequate"

    def failures(self) -> list[Finding]:
        return [f for f in self.findings if f.severity == "fail"]

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
        return {"verdict": self.verdict, "findings": [asdict(f) for f in self.findings],
                "diagnosis": list(self.diagnosis), "channels": self.channels,
                "bench": self.bench, "plausibility": self.plausibility}


# -- the statistics --------------------------------------------------------------------
def whiteness(r, u=None, *, lags: int | None = None) -> dict:
    """Autocorrelation of ``r`` at lags 1..M, its 99 % band ±2.58/√n, the Ljung–Box
    statistic and p-value; and the largest |cross-correlation| with the input ``u`` at
    lags 0..M (None when ``u`` does not vary)."""
    r = np.asarray(r, float) - np.mean(r)
    n = r.size
    m = int(lags or max(1, min(25, n // 5)))
    den = float(np.dot(r, r)) or 1.0
    rho = np.array([np.dot(r[:-k], r[k:]) / den for k in range(1, m + 1)])
    q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, m + 1))))
    band = 2.58 / np.sqrt(n)
    out = {"lags": m, "rho1": float(rho[0]), "max_abs_rho": float(np.max(np.abs(rho))),
           "band": float(band), "outside_band": int(np.sum(np.abs(rho) > band)),
           "ljung_box": q, "p_value": float(gammaincc(m / 2, q / 2)),  # χ²(m) survival
           "input_xcorr": None}
    if u is not None:
        u = np.asarray(u, float) - np.mean(u)
        su = float(np.sqrt(np.dot(u, u)))
        if su > 1e-12 * max(1.0, float(np.max(np.abs(u)))):
            xc = [np.dot(r[k:], u[:n - k]) / (np.sqrt(den) * su) for k in range(0, m + 1)]
            out["input_xcorr"] = float(np.max(np.abs(xc)))
    return out


def fit_percent(y, yhat) -> float:
    """MATLAB's ``compare`` figure: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖)."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    den = float(np.linalg.norm(y - y.mean()))
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den)) if den > 0 else float("nan")


def systematic_misfit(r, noise_sd: float) -> float:
    """RMS of the slow part of ``r``: a centred moving average over ~1/40 of the record,
    less the share of white noise of sd ``noise_sd`` that survives the average."""
    r = np.asarray(r, float)
    w = int(max(5, min(r.size // 40, 200)))
    if r.size < 2 * w:
        return float(np.sqrt(max(0.0, np.mean(r * r) - noise_sd**2)))
    smooth = np.convolve(r, np.ones(w) / w, mode="valid")
    return float(np.sqrt(max(0.0, np.mean(smooth**2) - noise_sd**2 / w)))


def inflation_limit(n: int) -> float:
    """Largest ratio of fitted to model-free noise sd a correct model plausibly gives:
    the robust estimate's relative sd is about 1.2/√n, so 1 + 5 of those, and never
    below 1.5 (coloured sensor noise that second differences partly miss)."""
    return float(max(1.5, 1.0 + 5.0 * 1.2 / np.sqrt(max(n, 1))))


# -- the checks ------------------------------------------------------------------------
def _trace_channel(name, unit, y, yhat, yhat_cf, u, s0, sigma) -> tuple[dict, list]:
    r = y - yhat
    span = float(np.max(y) - np.min(y)) or float(np.max(np.abs(y))) or 1.0
    white = whiteness(r / max(sigma, 1e-300), u)
    sys_rms = systematic_misfit(r, s0)
    limit = inflation_limit(y.size)
    row = {"unit": unit, "n": int(y.size), "model_free_sd": s0, "fitted_sd": sigma,
           "inflation": sigma / s0 if s0 > 0 else float("inf"), "inflation_limit": limit,
           "whiteness": white, "systematic_rms": sys_rms,
           "systematic_fraction": sys_rms / span, "span": span,
           "fit_percent_map": fit_percent(y, yhat),
           "fit_percent_closed_form": None if yhat_cf is None else fit_percent(y, yhat_cf)}
    detectable = row["inflation"] > limit or white["p_value"] < LJUNG_BOX_P
    material = row["systematic_fraction"] > MATERIAL_FRACTION
    found = []
    size = (f"noise sd {_g(sigma)} {unit} fitted against {_g(s0)} {unit} from the data "
            f"(x{row['inflation']:.3g}); systematic misfit {100 * row['systematic_fraction']:.2g} "
            f"% of the span; fit {row['fit_percent_map']:.1f} %")
    if detectable and material:
        found.append(Finding("systematic misfit", name, "fail", size,
                             f"the model misses the data systematically "
                             f"({100 * row['systematic_fraction']:.2g} % of the span; its "
                             f"noise sd is x{row['inflation']:.3g} the data's own)"))
    elif white["rho1"] < ANTI_CORRELATION and white["p_value"] < LJUNG_BOX_P:
        found.append(Finding("residual whiteness", name, "fail",
                             f"lag-1 autocorrelation {white['rho1']:.2f}",
                             f"the noise is strongly anti-correlated (lag-1 autocorrelation "
                             f"{white['rho1']:.2f}), so it is not the white noise the "
                             "likelihood assumes"))
    elif detectable:
        found.append(Finding("residual whiteness", name, "warn", size,
                             "the residuals are not white but the misfit is small; "
                             "intervals may be somewhat optimistic"))
    return row, found


def _steady_channel(name, unit, y, yhat) -> tuple[dict, list]:
    scale = float(np.max(np.abs(y))) if y.size else 1.0
    rel = np.abs(y - yhat) / max(scale, 1e-300)
    rms = float(np.sqrt(np.mean(rel**2))) if rel.size else 0.0
    row = {"unit": unit, "n": int(y.size), "rms_miss_fraction": rms,
           "largest_miss_fraction": float(np.max(rel)) if rel.size else 0.0}
    found = []
    if rms > STEADY_MATERIAL:
        found.append(Finding("systematic misfit", name, "fail",
                             f"rms miss {100 * rms:.2g} % of the largest reading",
                             f"the model misses the steady readings by {100 * rms:.2g} % of "
                             "the largest reading (rms)"))
    return row, found


def _g(x: float) -> str:
    return f"{x:.3g}"


@x64
def assess(model, fit, closed_form=None) -> Adequacy:
    """Every adequacy check of ``fit`` (a :class:`~.fit.FitResult` of ``model``)."""
    from .checks import bench_checks, plausibility_checks, search_checks, step_start_check
    from .diagnosis import diagnose
    from .model_checks import bound_checks, drag_checks, solver_checks

    session = model.session
    channels, findings = {}, []
    preds = model.predict(fit.theta)
    preds_cf = None
    if closed_form is not None and session.traces:
        theta_cf = np.asarray(model.theta(dict(closed_form.params(), Tc=0.0)))
        try:
            preds_cf = model.predict(theta_cf)  # Tc ≈ 0: the viscous motor, one program
        except (ValueError, FloatingPointError):
            preds_cf = None
    by_name = {c.name: c for c in model.channels}
    for k, tr in enumerate(session.traces):
        ia, w = preds[k]
        cf = preds_cf[k] if preds_cf is not None else (None, None)
        u = tr.voltage.at(tr.time)
        for what, y, yhat, ycf in (("speed", tr.speed if tr.speed_logged else None, w, cf[1]),
                                   ("current", tr.current, ia, cf[0])):
            if y is None:
                continue
            name = f"{tr.name}: {what}"
            ch = by_name[name]
            row, found = _trace_channel(name, ch.unit, np.asarray(y), np.asarray(yhat),
                                        None if ycf is None else np.asarray(ycf), u,
                                        ch.s0, float(fit.noise_sd.get(name, ch.s0)))
            channels[name] = row
            findings += found
            # a fitted dead time takes up a step's timing
            if "dead_time" not in session.nuisances:
                findings += step_start_check(tr, what, np.asarray(y), np.asarray(yhat), ch.s0)
    for name, y, yhat in _coast_down_pairs(model, fit) + _position_pairs(model, fit):
        ch = by_name[name]
        row, found = _trace_channel(name, ch.unit, y, yhat, None, None, ch.s0,
                                    float(fit.noise_sd.get(name, ch.s0)))
        channels[name] = row
        findings += found
    for name, y, yhat in _steady_pairs(model, fit):
        row, found = _steady_channel(name, by_name[name].unit, y, yhat)
        channels[name] = row
        findings += found
    bench, found = bench_checks(model, fit)
    findings += found
    plaus, found = plausibility_checks(model, fit, preds)
    findings += found
    findings += search_checks(fit)
    findings += solver_checks(model, fit)
    findings += drag_checks(model)
    findings += bound_checks(model, fit)
    findings.sort(key=lambda f: f.severity != "fail")
    verdict = "inadequate" if any(f.severity == "fail" for f in findings) else "adequate"
    diagnosis = diagnose(model, fit, preds, findings) if verdict == "inadequate" else ()
    return Adequacy(verdict, tuple(findings), channels, bench, plaus, tuple(diagnosis))


def _coast_down_pairs(model, fit):
    """(channel name, observed, predicted) for each coast-down's speed."""
    out = []
    for block in model.blocks:
        if isinstance(block, CoastDownBlock):
            d = model.data[block.key]
            r = np.asarray(block.residuals(model, np.asarray(fit.theta), d)[0])
            for k, tr in enumerate(model.session.coast_downs):
                out.append((f"{tr.name}: speed", tr.speed, tr.speed - r[k, :tr.n]))
    return out


def _position_pairs(model, fit):
    """(channel name, observed, predicted) for each trace's angle, where read (from the
    compiled prediction the trace channels use)."""
    out = []
    angles = model.predict_angles(np.asarray(fit.theta)) if model.exp is not None else []
    for tr, angle in zip(model.session.traces, angles, strict=True):
        if tr.position is not None:
            ok = np.isfinite(tr.position)
            out.append((f"{tr.name}: position", tr.position[ok], np.asarray(angle)[ok]))
    return out


def _steady_pairs(model, fit):
    """(channel name, observed, predicted) for the steady speeds and currents."""
    st = model.steady
    theta = np.asarray(fit.theta)
    p = type(model.params(theta))(*(float(x) for x in model.circuit(theta)))  # on the host
    w, i = model.steady_prediction(p, st["v"], st["tl"], float(model.drop(theta)))
    out = []
    for name, obs, pred, mask in (("steady: speed", st["w"], w, st["w_mask"]),
                                  ("steady: current", st["i"], i, st["i_mask"])):
        if np.any(mask):
            out.append((name, np.asarray(obs)[mask], np.asarray(pred)[mask]))
    return out
