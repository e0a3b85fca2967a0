"""A CSV's row of units under its header, checked against the units session.toml reads
the columns in: a file that says ``ms`` where the session reads seconds would make
every time a thousand times too long."""

from __future__ import annotations

from pathlib import Path

from .._errors import SessionError
from .units import KINDS, unit_factor, unit_named

__all__ = ["check_units_row"]


def check_units_row(path: Path, cols: dict, row: dict, line: int | None, read_in: dict,
                    kinds: dict, where: str) -> None:
    """Refuse a column whose unit in the file's row of units (``row``: role -> text, at
    ``line``) is a unit of its kind other than the one it is read in (``read_in``: role
    -> unit); ``where`` is the table of session.toml that gives the units.  Text that
    names no unit of the column's kind (a channel's name, a tachometer's volts) is not
    compared."""
    for role, text in row.items():
        kind = kinds.get(role)
        named = unit_named(kind, text) if kind else None
        unit = read_in.get(role)
        if named is None or unit is None or unit not in KINDS[kind]:
            continue
        if unit_factor(kind, named) != unit_factor(kind, unit):
            raise SessionError(
                path, f"the row of units gives column {cols[role]!r} in {text.strip()!r}, "
                f"where session.toml reads it in {unit!r}; set {where}.units.{role} = "
                f"\"{named}\" (or correct the row)", where=f"line {line}")
