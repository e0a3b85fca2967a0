"""The rig's model found by a stepwise search over its non-idealities (``fit --compare``).

The search starts from the session's model (the ideal motor without a ``[model]``) and
moves one step at a time, every candidate fitted at its MAP and scored by its Laplace
evidence (:func:`~.selection.laplace_log_evidence`, compared on the Kass–Raftery
scale), and checked for adequacy where the choice turns on it (in order of evidence,
until one the data do not reject gains enough; a candidate below it keeps its verdict
"not checked"):

- **forward**: the changes to the model's structure the adequacy verdict proposes (its
  ``proposals``), then every other single addition of the registry (:mod:`.terms`)
  with something in the session to act on, then coloured noise (proposed, then on
  every analogue trace): noise would otherwise soak up the misfit of a missing term.
  Where the model holds coloured noise already, the same noise on its other traces
  comes with the proposed structure (one sensor logs them all).
  The best of a stage is taken when its evidence beats the current model's by more
  than :data:`ADD_MARGIN` ("strong"), or when the data reject the current model and
  not it while its evidence is no lower.  A candidate whose added parameters the data
  cannot determine (posterior as wide as the prior) is not taken over an adequate
  model;
- **backward**: after each addition, every term the search added before it is taken
  out again when the evidence does not strongly support it (the smaller model's
  evidence within :data:`REMOVE_MARGIN`, the same margin as an addition's, of the
  larger's, and the data not rejecting it unless they reject the larger too);
- it stops (:class:`~.candidate.Stop`, named in the record) when the data do not
  reject the model and no single addition is clearly better (``fit --compare``), or as
  soon as they do not reject it (a plain ``fit``: an adequacy stop, which keeps a
  search from adding what the evidence alone favours, and its cost to the steps the
  misfit asks for), when no step helps, after :data:`MAX_FITS` fits; or at its start,
  when its fit fails, when the data hold a bad reading no addition mends, or (a plain
  ``fit``) when the data do not reject it.

The model the search starts from is fitted in its own programs (most sessions end
there).  On a short session a further candidate without a costly solution (stick-slip,
regime switching) is fitted in the compiled programs of a superset model
(:mod:`.supersets`), the non-idealities it lacks switched off as data, so that trying
one costs a fit, not a compile; any other, where a fit in a superset costs more than a
compile, in its own programs (a step's candidates after its first made in background
threads while the one before is fitted).  A candidate is fitted from the usual starts and from
its parent's MAP with the added parameters at their neutral values (no dead time, no
drop, a negligible lag or load, a limit far above the currents), so a larger model
never ends below the maximum of one it contains.  Adequate candidates whose evidence
lies within :data:`TIE` of the chosen one are reported beside it: the data do not tell
them apart.
"""

from __future__ import annotations

import math

from ._x64 import x64
from .candidate import Candidate, Fitted, Searched, Stop, nested_start
from .inference.model.contradictions import refuse_contradictions
from .io.session import Session
from .search_state import SearchState
from .terms import is_noise, label, model_table, ordered, terms_of

__all__ = ["search_model", "run_search", "Fitted", "Searched", "Stop", "nested_start",
           "ADD_MARGIN", "REMOVE_MARGIN", "TIE", "MAX_FITS"]

ADD_MARGIN = 3.0  # log Bayes factor an addition must gain over an adequate model ("strong")
REMOVE_MARGIN = ADD_MARGIN  # a term stays only where the evidence strongly supports it,
# as an addition is taken: a term taken early (a lag before the coloured noise it stood
# in for) is not kept on weaker evidence than would have added it to the model it ends in
TIE = 1.0  # adequate candidates this close in log evidence are reported side by side
MAX_FITS = 32  # the search's bound on MAP fits


def _better(current, cands) -> tuple[Candidate | None, str]:
    """The candidate an addition step takes, and why (None: none): the one of highest
    evidence the data do not reject that gains enough over ``current`` (more than
    :data:`ADD_MARGIN`, or anything where ``current`` is rejected; its added parameters
    determined by the data where ``current`` is not rejected); else, where ``current`` is
    rejected, the one of highest evidence that gains more than the margin.  The
    candidates are checked for adequacy in order of evidence, only as far as the choice
    needs."""
    fallback = None
    for c in sorted((c for c in cands if c.fit.ok
                     and math.isfinite(c.log_evidence)), key=lambda c: -c.log_evidence):
        gain = c.log_evidence - current.log_evidence
        if gain <= ADD_MARGIN and (current.ok or gain < 0):
            break  # in order of evidence: none after it gains enough
        if current.ok and c.undetermined:
            continue
        if c.ok:
            return c, (f"log Z {gain:+.1f} over {label(current.terms)}" if gain > ADD_MARGIN
                       else f"the data reject {label(current.terms)}, not it "
                            f"(log Z {gain:+.1f})")
        if not current.ok and gain > ADD_MARGIN and fallback is None:
            fallback = c, f"log Z {gain:+.1f} over {label(current.terms)}"
    return fallback or (None, "")


def _forward(search, current):
    """One forward step: the candidate taken, why, where its move came from, and every
    candidate tried.  Changes to the model's structure come before coloured noise, which
    would otherwise soak up a misfit a missing term makes: first the structural additions
    the verdict proposes, then every other structural single addition (also when the data
    do not reject ``current``: an addition the evidence strongly supports is taken), and
    coloured noise (proposed, then on every trace with an analogue channel) only when no
    structural addition is taken; where the model holds coloured noise already, the same
    on its other traces (one sensor logs them all) comes with the proposed structure."""
    proposed = search.proposed(current)
    singles = [m for m in search.singles(current) if m not in proposed]
    held = any(is_noise(t) for t in current.terms)  # noise on one sensor's others
    stages = (([m for m in proposed if held or not _noise(m)], "proposed by the verdict"),
              ([m for m in singles if not _noise(m)], "every single addition tried"),
              ([m for m in proposed if not held and _noise(m)], "proposed by the verdict"),
              ([m for m in singles if _noise(m)], "every single addition tried"))
    tried = []
    for moves, source in stages:
        if moves:
            tried += search.evaluate(moves, current, "add")
            best, why = _better(current, tried)
            if best is not None:
                return best, why, source, tried
    return None, "", "", tried


def _noise(move) -> bool:
    return all(is_noise(t) for t in move)


def _removals(search, current, start_terms, last_move) -> Candidate:
    """Every term the search added before ``last_move``, and each of the terms of a move
    of several (an unknown load on every suspect trace) but its last, taken out while
    the evidence does not support it."""
    changed = True
    while changed and search.fits_left() > 0:
        changed = False
        left = current.terms & last_move  # the move's last term stays: it was the gain
        kept = left if len(left) == 1 else frozenset()
        drop = [frozenset({t}) for t in ordered(current.terms - start_terms - kept)]
        for smaller in search.evaluate(drop, current, "remove"):
            loss = current.log_evidence - smaller.log_evidence
            if smaller.fit.ok and loss < REMOVE_MARGIN \
                    and (smaller.ok or not current.ok):
                search.done[current.terms].why = (f"{smaller.move[2:]} not supported "
                                                  f"(log Z {-loss:+.1f} without it)")
                smaller.why = f"removal kept: log Z {-loss:+.1f}"
                current, changed = smaller, True
                break
    return current


def search_model(session: Session, *, friction: str | None = None, seed: int = 0,
                 max_fits: int = MAX_FITS, say=None, only_if_rejected: bool = False) -> dict:
    """The stepwise search on ``session`` (module docstring): every candidate fitted,
    its verdict, log evidence, the step that made it and why it was kept or dropped; the
    chosen model (its terms, ``[model]`` table and friction) and why; the adequate
    candidates the evidence does not tell from it (a dict ready for JSON).  ``friction``
    given, Coulomb friction is not searched over.  ``only_if_rejected``: the search ends
    at the model it starts from when the data do not reject it (a plain ``fit``, which
    searches only where the session's model is rejected; ``fit --compare`` tries every
    single addition to it as well)."""
    return run_search(session, friction=friction, seed=seed, max_fits=max_fits,
                      say=say, only_if_rejected=only_if_rejected).record


@x64
def run_search(session: Session, *, friction: str | None = None, seed: int = 0,
               max_fits: int = MAX_FITS, say=None, only_if_rejected: bool = False) -> Searched:
    """:func:`search_model`'s record and the chosen candidate's fit."""
    say = say or (lambda text: None)
    refuse_contradictions(session)
    if friction is not None:
        import dataclasses

        session = dataclasses.replace(session, friction=friction)
    search = SearchState(session, free_friction=friction is None, seed=seed, max_fits=max_fits,
                         say=say, keep_within=max(TIE, REMOVE_MARGIN))
    start_terms = terms_of(session)
    current = search.start(start_terms)
    current.why = "the session's model" if start_terms else "the ideal motor"
    stop = _first_stop(current, only_if_rejected)
    if stop is None:
        current, stop = _walk(search, current, start_terms, only_if_rejected)
    record = _record(search, current, stop, session)
    record["compare"] = not only_if_rejected
    search.let_go(current, everything=True)  # the run goes on in the chosen model's own
    return Searched(record,
                    Fitted(current.session, current.cf, current.model, current.fit,
                           current.adequacy), stop)


def _walk(search, current, start_terms, only_if_rejected) -> tuple[Candidate, Stop]:
    """The steps from ``current``: forward, then backward, until a stop (module
    docstring); the model reached and why it stopped."""
    for _ in range(search.max_fits):  # each step fits a new candidate or stops
        if search.fits_left() <= 0:
            return current, Stop.FITS
        best, why, source, tried = _forward(search, current)
        for c in tried:
            if c is not best and not c.why:
                c.why = _dropped(current, c, best)
        if best is None:  # every addition tried, or the bound reached within the step
            return current, (Stop.FITS if search.fits_left() <= 0 else
                             Stop.NOTHING_BETTER if current.ok else Stop.NO_GAIN)
        best.why = f"{why} ({source})"
        current = _removals(search, best, start_terms, best.terms - best.parent.terms)
        search.let_go(current)
        if only_if_rejected and current.ok:
            return current, Stop.ADEQUATE_REACHED
    return current, Stop.STEPS


def _first_stop(start, only_if_rejected) -> Stop | None:
    """Why the search ends at the model it starts from, if it does."""
    if start.fit.overflows:
        return Stop.FIT_FAILED
    if start.adequacy is not None and start.adequacy.faulty_data:
        return Stop.FAULTY_DATA
    if only_if_rejected and start.ok:
        return Stop.ADEQUATE_START
    return None


def _dropped(current, c, best) -> str:
    """Why an addition was not taken."""
    if not c.fit.ok:
        return "the fit did not converge"
    gain = c.log_evidence - current.log_evidence
    if current.ok and c.undetermined and gain > ADD_MARGIN:
        return f"the data cannot determine {', '.join(c.undetermined)}"
    if best is not None:
        return f"log Z {c.log_evidence - best.log_evidence:+.1f} against {label(best.terms)}"
    return f"log Z {gain:+.1f} over {label(current.terms)}: not clearly better"


def _record(search, chosen, stop, session) -> dict:
    ties = [c for c in search.order if c is not chosen and chosen.ok
            and abs(c.log_evidence - chosen.log_evidence) <= TIE and c.ok]
    rows = []
    for c in search.order:
        row = c.row()
        row["why"] = c.why
        row["decision"] = "chosen" if c is chosen else "dropped"
        rows.append(row)
    table, friction = model_table(session, chosen.terms)
    why = stop.value.format(max_fits=search.max_fits)
    if chosen.ok:
        reason = f"the data do not reject it; the search stopped: {why}"
    elif chosen.fit.overflows:
        reason = f"the search stopped at its start: {why} ({chosen.fit.message})"
    else:
        reason = (f"the data reject every candidate tried; it has the highest evidence "
                  f"reached, and its diagnosis says what is still missing ({why})")
    return {"search": True, "start": label(search.order[0].terms),
            "candidates": rows, "fits": len(search.order), "max_fits": search.max_fits,
            "recommended": label(chosen.terms), "terms": ordered(chosen.terms),
            "nuisances": list(chosen.session.nuisances),
            "loaded_traces": list(chosen.session.loaded_traces),
            "coloured_traces": list(chosen.session.coloured_traces),
            "shared_dead_time": chosen.session.shared_dead_time,
            "friction": friction, "model": table, "reason": reason,
            "stopped": stop.name.lower(),
            "equivalent": [label(c.terms) for c in ties]}
