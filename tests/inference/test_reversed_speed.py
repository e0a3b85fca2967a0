"""A speed wired against the voltage's sign (a tachometer's leads swapped, an encoder
counting the other way): refused before any fit with the trace it is on and the fix,
where it was fitted and read as anti-correlated noise; a session that turns both ways
with its voltage is not touched."""

import shutil

import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.levels import reversed_speed
from pmdc_bayes.inference.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import fuzz_session


def _negate(csv, column):
    lines = csv.read_text().splitlines()
    j = lines[0].split(",").index(column)
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[j] = repr(-float(cells[j]))
        out.append(",".join(cells))
    csv.write_text("\n".join(out) + "\n")


@pytest.fixture(scope="module")
def speed_only(tmp_path_factory):
    """A step from rest logged with its voltage, speed only, and a steady table."""
    root = tmp_path_factory.mktemp("reversed") / "s"
    fuzz_session(5, out=root)
    return root


def test_a_trace_whose_sensor_is_reversed_is_named(speed_only, tmp_path):
    d = tmp_path / "s"
    shutil.copytree(speed_only, d)
    assert reversed_speed(load_session(d)) is None
    _negate(next(d.glob("tr0_*.csv")), "speed")
    with pytest.raises(SessionError) as err:
        fit_seed(load_session(d))
    text = str(err.value)
    assert "tr0_step_from_rest" in text and "negate that trace's speed column" in text


def test_a_whole_session_turning_against_its_voltage_is_one_wiring(speed_only, tmp_path):
    d = tmp_path / "s"
    shutil.copytree(speed_only, d)
    _negate(next(d.glob("tr0_*.csv")), "speed")
    _negate(d / "steady.csv", "w")
    found = reversed_speed(load_session(d))
    assert found is not None and found[0] is None
    assert "wired the other way round" in found[1]


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 5])  # each holds levels of both signs
def test_sessions_that_turn_both_ways_with_their_voltage_pass(seed, tmp_path):
    fuzz_session(seed, out=tmp_path / "s", shapes=("staircase", "up-down"))
    session = load_session(tmp_path / "s")
    assert reversed_speed(session) is None
