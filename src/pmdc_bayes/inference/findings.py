"""What a check finds: the one type every adequacy check returns, and the size of a
systematic misfit that matters."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Finding", "MATERIAL_FRACTION", "sig3"]

MATERIAL_FRACTION = 0.015  # a systematic misfit that matters, as a fraction of the span


@dataclass(frozen=True)
class Finding:
    """One thing the checks found: ``severity`` is ``"fail"`` or ``"warn"``;
    ``p_value`` the check's p-value under the fitted model (None for a check that is
    not statistical: the solver's limit, a parameter at its bound)."""

    check: str
    where: str
    severity: str
    size: str
    message: str
    suggestion: str = ""
    p_value: float | None = None


def sig3(x: float) -> str:
    """``x`` to three significant figures, as a finding's message shows a figure."""
    return f"{x:.3g}"
