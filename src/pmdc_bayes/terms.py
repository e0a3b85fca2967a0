"""A model of the rig as a set of terms: what the search adds and removes.

A term is one non-ideality of :data:`~pmdc_bayes.io.session.NUISANCES` (``"dead_time"``
per trace, ``"dead_time:shared"`` one for every trace, ``"unknown_load:<trace>"`` a
drag on that trace alone, ``"coloured_noise:<trace>"`` that trace's noise as AR(1), the
others by their name) or ``"coulomb"`` (Coulomb
friction).  :func:`terms_of` reads a session's model as terms, :func:`with_terms` gives
the session fitted with other terms, :func:`model_table` the ``[model]`` table (and
friction) that declares them in ``session.toml``.
"""

from __future__ import annotations

import dataclasses

from .io.lattice import analogue_channels
from .io.session import NUISANCES, Session

__all__ = ["terms_of", "with_terms", "model_table", "label", "nuisance_of", "term_of",
           "is_noise"]

SHARED = "dead_time:shared"
LOAD = "unknown_load:"
NOISE = "coloured_noise:"
PER_TRACE = (LOAD, NOISE)


def nuisance_of(term: str) -> str:
    """The ``[model]`` key a term sets (``"coulomb"`` for Coulomb friction)."""
    return term.split(":", 1)[0]


def is_noise(term: str) -> bool:
    """Whether a term is coloured noise on a trace."""
    return term.startswith(NOISE)


def term_of(nuisance: str, trace: str | None = None) -> str:
    """The term of a non-ideality (of one trace, for an unknown load)."""
    if nuisance == "unknown_load" and trace is not None:
        return LOAD + trace
    if nuisance == "coloured_noise" and trace is not None:
        return NOISE + trace
    return nuisance


def terms_of(session: Session) -> frozenset:
    """The terms of the model ``session`` declares (none: the ideal motor)."""
    out = {n for n in session.nuisances
           if n not in ("dead_time", "unknown_load", "coloured_noise")}
    if "dead_time" in session.nuisances:
        out.add(SHARED if session.shared_dead_time else "dead_time")
    out.update(LOAD + t for t in session.unknown_load_traces())
    analogue = set(analogue_channels(session).values())  # a quantised trace has none
    out.update(NOISE + t for t in session.coloured_noise_traces() if t in analogue)
    if session.friction == "coulomb":
        out.add("coulomb")
    return frozenset(out)


def _order(term: str) -> tuple:
    key = nuisance_of(term)
    rank = NUISANCES.index(key) if key in NUISANCES else len(NUISANCES)
    return rank, term


def ordered(terms) -> list[str]:
    """The terms in the registry's order (the order of :data:`NUISANCES`, then Coulomb)."""
    return sorted(terms, key=_order)


def with_terms(session: Session, terms) -> Session:
    """``session`` with the model ``terms`` declares in place of its own (a load's part
    kept for the traces the session gave one)."""
    loaded = tuple(t[len(LOAD):] for t in ordered(terms) if t.startswith(LOAD))
    coloured = tuple(t[len(NOISE):] for t in ordered(terms) if is_noise(t))
    nuisances = {nuisance_of(t) for t in terms if t != "coulomb"}
    kinds = tuple((n, k) for n, k in session.load_kinds if n in loaded)
    return dataclasses.replace(
        session, nuisances=tuple(n for n in NUISANCES if n in nuisances),
        loaded_traces=loaded, load_kinds=kinds, shared_dead_time=SHARED in terms,
        coloured_traces=coloured,
        friction="coulomb" if "coulomb" in terms else "viscous")


def model_table(session: Session, terms) -> tuple[dict, str]:
    """The ``[model]`` table declaring ``terms`` on ``session`` (a driver's current-limit
    setting kept) and the ``[motor] friction`` it needs."""
    table = {}
    for term in ordered(terms):
        key = nuisance_of(term)
        if term == SHARED:
            table[key] = "shared"
        elif term.startswith(LOAD):
            kinds = dict(session.load_kinds)
            trace = term[len(LOAD):]
            if kinds:
                table.setdefault(key, {})[trace] = kinds.get(trace, "both")
            else:
                table.setdefault(key, []).append(trace)
        elif is_noise(term):
            table.setdefault(key, []).append(term[len(NOISE):])
        elif key == "current_limit" and session.current_limit_setting is not None:
            table[key] = float(session.current_limit_setting)
        elif key != "coulomb":
            table[key] = True
    return table, "coulomb" if "coulomb" in terms else "viscous"


_WORDS = {"dead_time": "dead time", SHARED: "dead time (shared)", "coulomb": "Coulomb friction"}


def label(terms) -> str:
    """The model in words: ``"ideal"`` or its terms joined by ``+``."""
    if not terms:
        return "ideal"
    out = []
    for t in ordered(terms):
        if t.startswith(LOAD):
            out.append(f"unknown load ({t[len(LOAD):]})")
        elif is_noise(t):
            out.append(f"coloured noise ({t[len(NOISE):]})")
        else:
            out.append(_WORDS.get(t, t.replace("_", " ")))
    return " + ".join(out)
