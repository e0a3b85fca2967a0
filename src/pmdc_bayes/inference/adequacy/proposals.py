"""What the diagnosis proposes to add to the model, as records a model search reads.

A :class:`Proposal` names a non-ideality by its key in
:data:`pmdc_bayes.io.session.NUISANCES` (or ``"coulomb"``: Coulomb friction) and, for
one fitted per trace (``unknown_load``, ``dead_time``), the trace.  A diagnosis
sentence is a :class:`Said`: the text, carrying the proposals it makes.
"""

from __future__ import annotations

from dataclasses import dataclass

from ...io.session import NUISANCES

__all__ = ["Proposal", "Said", "said", "has", "PER_TRACE", "COULOMB"]

COULOMB = "coulomb"
PER_TRACE = ("unknown_load", "dead_time", "coloured_noise")


@dataclass(frozen=True)
class Proposal:
    """One addition: ``nuisance`` a key of ``NUISANCES`` or ``"coulomb"``; ``trace`` the
    trace it belongs to for a per-trace one (None: every trace, or not per trace)."""

    nuisance: str
    trace: str | None = None

    def __post_init__(self):
        if self.nuisance not in NUISANCES + (COULOMB,):
            raise ValueError(f"proposal {self.nuisance!r}; use one of "
                             f"{NUISANCES + (COULOMB,)}")


class Said(str):
    """A diagnosis sentence and the proposals it makes (``proposals``)."""

    proposals: tuple = ()


def said(text: str, *proposals: Proposal) -> Said:
    out = Said(text)
    out.proposals = tuple(proposals)
    return out


def has(model, proposal: Proposal) -> bool:
    """Whether ``model`` already fits what ``proposal`` adds."""
    session = model.session
    if proposal.nuisance == COULOMB:
        return bool(model.coulomb)
    if proposal.nuisance == "unknown_load" and proposal.trace is not None:
        return proposal.trace in session.unknown_load_traces()
    if proposal.nuisance == "coloured_noise" and proposal.trace is not None:
        return proposal.trace in session.coloured_noise_traces()
    return proposal.nuisance in session.nuisances
