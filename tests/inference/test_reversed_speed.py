"""A speed wired against the voltage's sign (a tachometer's leads swapped, an encoder
counting the other way), or a current sensor wired the other way round: refused before
any fit with the trace it is on and the fix, where it was fitted and read as
anti-correlated noise; a session that turns both ways with its voltage is not touched."""

import shutil

import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.model.contradictions import refuse_contradictions
from pmdc_bayes.inference.model.reversal import reversed_current, reversed_speed
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
        refuse_contradictions(load_session(d))
    assert err.value.path.name.startswith("tr0_step_from_rest")
    assert "negate this file's speed column" in str(err.value)


def test_a_whole_session_turning_against_its_voltage_is_one_wiring(speed_only, tmp_path):
    d = tmp_path / "s"
    shutil.copytree(speed_only, d)
    _negate(next(d.glob("tr0_*.csv")), "speed")
    _negate(d / "steady.csv", "w")
    found = reversed_speed(load_session(d))
    assert found is not None and found.file.name == "session.toml"
    assert "wired the other way round" in found.why


def test_a_steady_table_written_with_the_other_sign_is_named(speed_only, tmp_path):
    """The traces turn with their voltage, the table's speeds against theirs: the table's
    file is named, not the traces'."""
    d = tmp_path / "s"
    shutil.copytree(speed_only, d)
    _negate(d / "steady.csv", "w")
    with pytest.raises(SessionError) as err:
        refuse_contradictions(load_session(d))
    assert err.value.path == d / "steady.csv"
    assert "negate its speed column" in str(err.value)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 5])  # each holds levels of both signs
def test_sessions_that_turn_both_ways_with_their_voltage_pass(seed, tmp_path):
    fuzz_session(seed, out=tmp_path / "s", shapes=("staircase", "up-down"))
    session = load_session(tmp_path / "s")
    assert reversed_speed(session) is None


@pytest.mark.parametrize("entry", ["search", "fit"])
def test_both_ways_into_a_fit_refuse_it_first(speed_only, tmp_path, entry):
    """The model search and a fit of the session's own model each refuse the session
    before their first fit."""
    from pmdc_bayes.pipeline import FitOptions, fit_session
    from pmdc_bayes.search import run_search

    d = tmp_path / "s"
    shutil.copytree(speed_only, d)
    _negate(next(d.glob("tr0_*.csv")), "speed")
    session = load_session(d)
    with pytest.raises(SessionError, match="negate this file's speed column"):
        if entry == "search":
            run_search(session)
        else:
            fit_session(session, FitOptions(mcmc=False))


@pytest.mark.parametrize(("seed", "trace"), [(1, "tr0_up_down"), (32, "tr0_load_change")])
def test_a_current_sensor_wired_the_other_way_round_is_named(tmp_path, seed, trace):
    """A current that falls where the voltage steps up (an up-down step, both ways) or
    where the load steps up at a constant voltage (a load-change trace) is refused
    before any fit, naming its file and the fix; as logged it is not."""
    d = tmp_path / "s"
    fuzz_session(seed, out=d)
    assert reversed_current(load_session(d)) is None
    _negate(d / f"{trace}.csv", "ia")
    with pytest.raises(SessionError) as err:
        refuse_contradictions(load_session(d))
    assert err.value.path.name == f"{trace}.csv"
    assert "negate this file's current column" in str(err.value)


def test_the_closed_form_refuses_a_reversed_sensor_as_the_fit_does(pmdc, tmp_path):
    """The closed form would read a reversed current as a negative friction: refused
    first, one line, exit 2."""
    d = tmp_path / "s"
    fuzz_session(1, out=d)
    _negate(d / "tr0_up_down.csv", "ia")
    done = pmdc("closed-form", d)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and "current sensor is wired" in done.stderr
