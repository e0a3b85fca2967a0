"""Read named numeric columns from a CSV file, with errors that name the file and line.

Only the session loader uses this.  Line numbers are 1-based physical lines of the
file, so the header is line 1 and the first data row is usually line 2.  The column
separator is found from the header (comma, semicolon or tab); with a semicolon or a
tab, a decimal comma ("1,25") is read as a decimal point, as spreadsheets in many
locales write it.

Files as loggers and oscilloscopes write them are read as they are: lines of text
before the header (a logger's name, a date: the header is the first line naming every
column asked for), a row of units right under the header (``s,rpm,A`` or ``(ms),(V)``:
no number in any column read) and lines of text after the last sample (``End of log``)
are passed over, and a header written as a comment (``# t,speed,ia``, NumPy's
``savetxt``) is read as the header; a time column may hold a logger's time stamps
(``12:00:01.250``); a reading a logger missed (an empty cell, ``NaN``, ``-nan``, ``NA``, ``N/A``,
``#N/A``, ``null``, ``-``) is NaN in the columns the caller allows it in; anything else
that is not a number is an error naming its line.
"""

from __future__ import annotations

import csv
from array import array
from pathlib import Path

import numpy as np

from .._errors import SessionError
from ._cells import MISSING, parse_cell
from ._stamps import elapsed, stamp_seconds
from ._text import read_text

__all__ = ["read_columns", "MISSING"]

_SEPARATORS = {",": "commas", ";": "semicolons", "\t": "tabs"}
_SPACES = " "  # columns separated by runs of spaces (a logger's plain text table)


def _lines(text: str):
    """The lines of ``text`` one at a time (no copy of the whole), each with its newline;
    a whole-line comment (``#``, as loggers often write first) reads as a blank line, so
    the line numbers of errors stay those of the file."""
    start, n = 0, len(text)
    while start < n:
        end = text.find("\n", start)
        end = n if end < 0 else end + 1
        line = text[start:end]
        yield "\n" if line.lstrip().startswith("#") else line
        start = end


def _separator(header_line: str) -> str:
    """The separator the header uses: the candidate that splits it most; runs of spaces
    where the header has none of them but several words."""
    counts = {sep: header_line.count(sep) for sep in _SEPARATORS}
    best = max(counts, key=counts.get)
    if counts[best]:
        return best
    return _SPACES if len(header_line.split()) > 1 else ","


class _SpaceReader:
    """``csv.reader``'s iteration and ``line_num`` for columns separated by spaces."""

    def __init__(self, lines):
        self._lines, self.line_num = lines, 0

    def __iter__(self):
        return self

    def __next__(self) -> list[str]:
        line = next(self._lines)
        self.line_num += 1
        return line.split()


def _check_header(path: Path, header: list[str], sep: str, line: int) -> None:
    names = [h for h in header if h]
    dup = sorted({h for h in names if names.count(h) > 1})
    if dup:
        raise SessionError(path, f"the header names {', '.join(map(repr, dup))} more than "
                           "once; give every column its own name", where=f"line {line}")
    if len(header) == 1 and len(header[0].split()) > 1:
        raise SessionError(path, f"the header {header[0]!r} has no comma, semicolon or tab; "
                           "separate the columns with commas", where=f"line {line}")


def read_columns(path: Path, wanted: dict[str, str], *, asked_by: str,
                 stamps: tuple[str, float] | None = None,
                 missing: frozenset = frozenset()) -> tuple[dict, list]:
    """Read the columns ``wanted`` (role -> header name) of a CSV file as float arrays.

    Parameters
    ----------
    path : the CSV file: a header naming the columns (after a preamble, perhaps), one
        row per sample.
    wanted : maps a role (``"time"``, ``"speed"``, ...) to the header name to read.
    asked_by : where the names come from (e.g. ``"session.toml trace['x'].columns"``),
        quoted in the error when a name is not in the header.
    stamps : ``(role, seconds per unit)``: a column that may hold a logger's time
        stamps (``12:00:01.250``, ``2026-11-26 12:00:01,250``, ``01:02.5``) instead of
        numbers, read as the time since its first row, in its unit.
    missing : the roles whose cells may be a missed reading (:data:`MISSING`), read as
        NaN.

    Returns
    -------
    columns : dict mapping each role to a 1-D float array, in file order.
    lines : the 1-based file line of each row, for later error messages.

    Raises
    ------
    SessionError
        If the file cannot be read as text, is empty, names a column twice, lacks a
        column, has a row with fewer or more fields than the header, or a cell that is
        not a finite number.
    """
    text = _uncommented_header(read_text(path, "CSV file"), wanted)
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise SessionError(path, "a NUL byte (binary data) in the text; export the CSV file "
                           "again as text", where=f"line {line}")
    first = next((ln for ln in _lines(text) if ln.strip()), None)
    if first is None:
        raise SessionError(path, "the file is empty; its first line must be a header "
                           "naming the columns, followed by one row per sample")
    at, first = _header_line(text, wanted, first)
    sep = _separator(first)
    reader = (_SpaceReader(_lines(text)) if sep == _SPACES
              else csv.reader(_lines(text), delimiter=sep))
    try:
        for _ in range(at):  # a preamble before the header
            next(reader)
        return _read_rows(path, reader, sep, wanted, asked_by, stamps, missing)
    except csv.Error as exc:
        raise SessionError(path, f"not readable as CSV ({exc}); check the quoting and that "
                           "each cell is a short number", where=f"line {reader.line_num}") \
            from None


PREAMBLE = 100  # lines searched for a header after a first line that is not one


def _names(line: str) -> set[str]:
    """The names a header line gives its columns."""
    sep = _separator(line)
    cells = line.split() if sep == _SPACES else line.rstrip("\r\n").split(sep)
    return {cell.strip().strip('"') for cell in cells}


def _uncommented_header(text: str, wanted: dict[str, str]) -> str:
    """``text`` with a header written as a comment (``# t,speed,ia``, as NumPy's
    ``savetxt`` writes one) read as the header, where no other of the first
    :data:`PREAMBLE` lines names every column wanted; the line numbers unchanged."""
    want, found, start = set(wanted.values()), None, 0
    for _ in range(PREAMBLE + 1):
        if start >= len(text):
            break
        end = text.find("\n", start)
        end = len(text) if end < 0 else end + 1
        line = text[start:end]
        body = line.lstrip()
        if body.startswith("#"):
            body = body.lstrip("#").lstrip()
            if found is None and body.strip() and want <= _names(body):
                found = (start, end, body)
        elif line.strip() and want <= _names(line):
            return text
        start = end
    if found is None:
        return text
    a, b, body = found
    return text[:a] + body + text[b:]


def _header_line(text: str, wanted: dict[str, str], first: str) -> tuple[int, str]:
    """The header: the first non-blank line, or, when that does not name every column
    wanted, the first of the next :data:`PREAMBLE` lines that does (a logger's preamble
    above it); the count of lines before it and its text."""
    names = _names

    if set(wanted.values()) <= names(first):
        return _blank_lines_before(text), first
    for k, line in enumerate(_lines(text)):
        if k > PREAMBLE:
            break
        if line.strip() and set(wanted.values()) <= names(line):
            return k, line
    return _blank_lines_before(text), first


def _blank_lines_before(text: str) -> int:
    return next((k for k, ln in enumerate(_lines(text)) if ln.strip()), 0)


def _numeric(cell: str, decimal_comma: bool) -> bool:
    try:
        float(cell.replace(",", ".") if decimal_comma and "." not in cell else cell)
    except ValueError:
        return False
    return True


def _text_only(row, index, decimal_comma: bool) -> bool:
    """Whether no column read holds a number (a row of units, a closing line)."""
    cells = [row[k].strip() for k in index.values() if k < len(row)]
    return not any(_numeric(c, decimal_comma) for c in cells if c)


def _read_rows(path, reader, sep, wanted, asked_by, stamps=None, missing=frozenset()):
    header = None
    for row in reader:
        if any(cell.strip() for cell in row):
            header = [cell.strip() for cell in row]
            break
    header_line = reader.line_num
    _check_header(path, header, sep, header_line)
    index = {}
    for role, name in wanted.items():
        if name not in header:
            cols = ", ".join(repr(h) for h in header)
            raise SessionError(
                path,
                f"no column named {name!r} (the {role} column named in {asked_by}); the "
                f"header, separated by {_SEPARATORS.get(sep, 'spaces')}, has {cols}; fix "
                "the name in session.toml or in the header",
                where=f"line {header_line}",
            )
        index[role] = header.index(name)
    decimal_comma = sep != ","
    values = {role: array("d") for role in wanted}
    stamped = stamps[0] if stamps is not None and stamps[0] in wanted else None
    kinds: set[bool] = set()  # whether the stamped column's cells were time stamps
    lines: list[int] = []
    end = reader.line_num
    closing = None  # a line of text after the samples, an error if samples follow it
    for row in reader:
        start, end = end + 1, reader.line_num
        if not any(cell.strip() for cell in row):
            continue
        line = reader.line_num if all("\n" not in c for c in row) else start
        if _text_only(row, index, decimal_comma) and all("\n" not in c for c in row):
            if not lines and closing is None:
                closing = "units"  # the units under the header
                continue
            if lines:
                closing = closing if isinstance(closing, tuple) else (row, line)
                continue
        if isinstance(closing, tuple):  # text between samples: not a closing line
            row, line = closing
        if len(row) > len(header) and any(cell.strip() for cell in row[len(header):]):
            hint = (" (is the decimal separator a comma? write decimals with a point, or "
                    "separate the columns with semicolons)" if sep == "," else "")
            raise SessionError(path, f"the row has {len(row)} fields but the header has "
                               f"{len(header)}{hint}; make every row match the header",
                               where=f"line {line}")
        for role, k in index.items():
            if k >= len(row):
                raise SessionError(
                    path,
                    f"the row has {len(row)} fields but column {wanted[role]!r} is "
                    f"field {k + 1}; fill in the missing fields",
                    where=f"line {line}",
                )
            cell = row[k].strip()
            stamp = stamp_seconds(cell) if role == stamped else None
            if role == stamped:
                kinds.add(stamp is not None)
                if len(kinds) > 1:
                    raise SessionError(path, f"column {wanted[role]!r}: {cell!r} is written "
                                       "unlike the rows before it (time stamps and plain "
                                       "numbers mixed); write every time the same way",
                                       where=f"line {line}")
            values[role].append(stamp if stamp is not None
                                else parse_cell(path, line, wanted[role], cell, decimal_comma,
                                                 role in missing))
        lines.append(line)
    out = {role: np.frombuffer(v, dtype=float).copy() for role, v in values.items()}
    if True in kinds and out[stamped].size:
        out[stamped] = elapsed(out[stamped], stamps[1])
    return out, lines
