"""Read named numeric columns from a CSV file, with errors that name the file and line.

Only the session loader uses this.  Line numbers are 1-based physical lines of the
file, so the header is line 1 and the first data row is usually line 2.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .._errors import SessionError

__all__ = ["read_columns"]


def _parse_cell(path: Path, line: int, column: str, text: str) -> float:
    """One cell as a finite float, or a SessionError naming the line, column and text."""
    try:
        value = float(text)
    except ValueError:
        raise SessionError(
            path,
            f"column {column!r}: {text!r} is not a number; write a plain decimal number "
            "(no units, no thousands separators) or remove the row",
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


def read_columns(path: Path, wanted: dict[str, str], *, asked_by: str) -> tuple[dict, list]:
    """Read the columns ``wanted`` (role -> header name) of a CSV file as float arrays.

    Parameters
    ----------
    path : the CSV file; its first line is a header naming the columns.
    wanted : maps a role (``"time"``, ``"speed"``, ...) to the header name to read.
    asked_by : where the names come from (e.g. ``"session.toml trace['x'].columns"``),
        quoted in the error when a name is not in the header.

    Returns
    -------
    columns : dict mapping each role to a 1-D float array, in file order.
    lines : the 1-based file line of each row, for later error messages.

    Raises
    ------
    SessionError
        If the file is missing or empty, a column is missing, a row is short, or a
        cell is not a finite number.
    """
    if not path.is_file():
        raise SessionError(path, "file not found; check the file name in session.toml "
                           "(it is relative to the session directory) or add the file")
    with path.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        header = None
        for row in reader:
            if any(cell.strip() for cell in row):
                header = [cell.strip() for cell in row]
                break
        if header is None:
            raise SessionError(path, "the file is empty; its first line must be a header "
                               "naming the columns, followed by one row per sample")
        header_line = reader.line_num
        index = {}
        for role, name in wanted.items():
            if name not in header:
                cols = ", ".join(repr(h) for h in header)
                raise SessionError(
                    path,
                    f"no column named {name!r} (the {role} column named in {asked_by}); the "
                    f"header has {cols}; fix the name in session.toml or in the header",
                    where=f"line {header_line}",
                )
            index[role] = header.index(name)
        values: dict[str, list[float]] = {role: [] for role in wanted}
        lines: list[int] = []
        for row in reader:
            if not any(cell.strip() for cell in row):
                continue
            line = reader.line_num
            for role, k in index.items():
                if k >= len(row):
                    raise SessionError(
                        path,
                        f"the row has {len(row)} fields but column {wanted[role]!r} is "
                        f"field {k + 1}; fill in the missing fields",
                        where=f"line {line}",
                    )
                values[role].append(_parse_cell(path, line, wanted[role], row[k].strip()))
            lines.append(line)
    return {role: np.asarray(v, dtype=float) for role, v in values.items()}, lines
