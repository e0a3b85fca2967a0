"""A session whose readings contradict its inputs, refused before any fit."""

from __future__ import annotations

from ..._errors import SessionError
from .early_motion import moves_early
from .reversal import reversed_current, reversed_speed

__all__ = ["refuse_contradictions"]


def refuse_contradictions(session) -> None:
    """Raise :class:`~pmdc_bayes.SessionError` where a trace's motor moves before its
    voltage switches on (:func:`.early_motion.moves_early`), the session's speed turns
    against its voltage (:func:`.reversal.reversed_speed`) or a trace's current swings
    against it (:func:`.reversal.reversed_current`): no motor does that, and a fit would
    take the timing or the wiring for noise.  The late voltage is looked for first: it
    makes a current seem to fall where the voltage steps up.  Checked once per session,
    before its first fit."""
    found = moves_early(session) or reversed_speed(session) or reversed_current(session)
    if found is not None:
        raise SessionError(found.file, found.why, where=found.where)
