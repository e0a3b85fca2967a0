"""Logs written as ``name=value`` pairs, one sample per line, as a microcontroller's
serial prints write them (``t=12 ms w=153.2 ia=0.41``, ``t: 12, w: 153.2``) or as
JSON lines (``{"t": 0.012, "w": 153.2}``): the pairs become the rows of a table
without a header, one line for each line of the file (so errors name the file's
lines), the columns in the order asked for."""

from __future__ import annotations

import re
from typing import NamedTuple

__all__ = ["KeyValueTable", "key_value_rows"]

_PAIR = re.compile(
    r"""(?<![\w.])["']?([A-Za-z_][\w.\[\]()/]*)["']?\s*[=:]\s*"""  # a name, = or :
    r"""["']?([^\s,;=}"']+)["']?"""  # its value
    r"""(?:[ \t]+(?![^\s,;=:]+\s*[=:])([^\s\d,;=:}][^\s,;=:}]*))?""")  # a unit after it
SEARCHED = 100  # lines searched for the first with every name asked for


class KeyValueTable(NamedTuple):
    """The pairs as a comma-separated table: ``text`` (one line per line of the file,
    blank where a line holds none of the names), and the unit written after each value
    on the first complete line (role -> text; ``units_line`` that line)."""

    text: str
    units: dict
    units_line: int | None


def _pairs(line: str) -> dict[str, tuple[str, str]]:
    return {m.group(1).casefold(): (m.group(2), m.group(3) or "") for m in _PAIR.finditer(line)}


def key_value_rows(text: str, wanted: dict[str, str]) -> KeyValueTable | None:
    """``text`` read as ``name=value`` pairs, when one of its first :data:`SEARCHED`
    lines gives every name ``wanted`` (role -> name, matched in any case), else None."""
    lines = text.split("\n")
    names = {role: name.casefold() for role, name in wanted.items()}
    first = next((k for k, line in enumerate(lines[:SEARCHED])
                  if set(names.values()) <= set(_pairs(line))), None)
    if first is None:
        return None
    units = {role: _pairs(lines[first])[name][1] for role, name in names.items()}
    rows = []
    for line in lines:
        pairs = _pairs(line)
        if any(name in pairs for name in names.values()):
            rows.append(",".join(pairs.get(name, ("", ""))[0] for name in names.values()))
        else:
            rows.append("")
    return KeyValueTable("\n".join(rows), units if any(units.values()) else {},
                         first + 1 if any(units.values()) else None)
