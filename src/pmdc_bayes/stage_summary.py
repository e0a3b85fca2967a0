"""What ``summary.json`` holds of a fit's stages up to the verdict: the session as
fitted, each parameter's closed-form and MAP values, the MAP fit, the verdict, what the
data cannot determine, the closed form's consistency and each trace's residuals."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ._x64 import x64
from .io.session import Session
from .paper.consistency import consistency_checks
from .rundir import versions

if TYPE_CHECKING:
    from .candidate import Fitted

__all__ = ["stage_summary", "trace_rms", "closed_form_theta", "columns_as_levels"]


def columns_as_levels(session: Session) -> dict:
    """Per trace and input (``voltage``, ``load_torque``), the logged columns whose noise
    had them read as the levels the driver held (:mod:`.io.held_levels`): how many
    levels, the readings' noise sd (SI), and whether the column sampled a switching
    driver's output."""
    out: dict = {}
    for tr in session.traces:
        for role in ("voltage", "load_torque"):
            held = getattr(tr, role)
            if held.se is not None:
                out.setdefault(tr.name, {})[role] = {
                    "levels": int(held.values.size), "noise_sd": float(held.noise),
                    "switched": held.switched}
    return out


def _rms(x) -> float:
    x = np.asarray(x)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def trace_rms(model, theta) -> dict:
    """Per trace RMS of the residuals of each channel it logged: ``speed`` (rad/s),
    ``current`` (A), ``position`` (rad; where an encoder's count has not started, no
    sample).  A speed estimated from the angle is not a measurement and has no row."""
    out = {}
    angles = model.predict_angles(theta)
    for tr, (ia, w), a in zip(model.session.traces, model.predict(theta),
                              angles, strict=True):
        row = {}
        if tr.speed_logged:
            row["speed"] = _rms(tr.speed - w)
        if tr.current is not None:
            row["current"] = _rms(tr.current - ia)
        if tr.position is not None and a is not None:
            row["position"] = _rms(tr.position - a)
        out[tr.name] = row
    return out


def closed_form_theta(model, cf):
    return np.asarray(model.theta(dict(cf.params(), Tc=0.0)))


@x64
def stage_summary(session: Session, fitted: Fitted, ident: dict, *, holdout, seed: int) -> dict:
    """What ``summary.json`` holds of the stages up to the verdict: ``fitted`` (seed,
    model, MAP fit, verdict) of ``session`` without the traces ``holdout`` names, fitted
    from ``seed``, and ``ident``, what the data cannot determine."""
    cf, model, fit, adequacy = fitted.seed, fitted.model, fitted.fit, fitted.adequacy
    cf_theta = closed_form_theta(model, cf)
    params = {}
    for name in model.names:
        params[name] = {"unit": model.registry[name].unit,
                        "description": model.registry[name].description,
                        "block": model.registry[name].block,
                        "closed_form": cf.known().get(name) if cf.applicable else None,
                        "map": fit.values[name], "map_sd": fit.sd[name]}
        if not adequacy.ok:
            params[name]["note"] = "conditional on a model the data reject"
    summary = {
        "session": {"name": session.name, "path": str(session.root), "motor": session.motor,
                    "friction": "coulomb" if model.coulomb else "viscous",
                    "holdout": list(holdout), "nuisances": list(session.nuisances),
                    "loaded_traces": list(session.unknown_load_traces()),
                    "load_kinds": dict(session.load_kinds),
                    "coloured_traces": list(session.coloured_noise_traces()),
                    "dead_time": "shared" if session.shared_dead_time else "per_trace",
                    "gear_ratio": session.gear_ratio,
                    "rows_left_out": {tr.name: list(tr.rows_left_out)
                                      for tr in session.traces + session.coast_downs
                                      if tr.rows_left_out},
                    "columns_as_levels": columns_as_levels(session)},
        "adequacy": adequacy.as_json(),
        "seed": seed,
        "parameters": params,
        "closed_form": cf.as_json(),
        "fit": {"status": str(fit.status), "message": fit.message,
                "log_posterior": fit.log_posterior,
                "starts": fit.starts, "correlation": np.asarray(fit.corr).tolist(),
                "names": list(model.names),
                "noise_sd": {str(c): sd for c, sd in fit.noise_sd.items()}},
        "identifiability": ident,
        "consistency": consistency_checks(session, cf),
        "residuals": {"closed_form": trace_rms(model, cf_theta),
                      "map": trace_rms(model, fit.theta)},
        "versions": versions(),
    }
    if session.truth:
        summary["truth"] = {k: session.truth.get(k) for k in model.names}
    summary["diagnostics"] = {"gates_passed": None, "failures": []}
    return summary
