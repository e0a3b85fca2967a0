"""Choosing the model: candidate sets of the rig's non-idealities, fitted and compared.

``pmdc-bayes fit --compare`` fits every candidate of :data:`CANDIDATES` (the ideal
motor; + dead time; + a speed-sensor lag; + voltage drop; + voltage drop with either
of the first two; + a speed sensor's lag and offset, as a tachometer has; + an unknown
load on the traces whose levels stand out; + a driver's current limit) to the same
session and checks each for adequacy at its MAP (the next candidates' programs are
compiled in background threads while one is fitted).  With MCMC, every candidate the
data do not reject is sampled and the candidates are compared by PSIS-LOO (they share
every observation: the nuisances change the prediction, not the data).

The recommendation is the simplest candidate the data do not reject (fewest
parameters).  When LOO prefers a larger adequate candidate by more than
:data:`LOO_MARGIN` and twice the difference's standard error, that one is taken and
the reason says so.  Without posteriors (``--no-mcmc``) the Laplace approximation of
each candidate's marginal likelihood (:func:`laplace_log_evidence`) stands in for LOO:
a larger adequate candidate more probable than the simplest by more than
:data:`EVIDENCE_MARGIN` (a Bayes factor of e⁵ ≈ 150) is taken.  When the data reject
every candidate, the largest is taken: its verdict and diagnosis then say what is
still missing.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._x64 import x64
from .inference.adequacy import assess
from .inference.diagnostics import loo_compare
from .inference.fit import fit_map
from .inference.levels import level_outliers
from .inference.objective import build_model
from .inference.sampling import sample_posterior
from .inference.seed import fit_seed
from .inference.warmup import WarmUp
from .io.session import Session

__all__ = ["CANDIDATES", "LOO_MARGIN", "EVIDENCE_MARGIN", "applicable", "compare_nuisances",
           "format_selection", "laplace_log_evidence"]

CANDIDATES = (
    ("ideal", ()),
    ("dead time", ("dead_time",)),
    ("speed lag", ("speed_lag",)),
    ("voltage drop", ("voltage_drop",)),
    ("dead time + voltage drop", ("dead_time", "voltage_drop")),
    ("speed lag + voltage drop", ("voltage_drop", "speed_lag")),
    ("speed lag + offset", ("speed_lag", "speed_offset")),
    ("unknown load", ("unknown_load",)),
    ("current limit", ("current_limit",)),
)
LOO_MARGIN = 4.0  # elpd units a larger candidate must gain to be preferred
EVIDENCE_MARGIN = 5.0  # log marginal likelihood a larger candidate must gain, without LOO


def laplace_log_evidence(model, fit) -> float:
    """The Laplace approximation of ``log p(data | candidate)``: the log-posterior at the
    MAP with every prior normalised, plus ``½·log det(2π·Σ)`` of the Laplace covariance
    in the fit's coordinates.  The constants the log-posterior leaves out are the
    channels' (the same data for every candidate) and the priors' (added here), so the
    values of candidates of one session compare: their difference is a log Bayes
    factor.  Only as good as the Laplace approximation (one mode, not at a bound)."""
    scale = np.asarray(model.data["prior_scale"], dtype=float)
    sign, logdet = np.linalg.slogdet(np.asarray(fit.cov_log, dtype=float))
    if sign <= 0:
        return float("nan")
    return float(fit.log_posterior - np.sum(np.log(scale)) + 0.5 * logdet)


@x64
def applicable(session, candidates=CANDIDATES) -> list:
    """The candidates whose every non-ideality has something in ``session`` to act on (no
    speed lag without a logged speed: :meth:`~pmdc_bayes.io.session.Session.inert_nuisance`)."""
    return [c for c in candidates if session.inert_nuisance(c[1]) is None]


def compare_nuisances(session: Session, *, friction: str | None = None, seed: int = 0,
                      mcmc: bool = True, progress=None, candidates=CANDIDATES,
                      max_seconds: float | None = None) -> dict:
    """Every candidate (default :data:`CANDIDATES`) fitted to ``session``: its verdict, the
    checks it fails, its MAP log-posterior and (with ``mcmc``, adequate ones only) its
    LOO, each posterior sampled for at most ``max_seconds``; the recommended candidate
    and why (a dict ready for JSON)."""
    coulomb = None if friction is None else friction == "coulomb"
    rows, idata, prepared = [], {}, []
    loaded = _suspect_traces(session)
    for name, nuisances in applicable(session, candidates):
        s = dataclasses.replace(session, nuisances=nuisances,
                                loaded_traces=loaded if "unknown_load" in nuisances else (),
                                load_kinds=())
        seed_cf = fit_seed(s)
        prepared.append((name, nuisances, s, seed_cf, build_model(s, seed_cf, coulomb=coulomb)))
    # the next candidates' programs are made while this one is fitted
    ahead = WarmUp.fits([p[-1] for p in prepared[1:]])
    with ahead.stopped_on_error():
        for name, nuisances, s, seed_cf, model in prepared:
            fit = fit_map(model, seed=seed)
            adequacy = assess(model, fit, seed_cf)
            rows.append({"name": name, "nuisances": list(nuisances),
                         "n_params": len(model.names),
                         "loaded_traces": list(s.unknown_load_traces()),
                         "verdict": adequacy.verdict, "converged": fit.status == "converged",
                         "log_posterior": float(fit.log_posterior),
                         "log_evidence": laplace_log_evidence(model, fit),
                         "failures": [f"{f.where}: {f.check}" for f in adequacy.findings
                                      if f.severity == "fail"],
                         "loo": None})
            if mcmc and adequacy.ok:
                idata[name] = sample_posterior(model, fit, seed=seed, progress=progress,
                                               max_seconds=max_seconds).idata
    if idata:
        for r in loo_compare(idata):
            next(row for row in rows if row["name"] == r["model"])["loo"] = r
    chosen, reason = _choose(rows)
    return {"candidates": rows, "recommended": chosen["name"],
            "nuisances": chosen["nuisances"], "loaded_traces": chosen["loaded_traces"],
            "reason": reason}


def _suspect_traces(session: Session) -> tuple[str, ...]:
    """The traces an unknown-load candidate loads: those settling off the line the other
    traces' levels draw (model-free), or every driven trace when the levels are too few
    to judge or none stands out."""
    off = level_outliers(session)
    return tuple(off) if off else tuple(t.name for t in session.traces)


def _choose(rows: list[dict]) -> tuple[dict, str]:
    ok = [r for r in rows if r["verdict"] == "adequate" and r["converged"]]
    if not ok:
        largest = max(rows, key=lambda r: r["n_params"])
        return largest, ("the data reject every candidate; the largest is fitted so that its "
                         "diagnosis says what is still missing")
    simplest = min(ok, key=lambda r: (r["n_params"], rows.index(r)))
    reason = f"the simplest candidate the data do not reject ({simplest['n_params']} parameters)"
    base = simplest["loo"]
    if base is None:
        return _by_evidence(ok, simplest, reason)
    # ArviZ states each difference's se against the best-ranked candidate: the larger of
    # the two stands in for the se of their difference.
    better = [r for r in ok if r["loo"] is not None and r["n_params"] > simplest["n_params"]
              and r["loo"]["elpd_loo"] - base["elpd_loo"]
              > max(LOO_MARGIN, 2 * max(r["loo"]["dse"], base["dse"]))]
    if better:
        best = max(better, key=lambda r: r["loo"]["elpd_loo"])
        gain = best["loo"]["elpd_loo"] - base["elpd_loo"]
        return best, (f"LOO prefers it to the simplest adequate candidate "
                      f"({simplest['name']!r}) by {gain:.1f} elpd")
    return simplest, reason + "; no larger candidate predicts clearly better (LOO)"


def _by_evidence(ok: list[dict], simplest: dict, reason: str) -> tuple[dict, str]:
    """Without LOO: a larger adequate candidate whose Laplace evidence beats the
    simplest's by more than :data:`EVIDENCE_MARGIN`, else the simplest."""
    base = simplest.get("log_evidence")
    if base is None or not math.isfinite(base):
        return simplest, reason
    better = [r for r in ok if r["n_params"] > simplest["n_params"]
              and math.isfinite(r.get("log_evidence", math.nan))
              and r["log_evidence"] - base > EVIDENCE_MARGIN]
    if not better:
        return simplest, reason + "; no larger candidate is clearly more probable (Laplace " \
            "evidence; LOO needs the posterior)"
    best = max(better, key=lambda r: r["log_evidence"])
    return best, (f"its Laplace evidence beats the simplest adequate candidate's "
                  f"({simplest['name']!r}) by {best['log_evidence'] - base:.1f} (a log Bayes "
                  f"factor; LOO needs the posterior)")


def format_selection(sel: dict) -> list[str]:
    """The comparison as lines of text for the terminal."""
    width = max(len(r["name"]) for r in sel["candidates"]) + 2
    lines = [f"{'candidate':<{width}}{'params':>7}  {'verdict':<11}{'log post':>12}"
             f"{'log Z':>10}{'elpd_loo':>12}{'± se':>8}  fails"]
    for r in sel["candidates"]:
        loo = r["loo"]
        elpd = "—" if loo is None else f"{loo['elpd_loo']:.1f}"
        se = "" if loo is None else f"{loo['se']:.1f}"
        z = r.get("log_evidence")
        z = "—" if z is None or z != z else f"{z:.1f}"
        fails = ", ".join(r["failures"][:3]) + (" ..." if len(r["failures"]) > 3 else "")
        lines.append(f"{r['name']:<{width}}{r['n_params']:>7}  {r['verdict']:<11}"
                     f"{r['log_posterior']:>12.1f}{z:>10}{elpd:>12}{se:>8}  {fails or '—'}")
    if all(r["loo"] is None for r in sel["candidates"]):
        lines.append("log Z: the Laplace approximation of each candidate's log marginal "
                     "likelihood; elpd_loo needs posteriors (run without --no-mcmc).")
    lines.append(f"Recommended: {sel['recommended']} — {sel['reason']}.")
    return lines
