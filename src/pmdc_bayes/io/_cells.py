"""One cell of a trace's CSV as a number, or an error naming its line, column and what
the text looks like: a reading a logger missed (:data:`MISSING`), a clock time, the
header written again."""

from __future__ import annotations

import math
import re
from pathlib import Path

from .._errors import SessionError

__all__ = ["parse_cell", "MISSING"]

MISSING = frozenset({"", "nan", "-nan", "+nan", "na", "n/a", "#n/a", "null", "none", "-",
                     "--"})  # lower case (C's printf writes a NaN as "-nan" or "nan")

_CLOCK = re.compile(r"\d{1,2}:\d{2}(:\d{2}([.,]\d*)?)?")  # 12:00:01.250, as loggers stamp


def parse_cell(path: Path, line: int, column: str, text: str, decimal_comma: bool,
                missing: bool = False) -> float:
    """One cell as a finite float (NaN for a missed reading, :data:`MISSING`, where
    ``missing``), or a SessionError naming the line, column and text."""
    if missing and text.lower() in MISSING:
        return math.nan
    if not text:
        raise SessionError(path, f"column {column!r} is empty; fill in the value or remove "
                           "the row", where=f"line {line}")
    if "\n" in text:
        raise SessionError(path, f"column {column!r}: a quote (\") opened here is never "
                           "closed, so the rest of the file reads as one cell; remove the "
                           "quote", where=f"line {line}")
    try:
        value = float(text.replace(",", ".") if decimal_comma and "." not in text else text)
    except ValueError:
        if text.strip() == column:
            raise SessionError(path, f"the header ({column!r} ...) is written again here, as "
                               "when two logs are joined into one file; remove this line "
                               "(and check the time carries on after it)",
                               where=f"line {line}") from None
        clock = _CLOCK.fullmatch(text) is not None
        raise SessionError(
            path,
            f"column {column!r}: {text!r} is not a number; "
            + ("a clock time? write the time as a number (seconds since the trace began, "
               "in the unit session.toml gives)" if clock else
               "write a plain decimal number (no units, no thousands separators) or remove "
               "the row"),
            where=f"line {line}",
        ) from None
    if not math.isfinite(value):
        raise SessionError(
            path,
            f"column {column!r}: {text!r} is not a finite number; replace it with a measured "
            "value or remove the row",
            where=f"line {line}",
        )
    return value
