"""Typed access to the tables of a parsed ``session.toml``, for the session loader.

Every accessor raises a one-line :class:`SessionError` naming ``session.toml`` and the
key path (e.g. ``bench.Ra.sd``, ``trace['step'].units.speed``) of the bad entry.
"""

from __future__ import annotations

import math
from pathlib import Path

from .._errors import SessionError
from .units import SI_UNIT, to_si, unit_factor, unit_named

__all__ = ["Table", "REQUIRED", "describe"]

REQUIRED = object()


def describe(value) -> str:
    """How a TOML value reads in an error message."""
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    return f"{value!r}"


class Table:
    """Typed access to one TOML table; errors name ``session.toml`` and the key path."""

    def __init__(self, file: Path, data: dict, where: str):
        self.file, self.data, self.where = file, data, where

    def path(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, message: str):
        raise SessionError(self.file, message, where=self.path(key))

    def check_keys(self, allowed) -> None:
        for key in self.data:
            if key not in allowed:
                self.fail(key, f"unknown key {key!r}; use one of: {', '.join(allowed)} "
                          "(check the spelling)")

    def _get(self, key, default, what):
        if key not in self.data:
            if default is REQUIRED:
                self.fail(key, f"missing required key; add {key} = <{what}>")
            return default, False
        return self.data[key], True

    def value(self, key: str, *, default=REQUIRED, what: str = "value"):
        """The raw value of ``key`` (``default`` when absent), unchecked."""
        return self._get(key, default, what)[0]

    def table(self, key: str, *, required: bool = True) -> Table | None:
        if key not in self.data:
            if required:
                how = f"{key} = {{ ... }}" if "[" in self.where else f"a [{self.path(key)}] section"
                self.fail(key, f"missing required table; add {how}")
            return None
        value = self.data[key]
        if not isinstance(value, dict):
            self.fail(key, f"expected a table, got {describe(value)}; write [{self.path(key)}] "
                      "or an inline table { ... }")
        return Table(self.file, value, self.path(key))

    def tables(self, key: str) -> list[Table]:
        """An array of tables ``[[key]]``, each labelled by its name (or 1-based position)."""
        value = self.data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            self.fail(key, f"expected an array of tables, got {describe(value)}; write each "
                      f"entry as a [[{key}]] table")
        out = []
        for i, item in enumerate(value, start=1):
            name = item.get("name")
            label = f"{key}[{name!r}]" if isinstance(name, str) and name else f"{key}[{i}]"
            out.append(Table(self.file, item, label))
        return out

    def string(self, key: str, *, default=REQUIRED, choices=None) -> str:
        value, given = self._get(key, default, "text in quotes")
        if given and (not isinstance(value, str) or not value.strip()):
            self.fail(key, f"expected a non-empty string, got {describe(value)}; write "
                      f'{key} = "..."')
        if given and choices and value not in choices:
            self.fail(key, f"unknown value {value!r}; use one of: {', '.join(choices)}")
        return value

    def number(self, key: str, kind: str | None = None, unit: str | None = None, *,
               default=REQUIRED, positive: bool = False, low: float | None = None) -> float:
        """A finite number, converted from ``unit`` to SI for a quantity of ``kind``;
        ``positive`` and ``low`` bound the SI value."""
        value, given = self._get(key, default, "number")
        if not given:
            return value
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(key, f"expected a number, got {describe(value)}; write the number "
                      "without quotes" + (" and give its unit in units" if kind else ""))
        if isinstance(value, int) and abs(value) > 1e300:
            self.fail(key, "the integer is too large for a number; write the measured value")
        if not math.isfinite(value):
            self.fail(key, f"{value} is not a finite number; write the measured value")
        si = float(value) if kind is None else to_si(value, kind, unit or SI_UNIT[kind])
        if positive and not si > 0:
            self.fail(key, f"must be positive, got {value}; check the value and its sign")
        if low is not None and si < low:
            self.fail(key, f"must be >= {low}, got {value}; check the value")
        return si

    def numbers(self, key: str, *, required: bool = True) -> tuple[float, ...] | None:
        """A non-empty list of finite numbers (SI, no unit)."""
        value, given = self._get(key, REQUIRED if required else None, "[number, ...]")
        if not given:
            return None
        if not isinstance(value, list) or not value:
            self.fail(key, f"expected a non-empty list of numbers, got {describe(value)}")
        return tuple(Table(self.file, {key: v}, self.where).number(key) for v in value)

    def unit(self, key: str, kind: str) -> str:
        text = self.string(key)
        try:
            unit_factor(kind, text)
        except ValueError as exc:
            self.fail(key, str(exc))
        return unit_named(kind, text) or text.strip()  # "RPM" is rpm

    def units(self, kinds: dict[str, str], extra: dict | None = None) -> dict[str, str]:
        """The optional ``units`` table: key -> unit, SI for keys not given; ``extra``
        maps a key to further unit names it accepts (converted by the caller)."""
        out = {key: SI_UNIT[kind] for key, kind in kinds.items()}
        extra = extra or {}
        given = self.table("units", required=False)
        if given is not None:
            given.check_keys(kinds)
            out.update({key: (given.data[key].strip() if given.data[key] in extra.get(key, ())
                              else given.unit(key, kinds[key])) for key in given.data})
        return out

    def columns(self, kinds: dict[str, str], required: tuple[str, ...]) -> dict[str, str | int]:
        """Each role's column: a header name, or, in a file without a header, the
        column's field number counted from 1 (every role the same way)."""
        cols = self.table("columns")
        cols.check_keys(kinds)
        for role in required:
            cols._get(role, REQUIRED, "text in quotes")
        for role in kinds:
            if isinstance(cols.data.get(role), float | bool):
                cols.fail(role, f"expected a header name in quotes or a field number (a whole "
                          f"number from 1), got {describe(cols.data[role])}")
        out = {role: (cols._field(role) if isinstance(cols.data[role], int) else
                      cols.string(role)) for role in kinds if role in cols.data}
        if len({type(v) for v in out.values()}) > 1:
            self.fail("columns", "mixes header names and field numbers; name every column "
                      "by its header, or, in a file without a header, give every one as its "
                      "field number (1 for the first)")
        return out

    def _field(self, key: str) -> int:
        value = self.data[key]
        if value < 1:
            self.fail(key, f"field {value} does not exist; count the fields from 1 (the "
                      "first column of the file)")
        return value
