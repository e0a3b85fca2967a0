"""Read named numeric columns from a CSV file, with errors that name the file and line.

Only the session loader uses this.  Line numbers are 1-based physical lines of the
file, so the header is line 1 and the first data row is usually line 2.  The column
separator is found from the header (comma, semicolon, tab or runs of spaces); a decimal
comma ("1,25", quoted in a comma-separated file) is read as a decimal point, as
spreadsheets in many locales write it, where the file does not also write points
(:class:`._cells.DecimalMarks`).

Files as loggers and oscilloscopes write them are read as they are: lines of text
before the header (a logger's name, a date: the header is the first line naming every
column asked for), a row of units right under the header (``s,rpm,A`` or ``(ms),(V)``:
no number in any column read; kept, for the caller to check against the units it was
given) and lines of text after the last sample (``End of log``) are passed over, a
header written as a comment (``# t,speed,ia``, NumPy's ``savetxt``) is read as the
header, lines ended by a carriage return alone are lines, and a card's NUL padding
after the text is dropped; a time column may hold a logger's time stamps
(``12:00:01.250``, ``10:15:03 PM``); a reading a logger missed (an empty cell, ``NaN``,
``-nan``, ``NA``, ``N/A``, ``#N/A``, ``null``, ``-``, an instrument's overrange code
9.9E37) is NaN in the columns the caller allows it in, and a row that missed every
reading keeps its place (:mod:`._rows`); anything else that is not a number is an
error naming its line.

A file without a header is read by field numbers (``columns = { time = 1, ... }``):
every line whose numbered fields hold numbers is a sample, the text before the first
(an instrument's settings, a header not read) is passed over.  A log of ``name=value``
lines (:mod:`._key_values`) is read by the names.  A file that is not UTF-8 is read as
Windows-1252, whose letters only its names can hold.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

from .._errors import SessionError
from ._cells import MISSING
from ._key_values import key_value_rows
from ._rows import SEPARATOR_NAMES, Columns, read_rows
from .text import read_text

__all__ = ["read_columns", "Columns", "MISSING"]

_SEPARATORS = SEPARATOR_NAMES
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


def read_columns(path: Path, wanted: dict[str, str], *, asked_by: str,
                 stamps: tuple[str, float] | None = None,
                 missing: frozenset = frozenset()) -> Columns:
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
    :class:`~._rows.Columns`: each role's values, the file line of each row, the rows
    left out whole and a row of units under the header.

    Raises
    ------
    SessionError
        If the file cannot be read as text, is empty, names a column twice, lacks a
        column, has a row with fewer or more fields than the header, or a cell that is
        not a finite number.
    """
    text = read_text(path, "CSV file", legacy=True)
    text = text.rstrip("\x00")  # a logger's card padded with NULs
    if "\n" not in text:
        text = text.replace("\r", "\n")  # lines ended by a carriage return alone
    text = _without_monitor_stamps(text)
    positional = all(isinstance(v, int) for v in wanted.values())  # no header
    if not positional:
        text = _uncommented_header(text, wanted)
    cut = None if text.endswith("\n") else text.count("\n") + 1  # a last line unended
    if "\x00" in text:
        line = text[:text.index("\x00")].count("\n") + 1
        raise SessionError(path, "a NUL byte (binary data) in the text; export the CSV file "
                           "again as text", where=f"line {line}")
    first = next((ln for ln in _lines(text) if ln.strip()), None)
    if first is None:
        raise SessionError(path, "the file is empty; its first line must be a header "
                           "naming the columns, followed by one row per sample")
    fields = None
    if positional:
        at, sep = 0, _data_separator(text)
        fields = {role: k - 1 for role, k in wanted.items()}
        wanted = {role: f"field {k}" for role, k in wanted.items()}
    else:
        at, first = _header_line(text, wanted, first)
        if not _asked(wanted) <= _names(first):
            pairs = key_value_rows(text, wanted)
            if pairs is not None:
                return _read_key_values(path, pairs, wanted, stamps, missing, cut)
        sep = _separator(first)
    reader = (_SpaceReader(_lines(text)) if sep == _SPACES
              else csv.reader(_lines(text), delimiter=sep, skipinitialspace=True))
    try:
        for _ in range(at):  # a preamble before the header
            next(reader)
        return read_rows(path, reader, sep, wanted, asked_by, stamps=stamps,
                         missing=missing, cut=cut, fields=fields)
    except csv.Error as exc:
        raise SessionError(path, f"not readable as CSV ({exc}); check the quoting and that "
                           "each cell is a short number", where=f"line {reader.line_num}") \
            from None


def _read_key_values(path, table, wanted, stamps, missing, cut) -> Columns:
    """The columns of a log written as ``name=value`` pairs (:mod:`._key_values`), with
    the unit written after each value, if any, as a row of units on the first line."""
    fields = {role: k for k, role in enumerate(wanted)}
    read = read_rows(path, csv.reader(_lines(table.text), delimiter=","), ",", wanted, "",
                     stamps=stamps, missing=missing, cut=cut, fields=fields)
    return read._replace(units=table.units, units_line=table.units_line)


def _data_separator(text: str) -> str:
    """The separator of a file without a header: the one most of its first lines that
    hold a digit use, a tab or semicolon before a comma (a decimal comma sits beside
    semicolons and tabs, never the other way round), runs of spaces where none is."""
    votes: dict[str, int] = {}
    for k, line in enumerate(_lines(text)):
        if k > PREAMBLE:
            break
        if any(c.isdigit() for c in line):
            sep = next((s for s in ("\t", ";", ",") if s in line), _SPACES)
            votes[sep] = votes.get(sep, 0) + 1
    return max(votes, key=votes.get) if votes else ","


PREAMBLE = 100  # lines searched for a header after a first line that is not one


def _names(line: str) -> set[str]:
    """The names a header line gives its columns, case folded (a header matches the
    names asked for in any case, :func:`._rows.column_index`)."""
    sep = _separator(line)
    cells = line.split() if sep == _SPACES else line.rstrip("\r\n").split(sep)
    return {cell.strip().strip('"').casefold() for cell in cells}


def _asked(wanted: dict[str, str]) -> set[str]:
    return {name.casefold() for name in wanted.values()}


def _uncommented_header(text: str, wanted: dict[str, str]) -> str:
    """``text`` with a header written as a comment (``# t,speed,ia``, as NumPy's
    ``savetxt`` writes one) read as the header, where no other of the first
    :data:`PREAMBLE` lines names every column wanted; the line numbers unchanged."""
    want, found, start = _asked(wanted), None, 0
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

    if _asked(wanted) <= names(first):
        return _blank_lines_before(text), first
    for k, line in enumerate(_lines(text)):
        if k > PREAMBLE:
            break
        if line.strip() and _asked(wanted) <= names(line):
            return k, line
    return _blank_lines_before(text), first


_MONITOR = re.compile(r"^[0-2]?\d:[0-5]\d:[0-5]\d\.\d{3} -> ", re.MULTILINE)


def _without_monitor_stamps(text: str) -> str:
    """``text`` without the time of arrival a serial monitor writes before every line it
    shows (``14:05:11.010 -> ``, the Arduino IDE's "Show timestamp"): the computer's
    clock on receipt, not the logger's, when every non-blank line starts with one."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines or not all(_MONITOR.match(ln) for ln in lines):
        return text
    return _MONITOR.sub("", text)


def _blank_lines_before(text: str) -> int:
    return next((k for k, ln in enumerate(_lines(text)) if ln.strip()), 0)
