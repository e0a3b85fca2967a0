"""Choosing the model: the log evidence candidates are compared by, and the search's
record in words.

``pmdc-bayes fit --compare`` (and a plain ``fit`` of a session without a ``[model]``
whose ideal model the data reject) runs the stepwise search of :mod:`.search`;
:func:`laplace_log_evidence` is its score, :func:`format_selection` the lines the
terminal shows of its record (``summary.json["model_selection"]``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["laplace_log_evidence", "format_selection", "side_by_side"]


def laplace_log_evidence(model, fit) -> float:
    """The Laplace approximation of ``log p(data | candidate)``: the log-posterior at the
    MAP with every prior normalised, plus ``½·log det(2π·Σ)`` of the Laplace covariance
    in the fit's coordinates.  The constants the log-posterior leaves out are the
    channels' (the same data for every candidate) and the priors' (added here: a
    positive quantity's Gaussian prior in value renormalised over its positive values),
    so the values of candidates of one session compare: their difference is a log Bayes
    factor.  Only as good as the Laplace approximation (not at a bound); where the fit
    spans several optima of nearly equal density, the MAP's own Laplace mass plus the
    others' (``fit.log_mass``), not the width of their mixture."""
    scale = np.asarray(model.data["prior_scale"], dtype=float)
    own = getattr(fit, "cov_map", None)
    cov = np.asarray(fit.cov_log if own is None else own, dtype=float)
    if fit.overflows or not math.isfinite(fit.log_posterior):
        return float("nan")
    sign, logdet = np.linalg.slogdet(cov)
    if sign <= 0:
        return float("nan")
    positive = sum(s.prior.log_positive_mass() for s in model.registry.specs
                   if s.transform == "log")
    return float(fit.log_posterior - np.sum(np.log(scale)) - positive + 0.5 * logdet
                 + getattr(fit, "log_mass", 0.0))


def _num(x, fmt=".1f") -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, fmt)


def format_selection(sel: dict) -> list[str]:
    """The search's path as lines of text for the terminal: each candidate fitted, the
    step that made it, its verdict, log evidence and why it was kept or dropped; the
    chosen model and the candidates the evidence does not tell from it."""
    rows = sel["candidates"]
    width = max(len(r["name"]) for r in rows) + 2
    fits = sel.get("fits", len(rows))
    lines = [f"Model search from {sel.get('start', 'ideal')}: {fits} "
             f"fit{'s' * (fits != 1)} (at most {sel.get('max_fits', len(rows))})",
             f"{'candidate':<{width}}{'params':>7}  {'verdict':<13}{'log Z':>11}{'ΔZ':>9}"
             f"  why"]
    for r in rows:
        mark = "*" if r.get("decision") == "chosen" else " "
        why = r.get("why") or ", ".join(r["failures"][:2]) or "—"
        lines.append(f"{mark}{r['name']:<{width - 1}}{r['n_params']:>7}  {r['verdict']:<13}"
                     f"{_num(r.get('log_evidence')):>11}"
                     f"{_num(r.get('delta_log_evidence'), '+.1f'):>9}  {why}")
    lines.append("log Z: the Laplace approximation of each candidate's log marginal "
                 "likelihood; ΔZ against the model it was made from (a log Bayes factor).")
    if any(r["verdict"] == "not checked" for r in rows):
        lines.append("not checked: its evidence too low to be chosen, so its verdict was "
                     "not needed.")
    lines.append(f"Chosen: {sel['recommended']} — {sel['reason']}.")
    if sel.get("equivalent"):
        lines.append("The data do not tell it from: " + "; ".join(sel["equivalent"])
                     + " (adequate, log Z within 1); their values side by side:")
        lines += side_by_side(sel)
    return lines


def side_by_side(sel: dict) -> list[str]:
    """The chosen model's and its equals' values of the parameters they share, one row
    per parameter (MAP ± sd)."""
    by = {r["name"]: r for r in sel["candidates"]}
    names = [sel["recommended"], *sel.get("equivalent", ())]
    rows = [by[n] for n in names if n in by and by[n].get("values")]
    if len(rows) < 2:
        return []
    shared = [p for p in rows[0]["values"] if all(p in r["values"] for r in rows)]
    width = max([10] + [len(p) + 2 for p in shared])
    lines = [f"  [{k + 1}] {r['name']}" for k, r in enumerate(rows)]  # names in full
    lines.append("  " + f"{'':<{width}}" + "".join(f"{f'[{k + 1}]':>13}{'':<13}"
                                                for k in range(len(rows))))
    for p in shared:
        cells = "".join(f"{v:>13.4g} ± {sd:<10.2g}" for v, sd in (r["values"][p] for r in rows))
        lines.append(f"  {p:<{width}}{cells}")
    return lines
