"""One cell of a trace's CSV as a number, or an error naming its line, column and what
the text looks like: a reading a logger missed (:data:`MISSING`), an instrument's
overrange code, a clock time, the header written again; and the decimal mark the file's
numbers use (:class:`DecimalMarks`), a point or a comma, never both."""

from __future__ import annotations

import math
import re
from pathlib import Path

from .._errors import SessionError

__all__ = ["parse_cell", "number", "DecimalMarks", "MISSING", "OVERRANGE"]

MISSING = frozenset({"", "nan", "-nan", "+nan", "na", "n/a", "#n/a", "null", "none", "-",
                     "--"})  # lower case (C's printf writes a NaN as "-nan" or "nan")
OVERRANGE = 9.9e37  # an instrument's code for a reading out of range (SCPI: 9.9E37, 9.91E37)

_CLOCK = re.compile(r"\d{1,2}:\d{2}(:\d{2}([.,]\d*)?)?")  # 12:00:01.250, as loggers stamp
_GROUPED = re.compile(r"[+-]?[1-9]\d{0,2}(,\d{3})+")  # 1,800: thousands, or 1.8 in a locale
_DOT_GROUPED = re.compile(r"[+-]?[1-9]\d{0,2}(\.\d{3})+")  # 1.014: or 1014 in a locale
_WHOLE = re.compile(r"[+-]?[1-9]\d{2,}")  # 933: a whole number of three digits at least
_MINUS = str.maketrans({"\u2212": "-",  # the minus sign some exports write for a hyphen
                        "\u221e": "inf"})  # an oscilloscope's overrange, written ∞


class DecimalMarks:
    """The decimal mark of a file's numbers, noted cell by cell as they are read: a
    point, or a comma (a spreadsheet's locale; in a comma-separated file, inside quotes).
    :meth:`check`, once the file is read, refuses a file that uses both (one of them is
    a thousands separator: 1.800 read as 1.8), or, in a comma-separated file, only
    commas that may be thousands separators (``"1,800"``), or a column whose only points
    fall before three digits (``1.014``) next to whole numbers of three digits or more
    written without one (``933``) that they meet as thousands: a locale's thousands
    point, 1014 read as 1.014."""

    def __init__(self, path: Path, separator: str):
        self.path, self.separator = path, separator
        self.point = self.comma = self.grouped = None  # (line, column, text), first seen
        self.dotted: dict = {}  # column -> (line, cell, neighbour) of a thousands point,
        # or False where the column has another decimal
        self.last: dict = {}  # column -> its last cell read: (text, value, its kind)

    def read(self, text: str, line: int, column: str) -> float:
        """``text`` as a float, its mark noted; ValueError when it is no number."""
        if "," in text and "." not in text:
            value = float(text.replace(",", "."))
            seen = (line, column, text)
            if _GROUPED.fullmatch(text):
                self.grouped = self.grouped or seen
            else:
                self.comma = self.comma or seen
            return value
        value = float(text)
        if "." in text:
            self.point = self.point or (line, column, text)
        self._note_grouping(text, value, line, column)
        return value

    def _note_grouping(self, text: str, value: float, line: int, column: str) -> None:
        """Note a cell like ``1.014`` next to a whole number like ``933`` in the same
        column (either before the other) that it meets better read as a thousand times
        its value (1014) than as written: a locale's thousands point; any other decimal
        in the column clears it."""
        if self.dotted.get(column) is False:
            return
        grouped = "." in text and _DOT_GROUPED.fullmatch(text) is not None
        if "." in text and not grouped:
            self.dotted[column] = False
            return
        kind = "grouped" if grouped else "whole" if _WHOLE.fullmatch(text) else None
        before = self.last.get(column)  # the column's cell before: (text, value, kind)
        self.last[column] = (text, value, kind)
        if (before is None or value == 0 or before[1] == 0
                or {before[2], kind} != {"grouped", "whole"}):
            return
        dotted, plain = (value, before[1]) if grouped else (before[1], value)
        if abs(math.log(abs(1000.0 * dotted / plain))) < abs(math.log(abs(dotted / plain))):
            cell, other = (text, before[0]) if grouped else (before[0], text)
            self.dotted.setdefault(column, (line, cell, other))

    def check(self) -> None:
        comma = self.comma or self.grouped
        if self.point is not None and comma is not None:
            first, later = sorted((self.point, comma))
            raise SessionError(
                self.path, f"column {later[1]!r}: {later[2]!r} is written with a decimal "
                f"{'point' if later is self.point else 'comma'} where line {first[0]}'s "
                f"{first[2]!r} has a decimal {'point' if first is self.point else 'comma'}: "
                "one of them is a thousands separator; write every number with one "
                "decimal mark and no thousands separators", where=f"line {later[0]}")
        for column, seen in self.dotted.items():
            if seen:
                line, text, other = seen
                raise SessionError(
                    self.path, f"column {column!r}: {text!r} may be a thousands separator "
                    f"({text.replace('.', '')}), next to {other!r} written without a "
                    "point; write numbers without thousands separators",
                    where=f"line {line}")
        if self.separator == "," and self.comma is None and self.grouped is not None:
            line, column, text = self.grouped
            raise SessionError(
                self.path, f"column {column!r}: {text!r} may be a thousands separator "
                f"({text.replace(',', '')}) or a decimal comma ({text.replace(',', '.')}); "
                "write numbers without thousands separators, with a decimal point",
                where=f"line {line}")


def number(text: str) -> bool:
    """Whether ``text`` reads as a number, with either decimal mark."""
    text = text.translate(_MINUS)
    try:
        float(text.replace(",", ".") if "." not in text else text)
    except ValueError:
        return False
    return True


def parse_cell(path: Path, line: int, column: str, text: str, marks: DecimalMarks,
               missing: bool = False) -> float:
    """One cell as a finite float (NaN for a missed reading, :data:`MISSING`, or an
    instrument's overrange code, :data:`OVERRANGE`, ``inf`` or ``∞``, where
    ``missing``), or a SessionError naming the line, column and text."""
    text = text.translate(_MINUS)
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
        value = marks.read(text, line, column)
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
    if missing and OVERRANGE <= abs(value):
        return math.nan  # the instrument's own mark of a reading it could not take (or inf)
    if not math.isfinite(value) or abs(value) >= OVERRANGE:
        raise SessionError(
            path,
            f"column {column!r}: {text!r} is not a finite number (an instrument's overrange "
            "code?); replace it with a measured value or remove the row",
            where=f"line {line}",
        )
    return value
