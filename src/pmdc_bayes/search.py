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
  The best of a stage is taken when its evidence beats the current model's by more
  than :data:`ADD_MARGIN` ("strong"), or when the data reject the current model and
  not it while its evidence is no lower.  A candidate whose added parameters the data
  cannot determine (posterior as wide as the prior) is not taken over an adequate
  model;
- **backward**: after each addition, every term the search added before it is taken
  out again when the evidence does not strongly support it (the smaller model's
  evidence within :data:`REMOVE_MARGIN`, the same margin as an addition's, of the
  larger's, and the data not rejecting it unless they reject the larger too);
- it stops when the data do not reject the model and no single addition is clearly
  better, when no step helps, or after :data:`MAX_FITS` fits.

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
from .candidate import Candidate, Fitted, Searched, nested_start
from .inference.coloured import COLOURED
from .inference.levels import level_outliers
from .inference.objective import build_model
from .inference.seed import fit_seed, refuse_reversed
from .inference.warmup import WarmUp
from .io.lattice import analogue_channels
from .io.session import NUISANCES, Session
from .supersets import Supersets
from .terms import (
    LOAD,
    NOISE,
    SHARED,
    label,
    model_table,
    nuisance_of,
    ordered,
    terms_of,
    with_terms,
)

__all__ = ["search_model", "run_search", "Fitted", "Searched", "nested_start", "ADD_MARGIN",
           "REMOVE_MARGIN", "TIE", "MAX_FITS"]

ADD_MARGIN = 3.0  # log Bayes factor an addition must gain over an adequate model ("strong")
REMOVE_MARGIN = ADD_MARGIN  # a term stays only where the evidence strongly supports it,
# as an addition is taken: a term taken early (a lag before the coloured noise it stood
# in for) is not kept on weaker evidence than would have added it to the model it ends in
TIE = 1.0  # adequate candidates this close in log evidence are reported side by side
MAX_FITS = 32  # the search's bound on MAP fits


class _Search:
    def __init__(self, session: Session, *, free_friction: bool, seed: int, max_fits: int,
                 say):
        self.session, self.seed, self.max_fits, self.say = session, seed, max_fits, say
        self.free_friction = free_friction
        self.done: dict[frozenset, Candidate] = {}
        self.order: list[Candidate] = []
        self.suspects = _suspect_traces(session)
        self.supersets = Supersets(session, terms_of(session), free_friction=free_friction)

    def fits_left(self) -> int:
        return self.max_fits - len(self.order)

    def evaluate(self, moves, parent, kind) -> list[Candidate]:
        """The candidates ``parent.terms`` changed by each move (terms to add, or to take
        out when ``kind`` is ``"remove"``), fitted in order within the bound; one fitted
        before is not fitted again.  The next candidates' programs are made meanwhile."""
        new, out = [], []
        for move in moves:
            terms = parent.terms - move if kind == "remove" else parent.terms | move
            if terms in self.done:
                out.append(self.done[terms])
                continue
            if len(new) >= self.fits_left():
                break
            s = with_terms(self.session, terms)
            cf = fit_seed(s)
            cand = Candidate(terms, s, cf, build_model(s, cf), parent,
                              f"{'−' if kind == 'remove' else '+'} {label(move)}")
            self.done[terms] = cand
            new.append(cand)
            out.append(cand)
        programs = [self.supersets.for_model(c.terms, c.model) for c in new]
        ahead = WarmUp.fits([c.model for c in new[1:]],
                            kernels=[p is None for p in programs[1:]])
        with ahead.stopped_on_error():
            for cand, superset in zip(new, programs, strict=True):
                cand.run(self.seed, superset)
                self.order.append(cand)
                self.say(f"model search: {label(cand.terms)}: log Z {cand.log_evidence:.1f}")
        ahead.stop()
        return out

    def start(self, terms) -> Candidate:
        s = with_terms(self.session, terms)
        cf = fit_seed(s)
        cand = Candidate(terms, s, cf, build_model(s, cf), None, "start")
        self.done[terms] = cand
        cand.run(self.seed)
        self.order.append(cand)
        self.say(f"model search: {label(terms)}: {cand.adequacy.verdict}, "
                 f"log Z {cand.log_evidence:.1f}")
        return cand

    # -- what to try -------------------------------------------------------------------
    def _moves_for(self, nuisance: str, trace: str | None) -> list[frozenset]:
        if nuisance == "dead_time":
            return [frozenset({SHARED}), frozenset({"dead_time"})] \
                if len(self.session.traces) > 1 else [frozenset({"dead_time"})]
        if nuisance == "unknown_load":
            return [frozenset({LOAD + (trace or t) for t in
                               ((trace,) if trace else self.suspects)})]
        if nuisance == COLOURED:
            return [frozenset({NOISE + t for t in ((trace,) if trace else
                                                   set(analogue_channels(self.session).values()))})]
        return [frozenset({nuisance})]

    def allowed(self, move, held) -> bool:
        if move & held or not move:
            return False
        if (SHARED in held and "dead_time" in move) or ("dead_time" in held and SHARED in move):
            return False
        if "coulomb" in move and not self.free_friction:
            return False
        keys = {nuisance_of(t) for t in move} - {"coulomb", COLOURED}
        noisy = {t[len(NOISE):] for t in move if t.startswith(NOISE)}
        if not noisy <= set(analogue_channels(self.session).values()):  # the move's traces
            return False
        return self.session.inert_nuisance(tuple(keys)) is None

    def proposed(self, cand) -> list[frozenset]:
        """The additions the verdict proposes, in its order; and where the candidate holds
        coloured noise on some traces, the same on every other trace with an analogue
        channel (one sensor logs them all; a trace whose correlated errors pass the
        misfit check, a quiet one or one its response fills, would otherwise be read as
        white)."""
        pairs = [(p.nuisance, p.trace) for p in cand.adequacy.proposals]
        moves = []
        for nuisance, trace in pairs:
            if nuisance in NUISANCES or nuisance == "coulomb":
                moves += self._moves_for(nuisance, trace)
        if any(t.startswith(NOISE) for t in cand.terms):
            moves += [m - cand.terms for m in self._moves_for(COLOURED, None)]
        return [m for m in dict.fromkeys(moves) if self.allowed(m, cand.terms)]

    def singles(self, cand) -> list[frozenset]:
        """Every single addition of the registry with something to act on."""
        moves = [m for n in NUISANCES + ("coulomb",) for m in self._moves_for(n, None)]
        return [m for m in dict.fromkeys(moves) if self.allowed(m, cand.terms)]


def _suspect_traces(session: Session) -> tuple[str, ...]:
    """The traces an unknown load goes on when the verdict names none: those settling off
    the line the other traces' levels draw (model-free), else every driven trace."""
    off = level_outliers(session)
    return tuple(off) if off else tuple(t.name for t in session.traces)


def _better(current, cands) -> tuple[Candidate | None, str]:
    """The candidate an addition step takes, and why (None: none): the one of highest
    evidence the data do not reject that gains enough over ``current`` (more than
    :data:`ADD_MARGIN`, or anything where ``current`` is rejected; its added parameters
    determined by the data where ``current`` is not rejected); else, where ``current`` is
    rejected, the one of highest evidence that gains more than the margin.  The
    candidates are checked for adequacy in order of evidence, only as far as the choice
    needs."""
    fallback = None
    for c in sorted((c for c in cands if c.fit.status == "converged"
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
    held = any(t.startswith(NOISE) for t in current.terms)  # noise on one sensor's others
    stages = (([m for m in proposed if held or not _noise(m)], "proposed by the verdict"),
              ([m for m in singles if not _noise(m)], "every single addition tried"),
              ([m for m in proposed if _noise(m)], "proposed by the verdict"),
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
    return all(t.startswith(NOISE) for t in move)


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
            if smaller.fit.status == "converged" and loss < REMOVE_MARGIN \
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
    refuse_reversed(session)
    if friction is not None:
        import dataclasses

        session = dataclasses.replace(session, friction=friction)
    search = _Search(session, free_friction=friction is None, seed=seed, max_fits=max_fits,
                     say=say)
    start_terms = terms_of(session)
    current = search.start(start_terms)
    current.why = "the session's model" if start_terms else "the ideal motor"
    halt = current.fit.overflows
    stop = "its MAP fit failed, so there is nothing to build on" if halt else ""
    if not halt and current.adequacy is not None and current.adequacy.faulty_data:
        halt, stop = True, ("the data hold a bad reading (its verdict's first line), "
                            "which no addition to the model mends")
    elif not halt and only_if_rejected and current.ok:
        halt, stop = True, "the data do not reject the session's model"
    for _ in range(0 if halt else max_fits):  # each step fits a new candidate or stops
        if search.fits_left() <= 0:
            stop = f"the bound of {max_fits} fits was reached"
            break
        best, why, source, tried = _forward(search, current)
        for c in tried:
            if c is not best and not c.why:
                c.why = _dropped(current, c, best)
        if best is None:
            stop = ("the data do not reject it and no single addition is clearly better"
                    if current.ok else "no addition improves on it")
            break
        best.why = f"{why} ({source})"
        current = _removals(search, best, start_terms, best.terms - best.parent.terms)
    stop = stop or f"the bound of {max_fits} steps was reached"
    return Searched(_record(search, current, stop, session),
                    Fitted(current.session, current.cf, current.model, current.fit,
                           current.adequacy))


def _dropped(current, c, best) -> str:
    """Why an addition was not taken."""
    if c.fit.status != "converged":
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
    if chosen.ok:
        reason = f"the data do not reject it; the search stopped: {stop}"
    elif chosen.fit.overflows:
        reason = f"the search stopped at its start: {stop} ({chosen.fit.message})"
    else:
        reason = (f"the data reject every candidate tried; it has the highest evidence "
                  f"reached, and its diagnosis says what is still missing ({stop})")
    return {"search": True, "start": label(search.order[0].terms),
            "candidates": rows, "fits": len(search.order), "max_fits": search.max_fits,
            "recommended": label(chosen.terms), "terms": ordered(chosen.terms),
            "nuisances": list(chosen.session.nuisances),
            "loaded_traces": list(chosen.session.loaded_traces),
            "coloured_traces": list(chosen.session.coloured_traces),
            "shared_dead_time": chosen.session.shared_dead_time,
            "friction": friction, "model": table, "reason": reason,
            "equivalent": [label(c.terms) for c in ties]}
