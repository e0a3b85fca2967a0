"""Sensors logged as their output voltage: a tachogenerator's speed and a current
sensor's (or shunt's) current, read as the speed and current they measure, and the
constants they need refused in one line where missing, zero or given for nothing."""

import json

import numpy as np
import pytest
from conftest import replace_once

from pmdc_bayes.io.loader import load_session

TOML = "session.toml"
UNITS = 'units = { time = "s", speed = "rpm", current = "A", voltage = "V" }'
TACHO = 2.5e-3  # V per rpm (2.5 V/krpm)
ZERO, SENSITIVITY = 2.5, 0.185  # a Hall sensor: 2.5 V at 0 A, 185 mV per A


def _as_volts(d, *, tacho=TACHO, units='speed = "V", current = "V"',
              keys='tacho_constant = 2.5\ncurrent_sensitivity = 185.0\ncurrent_zero = 2.5\n'
                   'units = { time = "s", tacho_constant = "V/krpm", '
                   'current_sensitivity = "mV/A", current_zero = "V", voltage = "V", '):
    """Rewrite step.csv as the sensors' volts and declare them in session.toml."""
    header, *rows = (d / "step.csv").read_text().splitlines()
    out = [header]
    for row in rows:
        t, w, i = (float(x) for x in row.split(","))
        out.append(f"{t!r},{w * tacho!r},{ZERO + SENSITIVITY * i!r}")
    (d / "step.csv").write_text("\n".join(out) + "\n")
    replace_once(d / TOML, UNITS, keys + units + " }")


def _closed_form(pmdc, d):
    proc = pmdc("closed-form", d, "--json", timeout=120)
    return proc


def test_a_tacho_and_a_hall_sensor_logged_in_volts_read_as_speed_and_current(session_dir, pmdc):
    before = load_session(session_dir).traces[0]
    expected = _closed_form(pmdc, session_dir)
    _as_volts(session_dir)
    after = load_session(session_dir).traces[0]
    np.testing.assert_allclose(after.speed, before.speed, rtol=1e-12)
    np.testing.assert_allclose(after.current, before.current, rtol=1e-9, atol=1e-12)
    proc = _closed_form(pmdc, session_dir)
    assert proc.returncode == 0, proc.stderr
    got, want = json.loads(proc.stdout), json.loads(expected.stdout)
    for key in ("Ra", "K", "B", "J"):
        assert got[key] == pytest.approx(want[key], rel=1e-6), key


def test_a_sensor_wired_the_other_way_round_takes_a_negative_constant(session_dir):
    before = load_session(session_dir).traces[0]
    _as_volts(session_dir, tacho=-TACHO, keys='tacho_constant = -2.5e-3\n'
              'units = { time = "s", tacho_constant = "V/rpm", voltage = "V", current = "A", ',
              units='speed = "V"')
    # the current column still holds the Hall sensor's volts: read it as amperes instead
    header, *rows = (session_dir / "step.csv").read_text().splitlines()
    rows = [",".join([*r.split(",")[:2], repr((float(r.split(",")[2]) - ZERO) / SENSITIVITY)])
            for r in rows]
    (session_dir / "step.csv").write_text("\n".join([header, *rows]) + "\n")
    after = load_session(session_dir).traces[0]
    np.testing.assert_allclose(after.speed, before.speed, rtol=1e-12)


@pytest.mark.parametrize("keys,units,expected", [
    ('units = { time = "s", voltage = "V", ', 'speed = "V", current = "A"',
     "trace['step'].tacho_constant: the speed is logged in volts"),
    ('tacho_constant = 0.0\nunits = { time = "s", voltage = "V", ', 'speed = "V", current = "A"',
     "tacho_constant: must not be zero"),
    ('tacho_constant = 2.5\nunits = { time = "s", tacho_constant = "V/krpm", voltage = "V", ',
     'speed = "rpm", current = "A"', "tacho_constant: is only read with a speed column "
     "logged in volts"),
    ('current_zero = 2.5\nunits = { time = "s", voltage = "V", ', 'speed = "rpm", current = "A"',
     "current_zero: is only read with a current column logged in volts"),
    ('units = { time = "s", voltage = "V", ', 'speed = "rpm", current = "mV"',
     "current_sensitivity: the current is logged in volts"),
])
def test_a_sensors_constant_missing_zero_or_for_nothing_is_one_line(session_dir, keys, units,
                                                                     expected, pmdc):
    replace_once(session_dir / TOML, UNITS, keys + units + " }")
    proc = _closed_form(pmdc, session_dir)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert "Traceback" not in proc.stderr and expected in line, line


def test_a_coast_down_read_by_a_tacho(session_dir):
    (session_dir / "coast.csv").write_text(
        "t,tacho\n" + "".join(f"{t:.3f},{float(2.5e-3 * 600.0 * np.exp(-t / 0.2))!r}\n"
                              for t in np.arange(0.0, 0.5, 0.01)))
    with (session_dir / TOML).open("a") as f:
        f.write('\n[[trace]]\nname = "coast"\nkind = "coast-down"\nfile = "coast.csv"\n'
                'columns = { time = "t", speed = "tacho" }\ntacho_constant = 2.5\n'
                'units = { speed = "V", tacho_constant = "V/krpm" }\n')
    coast = load_session(session_dir).coast_downs[0]
    rpm = 2.0 * np.pi / 60.0
    np.testing.assert_allclose(coast.speed / rpm, 600.0 * np.exp(-coast.time / 0.2),
                               rtol=1e-12)
