"""Readings logged as a sensor's output voltage, read as what the sensor measures.

A trace's speed logged in volts (``units.speed = "V"`` or ``"mV"``) is a
tachogenerator's output: the speed is the voltage over ``tacho_constant`` (e.g. 2.5
``V/krpm``).  A current logged in volts is a current sensor's output (a Hall sensor, a
shunt's amplifier or the shunt itself): the current is the voltage less
``current_zero`` (the output at zero current, 0 V unless given) over
``current_sensitivity`` (V per A; a bare shunt's resistance in ohm is the same number).
A negative constant reads a sensor wired the other way round.  What is left of a
sensor's error (a constant a few per cent off, an offset) is what the model's
``speed_gain``, ``current_gain`` and ``*_offset`` fit.
"""

from __future__ import annotations

import numpy as np

from .toml_tables import Table
from .units import to_si

__all__ = ["UNIT_KINDS", "KEYS", "VOLTS", "CONSTANT", "speed_si", "current_si", "check_unused",
           "physical"]

VOLTS = ("V", "mV")
UNIT_KINDS = {"tacho_constant": "motor_constant", "current_sensitivity": "resistance",
              "current_zero": "voltage"}
KEYS = tuple(UNIT_KINDS)
CONSTANT = {"speed": "tacho_constant", "current": "current_sensitivity"}  # volts to SI
_EXAMPLES = {"tacho_constant": 'tacho_constant = 2.5 with units.tacho_constant = "V/krpm"',
             "current_sensitivity": 'current_sensitivity = 0.185 with '
                                    'units.current_sensitivity = "V/A" (or a shunt\'s ohms)'}


def _constant(t: Table, key: str, u: dict, what: str) -> float:
    if key not in t.data:
        t.fail(key, f"the {what} is logged in volts (units.{what} = \"{u[what]}\") but no "
               f"{key} is given; add the sensor's constant, e.g. {_EXAMPLES[key]}")
    value = t.number(key, UNIT_KINDS[key], u[key])
    if value == 0.0:
        t.fail(key, "must not be zero; write the sensor's constant from its data sheet or "
               "calibration")
    return value


def speed_si(t: Table, raw: np.ndarray, u: dict) -> np.ndarray:
    """A speed column in SI: from a tachogenerator's volts when logged so."""
    if u["speed"] not in VOLTS:
        return to_si(raw, "speed", u["speed"])
    return to_si(raw, "voltage", u["speed"]) / _constant(t, CONSTANT["speed"], u, "speed")


def current_si(t: Table, raw: np.ndarray, u: dict) -> np.ndarray:
    """A current column in SI: from a current sensor's volts when logged so."""
    if u["current"] not in VOLTS:
        return to_si(raw, "current", u["current"])
    scale = _constant(t, CONSTANT["current"], u, "current")
    zero = t.number("current_zero", "voltage", u["current_zero"], default=0.0)
    return (to_si(raw, "voltage", u["current"]) - zero) / scale


def check_unused(t: Table, u: dict, columns: dict) -> None:
    """A sensor's constant given where no column is logged in volts is bad input."""
    for key, what in ((CONSTANT["speed"], "speed"), (CONSTANT["current"], "current"),
                      ("current_zero", "current")):
        if key in t.data and not (what in columns and u.get(what) in VOLTS):
            t.fail(key, f"is only read with a {what} column logged in volts; set "
                   f"units.{what} = \"V\" (or \"mV\") for the sensor's output, or remove "
                   f"{key}")


def physical(u: dict) -> dict:
    """The trace's units for the speeds and currents written in ``session.toml`` (an
    initial state, a drag curve): a column's unit, or SI where the column is a
    sensor's volts."""
    return {k: ("rad/s" if k == "speed" else "A") if k in ("speed", "current") and v in VOLTS
            else v for k, v in u.items()}
