"""Numbers as shown to people: each value rounded to its uncertainty.

A row of values that share an uncertainty (an estimate, its sd, its interval, the
closed form beside it) is written on one scale, a power of 1000 chosen from the
estimate, with as many decimals as the sd's second significant digit needs; the sd
itself has two significant digits.  So K = 0.0619991 ± 3.2e-06 reads
``61.9991 ± 0.0032`` on the scale ``×1e-3``.
"""

from __future__ import annotations

import math

__all__ = ["RowFormat", "row_format", "spread_format", "value_sd", "signed", "off_by"]

SD_DIGITS = 2  # significant digits of an uncertainty


def _finite(x) -> bool:
    return x is not None and isinstance(x, int | float) and math.isfinite(x)


class RowFormat:
    """How to write the numbers of one row: ``scale`` (a power of ten, a multiple of
    3) and ``decimals`` after scaling."""

    def __init__(self, exponent: int, decimals: int | None):
        self.exponent = exponent
        self.decimals = decimals

    @property
    def suffix(self) -> str:
        """The scale to write before the unit (``"×1e-3 "``), empty at 1."""
        return "" if self.exponent == 0 else f"×1e{self.exponent} "

    def value(self, x) -> str:
        """A value on the row's scale, rounded to the row's uncertainty."""
        if not _finite(x):
            return "—"
        y = x / 10.0 ** self.exponent
        if self.decimals is None:
            return f"{y:.6g}"
        return f"{round(y, self.decimals):.{max(0, self.decimals)}f}"

    def same_scale(self, sd) -> RowFormat:
        """The format of another value of the row with an uncertainty of its own
        (a bench value beside the fit): the row's scale, the decimals of ``sd``."""
        if not (_finite(sd) and sd > 0):
            return RowFormat(self.exponent, None)
        return RowFormat(self.exponent, _decimals(sd / 10.0 ** self.exponent))

    def interval(self, lo, hi) -> str:
        """``[lo, hi]`` on the row's scale (``—`` when either end is missing)."""
        if not (_finite(lo) and _finite(hi)):
            return "—"
        return f"[{self.value(lo)}, {self.value(hi)}]"

    def sd(self, s) -> str:
        """An uncertainty on the row's scale, two significant digits."""
        if not _finite(s):
            return "—"
        y = s / 10.0 ** self.exponent
        if y == 0:
            return "0"
        decimals = _decimals(y)
        return f"{round(y, decimals):.{max(0, decimals)}f}"


def _decimals(y: float) -> int:
    """Decimals that keep two significant digits of ``y`` (negative: round to tens...);
    one fewer when the rounding carries into the next power of ten (0.996 → 1.0, not
    1.00)."""
    d = SD_DIGITS - 1 - math.floor(math.log10(abs(y)))
    if abs(round(y, d)) >= 10.0 ** (SD_DIGITS - d):
        d -= 1
    return d


def row_format(estimate, sd) -> RowFormat:
    """The format of a row whose estimate is ``estimate`` with uncertainty ``sd``
    (the smallest sd of the row); without a usable sd, six significant digits.  The
    scale is 1 for magnitudes in [0.1, 10⁴), else the power of 1000 at or below the
    larger of the estimate and the sd."""
    has_sd = _finite(sd) and sd > 0
    ref = max(abs(estimate) if _finite(estimate) else 0.0, sd if has_sd else 0.0) or 1.0
    exponent = 0 if 0.1 <= ref < 1e4 else 3 * math.floor(math.log10(ref) / 3)
    if not has_sd:
        return RowFormat(exponent, None)
    return RowFormat(exponent, _decimals(sd / 10.0 ** exponent))


def spread_format(lo, hi) -> RowFormat:
    """The format of values known to the width of an interval ``[lo, hi]`` (a 94 %
    range over posterior draws, with no sd of its own): the decimals that keep two
    significant digits of the width, scale 1 (so ``[46.284, 46.303]``, not
    ``[46.3, 46.3]``); six significant digits when the width is zero or unknown."""
    width = hi - lo if _finite(lo) and _finite(hi) else None
    if not width or width <= 0:
        return RowFormat(0, None)
    return RowFormat(0, _decimals(width))


def value_sd(value, sd) -> str:
    """``value ± sd`` on their own scale, the scale written after them
    (``61.9991 ± 0.0032 ×1e-3``): for a number in running text."""
    f = row_format(value, sd)
    text = f.value(value) if not (_finite(sd) and sd > 0) else f"{f.value(value)} ± {f.sd(sd)}"
    return f"{text} {f.suffix}".rstrip()


def signed(x: float, resolution: float = 0.0) -> str:
    """``x`` with its sign and two significant digits (+24, -1.8, +0.034; whole numbers
    from 10 up; below 0.001 one digit, +3e-05); ``0`` when ``|x|`` is below
    ``resolution``, the smallest difference that means something."""
    if not _finite(x):
        return "—"
    if x == 0 or abs(x) < resolution:
        return "0"
    return f"{x:+.0f}" if abs(x) >= 10 else f"{x:+.2g}" if abs(x) >= 1e-3 else f"{x:+.0e}"


def off_by(value, estimate, sd) -> tuple[str, str] | None:
    """How far ``value`` (the closed form) lies from ``estimate``: ``(percent, sds)`` as
    signed strings, each ``0`` below a hundredth of an sd; None when it cannot be said
    (a missing value, a zero estimate or no sd)."""
    if not all(_finite(x) for x in (value, estimate, sd)) or not estimate or sd <= 0:
        return None
    pct, nsd = 100.0 * (value - estimate) / abs(estimate), (value - estimate) / sd
    return signed(pct, 1e-2 * 100.0 * sd / abs(estimate)), signed(nsd, 1e-2)
