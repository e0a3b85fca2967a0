"""Logs written as ``name=value`` pairs, one sample per line, as a microcontroller's
serial prints write them (``t=12 ms w=153.2 ia=0.41``, ``t: 12, w: 153.2``,
``t=12ms w=153.2rpm``) or as
JSON lines (``{"t": 0.012, "w": 153.2}``): the pairs become the rows of a table
without a header, one line for each line of the file (so errors name the file's
lines), the columns in the order asked for."""

from __future__ import annotations

import re
from typing import NamedTuple

from ._cells import number
from ._rows import column_index
from ._stamps import stamp_seconds
from .units import KINDS, unit_named

__all__ = ["KeyValueTable", "key_value_rows"]

_PAIR = re.compile(
    r"""(?<![\w.])["']?([A-Za-z_][\w.\[\]()/]*)["']?\s*[=:]\s*"""  # a name, = or :
    r"""["']?([^\s,;=}"']+(?:,\d+[^\s,;=}"']*(?![\d,]*\s*[=:]))?)["']?"""  # a decimal comma
    r"""(?:[ \t]+(?![^\s,;=:]+\s*[=:])([^\s\d,;=:}][^\s,;=:}]*))?""")  # a unit after it
SEARCHED = 100  # lines searched for the first with every name asked for


class KeyValueTable(NamedTuple):
    """The pairs as a comma-separated table: ``text`` (one line per line of the file,
    blank where a line holds none of the names), and the unit written after each value
    on the first complete line (role -> text; ``units_line`` that line)."""

    text: str
    units: dict
    units_line: int | None


_GLUED = re.compile(r"([+-]?\d+(?:[.,]\d+)?(?:[eE][+-]?\d+)?)([A-Za-zµ°%/][\w/%°µ^*.]*)")


def _pairs(line: str) -> dict[str, tuple[str, str]]:
    """A line's pairs, name -> (value, unit); none in a comment line (``#``).  A unit
    written against its value (``t=12ms``, ``w=153.2rpm``: a value that is no number,
    read as one followed by the name of a unit) is the value's unit."""
    if line.lstrip().startswith("#"):
        return {}
    out = {}
    for m in _PAIR.finditer(line):
        value, unit = m.group(2), m.group(3) or ""
        glued = None if unit or number(value) else _GLUED.fullmatch(value)
        if glued and any(unit_named(kind, glued.group(2)) for kind in KINDS):
            value, unit = glued.groups()
        out[m.group(1)] = (value, unit)
    return out


def _named(pairs: dict, name: str) -> str | None:
    """The pair's name that ``name`` reads: itself, or, where no pair has it, the one
    pair's name that differs from it only in case (as a header's names are matched)."""
    names = list(pairs)
    k = column_index(names, name)
    return None if k is None else names[k]


def _readable(value: str) -> bool:
    return number(value) or stamp_seconds(value) is not None


def key_value_rows(text: str, wanted: dict[str, str]) -> KeyValueTable | None:
    """``text`` read as ``name=value`` pairs, when one of its first :data:`SEARCHED`
    lines gives every name ``wanted`` (role -> name) a number or a time stamp, else None.
    A value with a decimal comma is quoted in the table, where the loader's decimal marks
    read it (:class:`._cells.DecimalMarks`)."""
    lines = text.split("\n")

    def complete(line):
        pairs = _pairs(line)
        keys = [_named(pairs, name) for name in wanted.values()]
        return all(k is not None and _readable(pairs[k][0]) for k in keys)

    first = next((k for k, line in enumerate(lines[:SEARCHED]) if complete(line)), None)
    if first is None:
        return None
    pairs = _pairs(lines[first])
    units = {role: pairs[_named(pairs, name)][1] for role, name in wanted.items()}
    rows = []
    for line in lines:
        pairs = _pairs(line)
        keys = [_named(pairs, name) for name in wanted.values()]
        if any(k is not None for k in keys):
            rows.append(",".join('"' + pairs[k][0] + '"' if k is not None else ""
                                 for k in keys))
        else:
            rows.append("")
    return KeyValueTable("\n".join(rows), units if any(units.values()) else {},
                         first + 1 if any(units.values()) else None)
