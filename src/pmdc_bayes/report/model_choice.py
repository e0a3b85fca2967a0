"""The report's "Model choice": the model search's path and the model it chose."""

from __future__ import annotations

import math

from ._doc import Paragraph, Section, Table

__all__ = ["selection_section"]


def _num(x, fmt=".1f") -> str:
    return "—" if x is None or not math.isfinite(x) else format(x, fmt)


def selection_section(ctx) -> Section | None:
    """The search of ``fit --compare`` (or of a plain fit whose ideal model the data
    rejected): each candidate, the step that made it, its verdict, log evidence and why
    it was kept or dropped; the chosen model; the candidates the evidence does not tell
    from it, side by side (None without a search)."""
    sel = ctx.summary.get("model_selection")
    if not sel:
        return None
    sec = Section("Model choice")
    sec.add(Paragraph(
        f"Fitted: {sel['recommended']}: {sel['reason']}. A stepwise search from "
        f"{sel.get('start', 'the ideal model')} ({sel.get('fits', '?')} fits): each candidate "
        "was fitted to the whole session at its MAP (from the usual starts and from the "
        "model it was made from, its added parameters neutral), checked for adequacy, and "
        "scored by the Laplace approximation of its log marginal likelihood (log Z; a "
        "difference is a log Bayes factor: above 3 strong, above 5 very strong). An "
        "addition was taken when it gained more than 3 over an adequate model or made a "
        "rejected one adequate; a term whose removal cost less than 1 was removed. The "
        "evidence rests on each non-ideality's prior over its physically plausible range "
        "(docs/session-format.md, [model]): a wider prior would favour the smaller model."))
    if sel.get("model"):
        sec.add(Paragraph("The run's copy of session.toml declares the chosen model: "
                          + ", ".join(f"{k} = {v}" for k, v in sel["model"].items())
                          + (" (Coulomb friction)" if sel.get("friction") == "coulomb" else "")
                          + "; 'pmdc-bayes report' and a refit of the copy use it."))
    rows = tuple((r["name"] + (" (chosen)" if r.get("decision") == "chosen" else ""),
                  r.get("move", "—"), str(r["n_params"]), r["verdict"],
                  _num(r.get("log_evidence")), _num(r.get("delta_log_evidence"), "+.1f"),
                  r.get("why") or "; ".join(r["failures"]) or "—")
                 for r in sel["candidates"])
    sec.add(Table("The search's path", ("candidate", "step", "parameters", "verdict", "log Z",
                                        "Δ log Z", "why kept or dropped"), rows,
                  "Δ log Z: against the model the step started from."))
    side = _side_by_side(sel)
    if side is not None:
        sec.add(side)
    return sec


def _side_by_side(sel) -> Table | None:
    """The chosen model's values beside those of the adequate candidates the evidence
    does not tell from it (log Z within 1)."""
    by = {r["name"]: r for r in sel["candidates"]}
    rows = [by[n] for n in [sel["recommended"], *sel.get("equivalent", ())]
            if n in by and by[n].get("values")]
    if len(rows) < 2:
        return None
    shared = [p for p in rows[0]["values"] if all(p in r["values"] for r in rows)]
    body = tuple((p, *(f"{r['values'][p][0]:.4g} ± {r['values'][p][1]:.2g}" for r in rows))
                 for p in shared)
    return Table("Equally supported models, side by side", ("parameter",
                 *(r["name"] for r in rows)), body,
                 "Both adequate, their log evidence within 1: the data do not tell them "
                 "apart; MAP ± Laplace sd (SI).")
