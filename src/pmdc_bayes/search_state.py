"""The state of a model search (:mod:`.search`): the candidates fitted so far, in the
order fitted, and the single additions it can try on a session.  Candidates are fitted
in their own compiled programs or a superset model's (:mod:`.supersets`), a step's next
candidates' programs made in background threads while the one before is fitted.

A candidate's programs are let go as soon as the search can no longer need them (a
stick-slip model's hold about half a gigabyte, and a search fits a dozen): when its
evidence falls so far below its parent's that it can be neither taken nor reported
beside the model chosen, or once its verdict is made and the search has moved on."""

from __future__ import annotations

from .candidate import Candidate
from .inference.model.coloured import COLOURED
from .inference.model.levels import level_outliers
from .inference.warmup import WarmUp
from .io.lattice import analogue_channels
from .io.session import NUISANCES, Session
from .supersets import Supersets
from .terms import LOAD, NOISE, SHARED, is_noise, label, nuisance_of, terms_of

__all__ = ["SearchState"]


class SearchState:
    """The candidates a search on ``session`` has fitted and what it can try next."""

    def __init__(self, session: Session, *, free_friction: bool, seed: int, max_fits: int,
                 say, keep_within: float = float("inf")):
        self.session, self.seed, self.max_fits, self.say = session, seed, max_fits, say
        self.keep_within = keep_within  # log Z below a parent's past which nothing is asked
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
            cand = Candidate.of(self.session, terms, parent,
                                f"{'−' if kind == 'remove' else '+'} {label(move)}")
            self.done[terms] = cand
            new.append(cand)
            out.append(cand)
        programs = [self.supersets.for_model(c.terms, c.model) for c in new]
        ahead = WarmUp.fits([c.model for c in new[1:]],
                            kernels=[p is None for p in programs[1:]], lookahead=1)
        with ahead.stopped_on_error():
            for k, (cand, superset) in enumerate(zip(new, programs, strict=True)):
                if k:
                    ahead.fitting(cand.model)
                self._fitted(cand, superset)
        ahead.stop()
        return out

    def start(self, terms) -> Candidate:
        """The model the search starts from, fitted in its own programs and checked."""
        cand = Candidate.of(self.session, terms)
        self.done[terms] = cand
        return self._fitted(cand, None, verdict=True)

    def _fitted(self, cand, superset, *, verdict: bool = False) -> Candidate:
        """``cand`` fitted (in ``superset``'s programs where given), in the record's order,
        and said; with its verdict where asked (which makes it)."""
        cand.run(self.seed, superset)
        self.order.append(cand)
        parent = cand.parent
        if parent is not None and not (
                cand.log_evidence >= parent.log_evidence - self.keep_within):
            cand.model.release()  # neither taken nor a tie: its verdict is never asked
        said = f"{cand.adequacy.verdict}, " if verdict else ""
        self.say(f"model search: {label(cand.terms)}: {said}log Z {cand.log_evidence:.1f}")
        return cand

    def let_go(self, current, *, everything: bool = False) -> None:
        """Let go of the programs of every candidate but ``current`` whose verdict is made
        or whose evidence is more than ``keep_within`` below ``current``'s; with
        ``everything`` (the search over), of all but ``current`` and of the supersets."""
        for cand in self.order:
            if cand is not current and (everything or cand.checked or not (
                    cand.log_evidence >= current.log_evidence - self.keep_within)):
                cand.model.release()
        if everything:
            self.supersets.release()

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
        noisy = {t[len(NOISE):] for t in move if is_noise(t)}
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
        if any(is_noise(t) for t in cand.terms):
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
