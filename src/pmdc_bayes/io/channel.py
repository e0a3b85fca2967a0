"""A channel of observations, identified by what it observes."""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["ChannelId", "STEADY", "STEP_READINGS"]

STEADY = "steady"  # the steady table's channels: ChannelId(STEADY, "speed"), ...
STEP_READINGS = "step readings"  # the step readings' 63.2 % times: ChannelId(..., "tau")


class ChannelId(NamedTuple):
    """A set of observations sharing one noise level: the trace that logged them (or
    :data:`STEADY`, :data:`STEP_READINGS` for the session's tables) and the signal
    (``"speed"``, ``"current"``, ``"position"``, ``"tau"``).  Code compares and looks up
    channels by this record; its text, ``"<trace>: <signal>"``, names a channel to
    people and in ``summary.json`` and is never read back."""

    trace: str
    signal: str

    def __str__(self) -> str:
        return f"{self.trace}: {self.signal}"
