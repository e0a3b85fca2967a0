"""Unit conversion to SI, done once at the boundary (the session loader and the CLI).

Every quantity inside pmdc_bayes is SI: s, rad/s, A, V, N·m, H, Ω, kg·m², N·m·s/rad,
V·s/rad.  :func:`to_si` converts a value given in a named unit of a known kind.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["KINDS", "SI_UNIT", "DISPLAY", "display_unit", "to_si", "from_si", "unit_factor",
           "unit_named"]

OUNCE_INCH = 0.45359237 / 16.0 * 9.80665 * 0.0254  # N·m: an ounce-force at an inch
_TORQUE = {"N*m": 1.0, "N.m": 1.0, "N·m": 1.0, "Nm": 1.0, "mN*m": 1e-3, "mN.m": 1e-3,
           "mN·m": 1e-3, "mNm": 1e-3, "N*cm": 1e-2, "N.cm": 1e-2, "N·cm": 1e-2, "Ncm": 1e-2,
           "oz*in": OUNCE_INCH, "oz-in": OUNCE_INCH, "oz.in": OUNCE_INCH, "ozin": OUNCE_INCH}

KINDS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6},
    "speed": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0, "rev/s": 2.0 * math.pi,
              "Hz": 2.0 * math.pi, "krpm": 2.0 * math.pi * 1e3 / 60.0, "deg/s": math.pi / 180.0},
    "current": {"A": 1.0, "mA": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3},
    "torque": _TORQUE,
    "inductance": {"H": 1.0, "mH": 1e-3, "uH": 1e-6, "µH": 1e-6},
    "resistance": {"ohm": 1.0, "Ohm": 1.0, "Ω": 1.0, "mohm": 1e-3, "mOhm": 1e-3, "mΩ": 1e-3,
                   "V/A": 1.0, "mV/A": 1e-3},
    "inertia": {"kg*m^2": 1.0, "kg·m²": 1.0, "kg*m2": 1.0, "kg.m^2": 1.0, "g*cm^2": 1e-7,
                "g·cm²": 1e-7, "g*cm2": 1e-7},
    "damping": {"N*m*s/rad": 1.0, "N·m·s/rad": 1.0, "N*m*s": 1.0, "mN*m*s/rad": 1e-3},
    "motor_constant": {"V*s/rad": 1.0, "V·s/rad": 1.0, "N*m/A": 1.0, "N·m/A": 1.0,
                       "mV*s/rad": 1e-3, "mN*m/A": 1e-3, "V/krpm": 60.0 / (2.0 * math.pi * 1000.0),
                       "mV/rpm": 60.0 / (2.0 * math.pi * 1000.0), "V/rpm": 60.0 / (2.0 * math.pi)},
    "duty": {"1": 1.0, "": 1.0, "%": 0.01},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "rev": 2.0 * math.pi},
    "frequency": {"Hz": 1.0, "kHz": 1e3},
}

SI_UNIT: dict[str, str] = {
    "time": "s", "speed": "rad/s", "current": "A", "voltage": "V", "torque": "N*m",
    "inductance": "H", "resistance": "ohm", "inertia": "kg*m^2", "damping": "N*m*s/rad",
    "motor_constant": "V*s/rad", "duty": "1", "angle": "rad", "frequency": "Hz",
}

# How each SI unit name (as written in summary.json) is shown to people: the one table
# every report, figure and printed table uses.
DISPLAY: dict[str, str] = {
    "ohm": "Ω", "H": "H", "V*s/rad": "V·s/rad", "N*m/A": "N·m/A", "N*m*s/rad": "N·m·s/rad",
    "kg*m^2": "kg·m²", "N*m": "N·m", "s": "s", "rad/s": "rad/s", "A": "A", "V": "V",
    "rad/s/V": "rad/s per V", "rpm/V": "rpm/V", "1": "", "rad": "rad",
    # the coefficients of the transfer functions (7) and (22)
    "H*kg*m^2": "H·kg·m²", "ohm*kg*m^2": "Ω·kg·m²", "(V*s/rad)^2": "(V·s/rad)²",
    "rad/s^2/A": "rad/s² per A", "ohm/s": "Ω/s",
}


# Names a logger's row of units writes for a unit of KINDS (compared case-blind).
_ALIASES: dict[str, dict[str, str]] = {
    "time": {"sec": "s", "secs": "s", "second": "s", "seconds": "s", "msec": "ms",
             "usec": "us", "μs": "µs"},
    "speed": {"1/min": "rpm", "u/min": "rpm", "min^-1": "rpm", "min-1": "rpm",
              "r/min": "rpm", "rev/min": "rpm", "rad/sec": "rad/s", "rps": "rev/s",
              "°/s": "deg/s", "deg/sec": "deg/s", "dps": "deg/s"},
    "voltage": {"volt": "V", "volts": "V"},
    "current": {"amp": "A", "amps": "A"},
    "angle": {"°": "deg", "degrees": "deg", "revs": "rev"},
}


def unit_named(kind: str, text: str, *, exact: bool = False) -> str | None:
    """The unit of ``kind`` that ``text`` names, as a logger writes it in a row of units
    (``ms``, ``(rpm)``, ``[A]``, ``1/min``), or None when it names none.  ``exact``:
    only as written, case included (``mA``, not ``ma``)."""
    key = text.strip().strip("()[]{}<>").strip()
    table = KINDS.get(kind, {})
    if key in table and key:
        return key
    if exact:
        return _ALIASES.get(kind, {}).get(key)
    folded = {u.lower(): u for u in table if u}
    aliases = {a.lower(): u for a, u in _ALIASES.get(kind, {}).items()}
    found = {folded.get(key.lower()), aliases.get(key.lower())} - {None}
    if len(found) != 1:
        return None
    unit = found.pop()
    mega = kind == "resistance" and key[:1] == "M"  # MΩ exists; a shouted "MS" is ms
    return None if mega and unit[:1] == "m" else unit


def display_unit(unit: str) -> str:
    """The unit as shown to people (``"N*m"`` → ``"N·m"``); unknown names unchanged."""
    return DISPLAY.get(unit, unit)


def unit_factor(kind: str, unit: str) -> float:
    """Return the factor that converts a value in ``unit`` to SI for a quantity of ``kind``
    (``unit`` one of :data:`KINDS`, or a name a logger writes for one, :func:`unit_named`).

    Raises
    ------
    KeyError
        If ``kind`` is unknown; ``ValueError`` (with the accepted units) if ``unit`` is.
    """
    table = KINDS[kind]
    key = unit.strip()
    if key not in table:
        key = unit_named(kind, key) or key  # as a logger writes it: "RPM", "rad/sec"
    if key not in table:
        accepted = ", ".join(u for u in table if u)
        raise ValueError(f"unknown {kind} unit {unit!r}; use one of: {accepted}")
    return table[key]


def to_si(value, kind: str, unit: str):
    """Convert ``value`` (float or array) from ``unit`` to SI."""
    factor = unit_factor(kind, unit)
    if isinstance(value, np.ndarray):
        return value * factor
    return float(value) * factor


def from_si(value, kind: str, unit: str):
    """Convert ``value`` from SI to ``unit`` (for display only)."""
    factor = unit_factor(kind, unit)
    if isinstance(value, np.ndarray):
        return value / factor
    return float(value) / factor
