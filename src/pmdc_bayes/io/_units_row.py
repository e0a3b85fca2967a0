"""A CSV's units, as its header names them (``time (ms)``, ``t_ms``, ``n/rpm``) or its
row of units under the header writes them, checked against the units session.toml
reads the columns in: a file that says ``ms`` where the session reads seconds would make
every time a thousand times too long."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .._errors import SessionError
from ._inputs import SUPPLY
from ._sensors import CONSTANT
from .units import KINDS, unit_factor, unit_named

__all__ = ["check_column_units", "check_units_row", "check_header_units", "header_unit",
           "unit_stated", "check_unstated", "KILOVOLT"]


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


_BRACKETED = re.compile(r"[(\[{<]\s*([^()\[\]{}<>]+?)\s*[)\]}>]\s*$")


def header_unit(kind: str, name: str) -> str | None:
    """The unit of ``kind`` a column's header name gives: in brackets at its end
    (``time (ms)``, ``Speed [RPM]``), after a slash (``t/ms``, the quantity over its unit)
    or after its last underscore (``t_ms``, ``i_mA``; written exactly, and at least two
    letters, so that ``I_a`` is a subscript, not amperes, but for a time's ``s``:
    ``time_s``); None when it gives none."""
    found = _BRACKETED.search(name)
    if found:
        return unit_named(kind, found.group(1))
    for sep, shortest in (("/", 1), ("_", 2)):
        head, _, tail = name.partition(sep) if sep == "/" else name.rpartition(sep)
        tail = tail.strip()
        if head.strip() and (len(tail) >= shortest or (kind, tail) == ("time", "s")):
            named = unit_named(kind, tail, exact=True)
            if named is not None:
                return named
    return None


# a column of the first kind may be logged as a sensor's output in a unit of the second,
# read so with that unit and the key named
_OUTPUTS = {**{role: ("voltage", key) for role, key in CONSTANT.items()},
            "voltage": ("duty", SUPPLY)}  # kind -> (its output's kind, the key reading it)


def check_header_units(path: Path, cols: dict, read_in: dict, kinds: dict,
                       where: str) -> None:
    """Refuse a column whose header name gives a unit of its kind (:func:`header_unit`)
    other than the one session.toml reads it in (``read_in``: role -> unit), or gives
    in brackets the unit of a sensor's or driver's output (a tachometer's volts, a duty)
    where session.toml reads it as the quantity itself."""
    for role, name in cols.items():
        kind, unit = kinds.get(role), read_in.get(role)
        if not (kind and isinstance(name, str) and unit in KINDS.get(kind, {})):
            continue
        named = header_unit(kind, name)
        if named is not None and unit_factor(kind, named) != unit_factor(kind, unit):
            raise SessionError(
                path, f"column {name!r} gives its unit in its header, {named!r}, where "
                f"session.toml reads it in {unit!r} ({where}.units.{role}, SI when not "
                f"given); set {where}.units.{role} = \"{named}\""
                + (" (Hz read as revolutions per second)" if named == "Hz" else "")
                + " (or correct the header)", where="header")
        other = None if named is not None else _bracketed_other(kind, name)
        if other is None:
            continue
        raise SessionError(
            path, f"column {name!r} gives its unit in its header, {other[1]!r}: a {kind} "
            f"logged as a sensor's or driver's output, where session.toml reads it as the "
            f"{kind} in {unit!r}; set {where}.units.{role} = \"{other[1]}\" and "
            f"{where}.{_OUTPUTS[kind][1]} (or correct the header)", where="header")


def _bracketed_other(kind: str, name: str) -> tuple[str, str] | None:
    """The (kind, unit) a header name's bracketed text names, written exactly, where a
    column of ``kind`` may be logged as a sensor's or driver's output in it (``Tacho [V]``
    for a speed, ``Duty [%]`` for a voltage); None where it names none (a note: ``(rev)``,
    ``[A0]``, ``(ch1)``, a channel's index)."""
    found = _BRACKETED.search(name)
    output = _OUTPUTS.get(kind, (None,))[0]
    if not (found and output):
        return None
    unit = unit_named(output, found.group(1).strip(), exact=True)
    return (output, unit) if unit and unit != "1" else None


def check_column_units(path: Path, cols: dict, read, read_in: dict, kinds: dict,
                       where: str) -> None:
    """The units a file's header names (:func:`check_header_units`) and its row of units
    writes (:func:`check_units_row`; ``read``: the file's columns as read) checked
    against those session.toml reads its columns in."""
    check_header_units(path, cols, read_in, kinds, where)
    check_units_row(path, cols, read.units, read.units_line, read_in, kinds, where)


def unit_stated(role: str, given, name, row: dict) -> bool:
    """Whether a trace's column of ``role`` (its kind's name: ``time``, ``voltage``)
    has a unit given: in session.toml (``given``, the trace's ``units``), its header
    ``name`` or the file's row of units (``row``: role -> text)."""
    return bool((isinstance(given, dict) and role in given)
                or (isinstance(name, str) and header_unit(role, name) is not None)
                or unit_named(role, row.get(role, "")) is not None)


KILOVOLT = 1000.0  # no bench drives a permanent-magnet DC motor at a kilovolt
WHOLE = {"voltage": 50.0, "current": 100.0}  # whole numbers this high with no unit: counts


def check_unstated(path: Path, cols: dict, raw: dict, given, row: dict, where: str, *,
                   duty: bool = True) -> None:
    """Refuse a voltage or current column with no unit given (in session.toml's
    ``given`` units, its header or the file's row of units ``row``) that reads a
    thousand or more (volts: a kilovolt, which millivolts or a PWM timer's or an ADC's
    counts written as numbers are; amperes: milliamperes or an ADC's counts), or only
    whole numbers up to :data:`WHOLE` or more (a PWM timer's counts, ``analogWrite``'s
    0–255, an ADC's, a duty in per cent, which an analogue sensor's readings never all
    are).  ``where``: the columns' table in session.toml; ``duty``: whether that table
    reads a PWM duty, as a trace does."""
    for role in ("voltage", "current"):
        if role in raw and not unit_stated(role, given, cols[role], row):
            _check_numbers(path, role, cols[role], raw[role], where, duty)


def _check_numbers(path: Path, role: str, column: str, values, where: str,
                   duty: bool) -> None:
    finite = np.abs(np.asarray(values, dtype=float))
    finite = finite[np.isfinite(finite)]
    if not finite.size:
        return
    top = float(finite.max())
    whole = WHOLE[role] <= top < KILOVOLT and bool(np.all(finite == np.round(finite)))
    if top < KILOVOLT and not whole:
        return
    read = (f"reads only whole numbers, up to {top:g}" if whole
            else f"reads up to {top:g}")
    if role == "current":
        raise SessionError(path, f"the current column {column!r} gives no unit and {read}: "
                           f"milliamperes or an ADC's counts rather than {top:g} A; set "
                           f"{where}.units.current = \"mA\", or convert counts to the "
                           "sensor's volts (units.current = \"V\" with current_sensitivity "
                           "and current_zero), or \"A\" if they are amperes", where="header")
    pwm = "\"pwm\" with pwm_full_scale and supply_voltage; " if duty else ""
    if not whole:
        raise SessionError(path, f"the voltage column {column!r} gives no unit and {read}, "
                           f"{top / KILOVOLT:.3g} kV if these were volts: millivolts, or a "
                           "PWM timer's or an ADC's counts, read so; set "
                           f"{where}.units.voltage = \"mV\" (or {pwm}\"V\" if they are "
                           "volts)", where="header")
    fix = (f"set {where}.units.voltage = \"pwm\" with pwm_full_scale = {_full(top)} "
           "and supply_voltage (\"%\" with supply_voltage for a duty in per cent), or "
           "\"V\" if they are volts" if duty else
           f"convert them to volts, or set {where}.units.voltage = \"V\" if they are")
    raise SessionError(path, f"the voltage column {column!r} gives no unit and {read}: a "
                       "PWM timer's or an ADC's counts or a duty in per cent rather than "
                       f"{top:g} V; {fix}", where="header")


def _full(top: float) -> int:
    """The full scale a PWM timer reading up to ``top`` most likely counts to: the
    smallest 2ⁿ − 1 (255, 1023, …) at or above it, or 100 for a per-cent duty's."""
    return 100 if top == 100 else int(2 ** np.ceil(np.log2(top + 1)) - 1)
