"""The superset models the search fits its candidates in
(:class:`~.inference.fit.superset.Superset`): one per *family* of candidates, made when the
first candidate of that family is fitted.

A family holds every non-ideality the search may reach from the session (its
*universe*: what the session's model declares, every single addition with something
in the session to act on, an unknown load on any driven trace; a dead time per trace
and one shared by all, which the prediction adds), with a solution of its own only
when the candidate needs it: the regime-switching solution of a current limit, a
voltage drop or a driver that opens the armature at a zero command, the solution that
sticks and slips of Coulomb friction or an unknown load.  Those solutions take several
times as long to compile and to evaluate as the smooth one, so a candidate without
them is fitted in a superset without them; the cheap terms (dead times, sensor gains
and offsets, a source resistance, a dead zone) are in every superset, and the sensors'
lags in every one without the regime-switching solution (through which a lag is
followed regime by regime, at a compile several times as long: there only when held).
A candidate no superset covers (one the session cannot seed) is fitted in its own
programs.

A superset pays only where a fit in it costs less than a compile of the candidate's own
programs (measured in ``reports/benchmarks.md``, *Model search*): each Gauss–Newton step
evaluates the Jacobian of every parameter the superset holds over every reading, so on
the 2-trace bench of 2,404 readings a candidate costs 2–5 s in a smooth superset against
about 0.5 s in its own programs once they are made (a search of 7 candidates: 65 s cold,
29 s with the compile cache filled, against 81 s and 15 s in their own programs), and on
the demo's 20,000 readings one fit in a superset holding the stick-slip solution takes
52 s against 17 s for compiling the candidate's own programs and fitting in them.  A
family is therefore used only when it needs no costly solution and the session has at
most :data:`SUPERSET_READINGS` readings; any other candidate is fitted in its own
programs, made ahead in background threads while the candidate before it is fitted and
kept in the compile cache for the next run.
"""

from __future__ import annotations

from .inference.fit.superset import Superset, extended
from .inference.model.coloured import COLOURED
from .inference.model.nuisances import dead_time_name, nuisance_specs
from .inference.model.objective import build_model
from .inference.model.seed import fit_seed
from .io.lattice import analogue_channels
from .io.session import NUISANCES, Session
from .terms import LOAD, NOISE, SHARED, nuisance_of, with_terms

__all__ = ["Supersets", "SWITCHING", "STICKING", "SUPERSET_READINGS"]

SUPERSET_READINGS = 1_000  # a session's readings above which a superset fit costs a compile
# the terms that need the regime-switching solution
SWITCHING = frozenset({"current_limit", "voltage_drop", "open_at_zero"})
STICKING = frozenset({"coulomb", "unknown_load"})  # need the solution that sticks and slips
LAGS = frozenset({"speed_lag", "current_lag"})


class Supersets:
    """The search's superset models of ``session``, by family."""

    def __init__(self, session: Session, start_terms: frozenset, *, free_friction: bool):
        self.session = session
        self.universe = _universe(session, start_terms, free_friction)
        self._made: dict[frozenset, Superset | None] = {}
        self.short = _readings(session) <= SUPERSET_READINGS

    def pays(self, terms, *, model=None) -> bool:
        """Whether a candidate of ``terms`` is fitted in its family's superset: the family
        holds no costly solution, nor does the candidate's own ``model`` where given (a
        known drag needs the stick-slip solution in every family), and the session is
        short (module docstring)."""
        held = {nuisance_of(t) for t in terms}
        costly = bool(held & (SWITCHING | STICKING)) or (model is not None
                                                         and model.coulomb_path)
        return self.short and not costly

    def family(self, terms) -> frozenset:
        """The terms of the superset a candidate of ``terms`` is fitted in."""
        out = set(self.universe)
        held = {nuisance_of(t) for t in terms}
        for path in (SWITCHING, STICKING):
            if not held & path:
                out = {t for t in out if nuisance_of(t) not in path}
        if held & SWITCHING:  # a lag followed through every regime: only when held
            out = {t for t in out if t not in LAGS or t in held}
        return frozenset(out)

    def for_model(self, terms, model) -> Superset | None:
        """The superset a candidate of ``terms`` (its own ``model``) is fitted in, made on
        first use; None when none covers it or a fit in one costs more than a compile
        (:meth:`pays`)."""
        family = self.family(terms)
        if not terms <= family or not self.pays(terms, model=model):
            return None
        if family not in self._made:
            try:
                made = Superset(self._build(family))
            except ValueError:  # a superset the session cannot seed: its own programs
                made = None
            self._made[family] = made
        made = self._made[family]
        return made if made is not None and made.covers(model) else None

    def release(self) -> None:
        """Let go of the compiled programs of every superset made."""
        for made in self._made.values():
            if made is not None:
                made.model.release()

    def _build(self, family):
        """The superset model of ``family``: a session declares one form of dead time, so
        the shared one is appended to the per-trace ones when the family holds both."""
        s = with_terms(self.session, family - {SHARED})
        model = build_model(s, fit_seed(s))
        if SHARED in family and "dead_time" in family:
            name = dead_time_name("", shared=True)
            own = nuisance_specs(with_terms(self.session, frozenset({SHARED})))
            model = extended(model, [sp for sp in own if sp.name == name])
        return model


def _universe(session: Session, start: frozenset, free_friction: bool) -> frozenset:
    """Every term a search from ``start`` may add: the session's own, each non-ideality
    with something in ``session`` to act on, an unknown load on each driven trace, a
    dead time in both forms (the families keep one) and Coulomb friction when the
    friction is searched over."""
    out = set(start)
    for key in NUISANCES:
        if key != COLOURED and session.inert_nuisance((key,)) is not None:
            continue
        if key == COLOURED:  # on every trace with an analogue channel, whichever it names
            out.update(NOISE + t for t in set(analogue_channels(session).values()))
        elif key == "unknown_load":
            out.update(LOAD + tr.name for tr in session.traces)
        elif key == "dead_time":
            out.add("dead_time")
            if len(session.traces) > 1:
                out.add(SHARED)
        else:
            out.add(key)
    if free_friction:
        out.add("coulomb")
    return frozenset(out)


def _readings(session: Session) -> int:
    """Every reading of the session's traces and coast-downs (a channel's samples)."""
    return sum(tr.n * ((tr.speed is not None and tr.speed_logged) + (tr.current is not None)
                       + (tr.position is not None))
               for tr in session.traces) + sum(len(tr.time) for tr in session.coast_downs)
