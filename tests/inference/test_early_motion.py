"""A voltage logged late against the motor (a supply's read-back, a logger that writes
the command after applying it): the motor moves before its voltage switches on, which
no motor at rest does.  Refused before any fit with the lead measured, where a fit of
the current would read its fall after the logged switch-on as a sensor wired the other
way round; a voltage that comes early (the motor's own dead time) is not touched, nor
are the sessions the bench simulator writes, each non-ideality among them."""

import numpy as np
import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.model.contradictions import refuse_contradictions
from pmdc_bayes.inference.model.early_motion import moves_early
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import NON_IDEALITIES, fuzz_session


def _shift_voltage(csv, rows: int) -> float:
    """Move the file's voltage column ``rows`` samples later (earlier where negative),
    the ends held; the time that many samples span."""
    lines = csv.read_text().splitlines()
    head = lines[0].split(",")
    cells = [line.split(",") for line in lines[1:]]
    j, k = head.index("va"), head.index("t")
    v = [c[j] for c in cells]
    v = [v[0]] * rows + v[:-rows] if rows > 0 else v[-rows:] + [v[-1]] * -rows
    for c, value in zip(cells, v, strict=True):
        c[j] = value
    csv.write_text("\n".join([lines[0], *(",".join(c) for c in cells)]) + "\n")
    t = np.array([float(c[k]) for c in cells])
    return abs(rows) * float(np.median(np.diff(t)))


@pytest.mark.parametrize("current", [False, True])
def test_a_voltage_logged_late_is_refused_with_its_lead(tmp_path, current):
    d = tmp_path / "s"
    fuzz_session(5, out=d, shapes=("step from rest",), trace_current=current)
    csv = next(d.glob("tr0_*.csv"))
    assert moves_early(load_session(d)) is None
    lead = _shift_voltage(csv, 60)
    with pytest.raises(SessionError) as err:
        refuse_contradictions(load_session(d))
    text = str(err.value)
    assert err.value.path == csv
    assert "before its logged voltage switches on" in text
    assert "wired the other way round" not in text
    said = float(text.split(" moves at least ")[1].split(" s ")[0])
    assert 0.3 * lead < said <= 1.05 * lead  # a lower bound on the delay


@pytest.mark.parametrize("current", [False, True])
def test_a_voltage_logged_early_is_a_dead_time_not_a_fault(tmp_path, current):
    d = tmp_path / "s"
    fuzz_session(5, out=d, shapes=("step from rest",), trace_current=current)
    _shift_voltage(next(d.glob("tr0_*.csv")), -30)
    assert moves_early(load_session(d)) is None


@pytest.mark.parametrize("seed", range(6))
def test_the_bench_simulators_sessions_do_not_move_early(tmp_path, seed):
    """Every non-ideality the simulator draws (a dead time, a lag, a drop, a limit, a
    load...) on sessions of many shapes, speeds quantised or not, samples between the
    driver's switching or on it."""
    for k, what in enumerate((None, *NON_IDEALITIES)):
        d = tmp_path / f"s{k}"
        fuzz_session(seed, misspecified=what, out=d, between_samples=seed % 2 == 1)
        found = moves_early(load_session(d))
        assert found is None, (what, found)


def test_a_run_down_that_ended_before_the_switch_on_is_not_early_motion(tmp_path):
    """A record that opens on the motor running down from a previous run, at rest well
    before the switch-on: its first readings are far from rest, the last ones before the
    switch-on a level, not a motion."""
    d = tmp_path / "s"
    fuzz_session(5, out=d, shapes=("step from rest",))
    csv = next(d.glob("tr0_*.csv"))
    lines = csv.read_text().splitlines()
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        t = float(cells[0])
        cells[1] = repr(float(cells[1]) + 500.0 * float(np.exp(-t / 0.004)))
        out.append(",".join(cells))
    csv.write_text("\n".join(out) + "\n")
    session = load_session(d)
    tr = session.traces[0]
    first = tr.time < 0.3 * float(tr.voltage.change_times()[0])
    assert np.median(tr.speed[first]) > 50.0  # the rest reading is off rest
    assert moves_early(session) is None


def test_a_late_schedule_is_named_in_session_toml(tmp_path):
    """A voltage written in session.toml that switches on after the motor moves: the
    schedule is the place to mend."""
    d = tmp_path / "s"
    fuzz_session(6, out=d, shapes=("step from rest",))
    toml = (d / "session.toml").read_text()
    was = "voltage = [[0, 0], [0.364267533, 5.46677]]"
    assert toml.count(was) == 1
    (d / "session.toml").write_text(toml.replace(was, was.replace("0.364267533", "0.52")))
    with pytest.raises(SessionError) as err:
        refuse_contradictions(load_session(d))
    assert err.value.path == d / "session.toml"
    assert err.value.where == "trace['tr0_step_from_rest'].voltage"
    assert "before its scheduled voltage switches on" in str(err.value)
