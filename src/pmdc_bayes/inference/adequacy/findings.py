"""What a check finds: the one type every adequacy check returns, the checks and
severities it names, and the size of a systematic misfit that matters."""

from __future__ import annotations

import enum
from dataclasses import asdict, dataclass

from ...io.channel import ChannelId

__all__ = ["Check", "Severity", "Verdict", "Finding", "MATERIAL_FRACTION", "NO_LOAD_SPEED", "sig3"]

MATERIAL_FRACTION = 0.015  # a systematic misfit that matters, as a fraction of the span
NO_LOAD_SPEED = "no-load speed"  # where the no-load speed's plausibility finding points


class Check(enum.StrEnum):
    """The adequacy checks, by the name a finding shows."""

    SYSTEMATIC_MISFIT = "systematic misfit"
    RESIDUAL_WHITENESS = "residual whiteness"
    NOISE_INFLATION = "noise inflation"
    INPUT_CORRELATION = "input correlation"
    OUTLYING_READING = "outlying reading"
    STEP_START = "step start"
    STEADY_MISS = "steady miss"
    BENCH_CONFLICT = "bench conflict"
    PLAUSIBILITY = "plausibility"
    PHYSICAL_BOUND = "physical bound"
    GLOBAL_SEARCH = "global search"
    SOLVER = "solver"
    KNOWN_LOAD = "known load"


class Severity(enum.StrEnum):
    """A failure rejects the model; a warning only says so."""

    FAIL = "fail"
    WARN = "warn"


class Verdict(enum.StrEnum):
    """Whether the data reject the fitted model."""

    ADEQUATE = "adequate"
    INADEQUATE = "inadequate"

    @classmethod
    def of(cls, summary: dict) -> Verdict:
        """The verdict a run's ``summary.json`` records (adequate for a run from before
        the verdict was recorded)."""
        return cls(summary.get("adequacy", {}).get("verdict", cls.ADEQUATE))


@dataclass(frozen=True)
class Finding:
    """One thing the checks found, ``where``: a channel (:class:`ChannelId`), a
    parameter's name, a trace's name or a quantity the check names; ``p_value`` the
    check's p-value under the fitted model (None for a check that is not statistical:
    the solver's limit, a parameter at its bound)."""

    check: Check
    where: ChannelId | str
    severity: Severity
    size: str
    message: str
    suggestion: str = ""
    p_value: float | None = None

    @property
    def failed(self) -> bool:
        return self.severity is Severity.FAIL

    def as_json(self) -> dict:
        return {**asdict(self), "check": str(self.check), "where": str(self.where),
                "severity": str(self.severity)}


def sig3(x: float) -> str:
    """``x`` to three significant figures, as a finding's message shows a figure."""
    return f"{x:.3g}"
