"""The rows of a CSV file under its header, as the columns asked for: a row of units
under the header, rows whose every reading was missed, text after the last sample and a
last line cut off mid-write each taken for what they are."""

from __future__ import annotations

import re
from array import array
from collections import deque
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .._errors import SessionError
from ._cells import MISSING, DecimalMarks, number, parse_cell
from ._stamps import duration_seconds, elapsed, stamp_seconds

__all__ = ["Columns", "read_rows"]

SEPARATOR_NAMES = {",": "commas", ";": "semicolons", "\t": "tabs"}
_INTEGER = re.compile(r"[+-]?\d+")
RECENT = 20  # samples whose last field's width tells a cut value from a short one


class Columns(NamedTuple):
    """The columns read from a CSV file.

    values : role -> 1-D float array, in file order (NaN: a reading missed).
    lines : the 1-based file line of each row, for later error messages.
    skipped : the lines of rows that were left out whole: every reading missed in a file
        with a time column (no time to place them at), or a last line cut off mid-write.
    units : role -> the text of a row of units under the header, when there is one, and
        ``units_line`` its line.
    plain_stamps : whether the time column is written as plain numbers (not clock times
        or durations), and ``whole_stamps`` whether as integers (a counter's or a sample
        number's).
    """

    values: dict
    lines: list
    skipped: tuple = ()
    units: dict = {}
    units_line: int | None = None
    whole_stamps: bool = False  # the time column written as integers (no point, no unit)
    plain_stamps: bool = False  # the time column written as numbers (no clock, no unit)


class _Row(NamedTuple):
    cells: list
    line: int


def _kind(row, index, stamped, missable) -> str:
    """``"data"`` (a number, or a time stamp, in a column read), ``"missed"`` (every
    column read empty or a missed reading, in a file whose columns may miss one) or
    ``"text"`` (a row of units, a closing line)."""
    cells = {role: (row[k].strip() if k < len(row) else "") for role, k in index.items()}
    if any(number(c) or (role == stamped and stamp_seconds(c) is not None)
           for role, c in cells.items() if c):
        return "data"
    if missable and all(c.lower() in MISSING for c in cells.values()):
        return "missed"
    return "text"


def _worded(row, index, stamped) -> bool:
    """Whether a numbered field of ``row`` holds text that is neither a number, a time
    stamp nor a missed reading (an instrument's setting beside its value)."""
    for role, k in index.items():
        c = row[k].strip() if k < len(row) else ""
        if c and not number(c) and c.lower() not in MISSING \
                and not (role == stamped and stamp_seconds(c) is not None):
            return True
    return False


def _refuse_text(path, row: _Row, index, wanted, marks) -> None:
    """A line of text between samples: the error its first cell that is no number
    gives (the header written again, a clock time), or one naming the line."""
    for role, k in index.items():
        cell = row.cells[k].strip() if k < len(row.cells) else ""
        if cell and cell.lower() not in MISSING:
            parse_cell(path, row.line, wanted[role], cell, marks)
    raise SessionError(path, "a line of text between the samples; remove it",
                       where=f"line {row.line}")


def read_rows(path: Path, reader, sep: str, wanted: dict, asked_by: str, *, stamps=None,
              missing=frozenset(), cut: int | None = None,
              fields: dict | None = None) -> Columns:
    """The columns ``wanted`` (role -> header name) of the rows ``reader`` gives (a
    ``csv.reader`` at the header); ``cut`` is the line number of a last line without
    its newline (a logger stopped mid-write), if any.  With ``fields`` (role -> field
    index from 0) the file has no header: ``reader`` is at its start, ``wanted`` names
    each column for messages, and the lines of text before the first sample (a
    preamble, a header not read) are passed over."""
    header = None
    if fields is None:
        for row in reader:
            if any(cell.strip() for cell in row):
                header = [cell.strip() for cell in row]
                break
        index = _index(path, header, sep, wanted, asked_by, reader.line_num)
    else:
        index = dict(fields)
    marks = DecimalMarks(path, sep)
    values = {role: array("d") for role in wanted}
    stamped = stamps[0] if stamps is not None and stamps[0] in wanted else None
    missable = bool(missing) and set(wanted) - {"time"} <= set(missing)
    timed = "time" in wanted
    kinds: set[str] = set()  # the stamped column's cells: clock, duration or plain
    fractional = False  # a plain cell of the stamped column written other than an integer
    lines: list[int] = []
    skipped: list[int] = []
    pending: list[int] = []  # rows of missed readings, placed once a sample follows
    units: dict = {}
    units_line = None
    closing = None  # a line of text after the samples, an error if samples follow it
    end = reader.line_num
    recent: deque = deque(maxlen=RECENT)  # the last samples' cells
    kept: list = []  # the first two samples' cells
    for cells in reader:
        start, end = end + 1, reader.line_num
        if not any(cell.strip() for cell in cells) and (len(cells) < 2 or not missable):
            continue
        row = _Row(cells, reader.line_num if all("\n" not in c for c in cells) else start)
        kind = _kind(cells, index, stamped, missable)
        short = any(k >= len(cells) for k in index.values())
        if row.line == cut and (short or _cut_inside(cells, recent, index)):
            kind = "missed"  # a last line cut off mid-write: its readings are lost
        if short and timed and header and not lines and not pending and kind == "data":
            kind = "missed"  # a first line cut at its start: the logger joined mid-line
        if header is None and not lines and (kind != "data" or _worded(cells, index, stamped)):
            continue  # a headerless file's preamble: a numbered field holds a word
        if kind == "text" and all("\n" not in c for c in cells):
            if not lines and not pending and closing is None and not units:
                units = {role: (cells[k].strip() if k < len(cells) else "")
                         for role, k in index.items()}
                units_line = row.line
                continue
            if lines:
                closing = closing or row
                continue
        if kind == "missed":
            pending.append(row.line)
            if row.line != cut:
                continue
        if closing is not None:
            _refuse_text(path, closing, index, wanted, marks)
        for line in pending:  # missed readings keep their place, or, timed, are left out
            if timed:
                skipped.append(line)
            else:
                for role in wanted:
                    values[role].append(np.nan)
                lines.append(line)
        pending = []
        if kind == "missed":
            continue
        if header is not None:
            _check_width(path, row, header, sep)
        for role, k in index.items():
            if k >= len(cells) and header is None and not lines:  # the first sample
                raise SessionError(path, f"the row has {len(cells)} fields, and {wanted[role]} "
                                   f"is asked for (the {role} column in {asked_by}); give "
                                   "the column's field number, counting from 1",
                                   where=f"line {row.line}")
            if k >= len(cells):
                raise SessionError(path, f"the row has {len(cells)} fields but column "
                                   f"{wanted[role]!r} is field {k + 1}; fill in the missing "
                                   "fields", where=f"line {row.line}")
            cell = cells[k].strip()
            stamp = stamp_seconds(cell) if role == stamped else None
            if role == stamped:
                kinds.add("plain" if stamp is None else
                          "duration" if duration_seconds(cell) is not None else "clock")
                fractional = fractional or (stamp is None and not _INTEGER.fullmatch(cell))
                if len(kinds) > 1:
                    raise SessionError(path, f"column {wanted[role]!r}: {cell!r} is written "
                                       "unlike the rows before it (time stamps and plain "
                                       "numbers mixed); write every time the same way",
                                       where=f"line {row.line}")
            values[role].append(stamp if stamp is not None
                                else parse_cell(path, row.line, wanted[role], cell, marks,
                                                role in missing))
        lines.append(row.line)
        recent.append(cells)
        kept = kept + [cells] if len(kept) < 2 else kept
    marks.check()
    if timed and _cut_at_start(kept, index["time"], values["time"]):
        for role in values:
            del values[role][0]
        skipped = sorted([lines.pop(0), *skipped])
    out = {role: np.frombuffer(v, dtype=float).copy() for role, v in values.items()}
    if "clock" in kinds and out[stamped].size:
        out[stamped] = elapsed(out[stamped], stamps[1])
    elif "duration" in kinds:  # as written, in the column's unit
        out[stamped] = out[stamped] / stamps[1]
    plain = kinds == {"plain"}
    return Columns(out, lines, tuple(skipped), units, units_line, plain and not fractional,
                   plain)


def _cut_inside(cells, recent, index) -> bool:
    """Whether a last line cut off mid-write may have lost the end of a value: its last
    field is read and written with fewer digits than in every one of the samples before
    it (``25`` where the counts stood at ``17681``, ``3.1`` after ``3.1416``: after the
    decimal mark where every one has one, else in all); a value written as short before
    (a float printed without trailing zeros, a sign lost) is not cut."""
    last = len(cells) - 1
    if last not in index.values():
        return False
    fields = [r[last] for r in recent if last < len(r)]
    if not fields:
        return False
    return _digits(cells[last], fields) < min(_digits(f, fields) for f in fields)


def _digits(field: str, fields) -> int:
    """The digits of ``field`` after its decimal mark where ``fields`` all have one, else
    its length without a sign."""
    text = field.strip().lstrip("+-")
    if all("." in f or "," in f for f in fields):
        mark = max(text.rfind("."), text.rfind(","))
        return len(text) - mark - 1 if mark >= 0 else 0
    return len(text)


def _cut_at_start(kept, k, t) -> bool:
    """Whether the first sample's line was cut at its start (a logger joined mid-line:
    ``7,0,1,0.00,4.7`` where ``3207`` was written): its time, the line's first field,
    written shorter than the next sample's and more than three of the next intervals
    before it."""
    if k != 0 or len(kept) < 2 or len(t) < 4:
        return False
    steps = np.diff(np.asarray(t[:12], dtype=float))
    typical = float(np.median(steps[1:]))
    return (len(kept[0][0].strip()) < len(kept[1][0].strip())
            and typical > 0 and steps[0] > 3.0 * typical)


def _index(path, header, sep, wanted, asked_by, line) -> dict:
    """Each role's field in the header; a name asked for twice, or missing, is an
    error (other columns may share a name: they are not read)."""
    names = [h for h in header if h]
    dup = sorted({h for h in names if names.count(h) > 1 and h in wanted.values()})
    if dup:
        raise SessionError(path, f"the header names {', '.join(map(repr, dup))} more than "
                           "once; give every column its own name", where=f"line {line}")
    if len(header) == 1 and len(header[0].split()) > 1:
        raise SessionError(path, f"the header {header[0]!r} has no comma, semicolon or tab; "
                           "separate the columns with commas", where=f"line {line}")
    index = {}
    for role, name in wanted.items():
        k = column_index(header, name)
        if k is None:
            cols = ", ".join(repr(h) for h in header)
            if all(number(h) for h in header if h):
                raise SessionError(
                    path, f"no header: line {line} holds numbers ({cols}), where session.toml "
                    f"names the columns ({asked_by}); give every column as its field number "
                    "instead (columns = { time = 1, speed = 2, ... }, counting from 1), or "
                    "write a header line", where=f"line {line}")
            raise SessionError(
                path,
                f"no column named {name!r} (the {role} column named in {asked_by}); the "
                f"header, separated by {SEPARATOR_NAMES.get(sep, 'spaces')}, has {cols}; fix "
                "the name in session.toml or in the header (a file without one: give every "
                "column as its field number, counting from 1)",
                where=f"line {line}",
            )
        index[role] = k
    return index


def column_index(header: list, name: str) -> int | None:
    """The field named ``name``: exactly, or, where no field is, the one field whose
    name differs only in case (``Time`` for ``time``)."""
    if name in header:
        return header.index(name)
    folded = [k for k, h in enumerate(header) if h.casefold() == name.casefold()]
    return folded[0] if len(folded) == 1 else None


def _check_width(path, row: _Row, header, sep) -> None:
    cells = row.cells
    if len(cells) > len(header) and any(cell.strip() for cell in cells[len(header):]):
        hint = (" (is the decimal separator a comma? write decimals with a point, or "
                "separate the columns with semicolons)" if sep == "," else "")
        raise SessionError(path, f"the row has {len(cells)} fields but the header has "
                           f"{len(header)}{hint}; make every row match the header",
                           where=f"line {row.line}")
