"""Unit conversion to SI (units.py): every table entry, the named factors, the errors."""

import math

import numpy as np
import pytest

from pmdc_bayes.io.units import KINDS, SI_UNIT, from_si, to_si, unit_factor

ALL_UNITS = [(kind, unit) for kind, table in KINDS.items() for unit in table]

# Independently written factors (value in unit -> SI), for the units users meet most.
KNOWN = [
    ("speed", "rpm", 2.0 * math.pi / 60.0),
    ("speed", "rev/s", 2.0 * math.pi),
    ("time", "ms", 1e-3),
    ("time", "us", 1e-6),
    ("current", "mA", 1e-3),
    ("voltage", "mV", 1e-3),
    ("torque", "mN*m", 1e-3),
    ("torque", "N·m", 1.0),
    ("inductance", "mH", 1e-3),
    ("inductance", "uH", 1e-6),
    ("resistance", "mohm", 1e-3),
    ("resistance", "Ω", 1.0),
    ("inertia", "g*cm^2", 1e-3 * 1e-4),
    ("damping", "mN*m*s/rad", 1e-3),
    ("motor_constant", "V/krpm", 1.0 / (1000.0 * 2.0 * math.pi / 60.0)),
    ("motor_constant", "mN*m/A", 1e-3),
    ("duty", "%", 0.01),
]


def test_every_kind_has_its_si_unit_with_factor_one():
    assert set(SI_UNIT) == set(KINDS)
    for kind, unit in SI_UNIT.items():
        assert unit_factor(kind, unit) == 1.0


@pytest.mark.parametrize(("kind", "unit", "factor"), KNOWN)
def test_known_factors(kind, unit, factor):
    assert to_si(1.0, kind, unit) == pytest.approx(factor, rel=1e-15)


def test_paper_numbers():
    # Figure 4: 1590 rpm is the paper's 166.5 rad/s; La = 5.621 mH.
    assert to_si(1590.0, "speed", "rpm") == pytest.approx(166.5, abs=0.05)
    assert to_si(5.621, "inductance", "mH") == pytest.approx(5.621e-3, rel=1e-15)


@pytest.mark.parametrize(("kind", "unit"), ALL_UNITS)
def test_round_trip_scalar_and_array(kind, unit):
    x = np.array([0.0, 1.5, -2.25, 1e3])
    assert np.allclose(from_si(to_si(x, kind, unit), kind, unit), x, rtol=1e-14, atol=0.0)
    assert from_si(to_si(3.5, kind, unit), kind, unit) == pytest.approx(3.5, rel=1e-14)
    assert isinstance(to_si(3, kind, unit), float)


def test_array_in_array_out():
    out = to_si(np.array([60.0, 120.0]), "speed", "rpm")
    assert isinstance(out, np.ndarray)
    np.testing.assert_allclose(out, [2.0 * math.pi, 4.0 * math.pi], rtol=1e-15, atol=0.0)


def test_surrounding_spaces_are_ignored():
    assert unit_factor("speed", " rpm ") == unit_factor("speed", "rpm")


def test_a_unit_written_as_loggers_write_it_is_read():
    """Case aside and the names a logger's header uses: what a user types in
    ``session.toml`` after reading it off the logger's header."""
    assert unit_factor("speed", "RPM") == unit_factor("speed", "rpm")
    assert unit_factor("speed", "rad/sec") == 1.0 and unit_factor("speed", "1/min") > 0.1
    assert unit_factor("time", "Sec") == 1.0 and unit_factor("time", "msec") == 1e-3
    assert unit_factor("current", "amps") == 1.0 and unit_factor("voltage", "mv") == 1e-3


def test_unknown_unit_lists_the_accepted_ones():
    with pytest.raises(ValueError, match=r"unknown speed unit 'mph'; use one of: rad/s, rpm"):
        to_si(1.0, "speed", "mph")


def test_unknown_kind_is_a_key_error():
    with pytest.raises(KeyError):
        unit_factor("temperature", "K")
