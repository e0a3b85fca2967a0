"""The session loader: SI conversion, defaults, schedules and the bundled paper session.

The error cases are run through the command line in ``test_validation_cli.py``; here a
few are checked in-process for the attributes of :class:`SessionError`.
"""

import json
import math

import numpy as np
import pytest
from conftest import (
    STEP_DT,
    STEP_FINAL_RPM,
    STEP_N,
    replace_once,
    step_rows,
)

from pmdc_bayes import SessionError
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Drag, Schedule

RPM = 2.0 * math.pi / 60.0
TOML = "session.toml"
SCHEDULE = "voltage = [[0.0, 0.0], [0.1, 6.0]]"


def test_small_session_in_si(session_dir):
    s = load_session(session_dir)
    assert s.name == "sess" and s.root == session_dir.resolve() and s.motor == "Test motor"
    assert s.friction == "viscous"
    assert s.Ra.value == 2.0 and s.Ra.sd == 0.05 and s.Ra.unit == "ohm"
    assert s.La.value == pytest.approx(1.5e-3, rel=1e-15)
    assert s.La.sd == pytest.approx(4e-5, rel=1e-15) and s.La.unit == "mH"
    (op,) = s.operating_points
    assert (op.supply_voltage, op.duty, op.current, op.speed, op.load_torque) == (
        12.0, 0.5, 0.3, 100.0, 0.0)
    assert op.voltage == 6.0
    (tab,) = s.steady_tables
    np.testing.assert_array_equal(tab.voltage, [2.0, 4.0, 6.0])
    np.testing.assert_array_equal(tab.speed, [10.0, 30.0, 50.0])
    assert tab.current is None
    np.testing.assert_array_equal(tab.load_torque, np.zeros(3))
    assert s.step_readings == () and s.closed_form_options == {} and s.truth is None


def test_trace_in_si(session_dir):
    tr = load_session(session_dir / TOML).trace("step")
    rows = np.array(step_rows())
    assert tr.kind == "step" and tr.file == (session_dir / "step.csv").resolve()
    assert tr.n == STEP_N and tr.dt == pytest.approx(STEP_DT, rel=1e-9)
    np.testing.assert_allclose(tr.time, rows[:, 0], rtol=0, atol=1e-12)
    # speed was written in rpm with 3 decimals
    np.testing.assert_allclose(tr.speed, rows[:, 1] * RPM, rtol=0, atol=0.0005 * RPM)
    assert tr.speed[-1] == pytest.approx(STEP_FINAL_RPM * RPM, rel=1e-3)
    np.testing.assert_allclose(tr.current, rows[:, 2], rtol=0, atol=5e-5)
    assert not tr.voltage_logged and not tr.load_logged
    np.testing.assert_array_equal(tr.voltage.times, [0.0, 0.1])
    np.testing.assert_array_equal(tr.voltage.at(np.array([0.0, 0.09, 0.1, 1.0])),
                                  [0.0, 0.0, 6.0, 6.0])
    # no load given: zero load from the first sample on
    np.testing.assert_array_equal(tr.load_torque.at(tr.time), np.zeros(STEP_N))
    assert tr.initial == "rest"


def test_trace_units_apply_to_schedules(session_dir):
    toml = session_dir / TOML
    replace_once(toml, 'speed = "speed_rpm"', 'speed = "w"')  # its header names rpm
    lines = (session_dir / "step.csv").read_text().splitlines()
    (session_dir / "step.csv").write_text("\n".join([lines[0].replace("speed_rpm", "w"),
                                                     *lines[1:]]) + "\n")
    replace_once(toml, 'time = "s", speed = "rpm", current = "A", voltage = "V"',
                 'time = "ms", speed = "rad/s", current = "mA", voltage = "mV", '
                 'load_torque = "mN*m"')
    replace_once(toml, SCHEDULE, "voltage = [[0.0, 0.0], [1.0, 6000.0]]\n"
                 "load_torque = [[0.0, 0.0], [1.2, 20.0]]\n"
                 "initial = { current = 50.0, speed = 3.0 }")
    tr = load_session(session_dir).trace("step")
    np.testing.assert_allclose(tr.time[:3], [0.0, 1e-5, 2e-5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(tr.voltage.times, [0.0, 1e-3], rtol=1e-15)
    np.testing.assert_allclose(tr.voltage.values, [0.0, 6.0], rtol=1e-15)
    np.testing.assert_allclose(tr.load_torque.times, [0.0, 1.2e-3], rtol=1e-15)
    np.testing.assert_allclose(tr.load_torque.values, [0.0, 0.02], rtol=1e-15)
    assert tr.initial == pytest.approx((0.05, 3.0), rel=1e-15)
    assert tr.current[0] == pytest.approx(step_rows()[0][2] * 1e-3, rel=1e-3)


def test_logged_input_columns_are_zero_order_hold_schedules(session_dir):
    toml = session_dir / TOML
    replace_once(toml, '"ia" }', '"ia", voltage = "Va", load_torque = "TL" }')
    replace_once(toml, SCHEDULE, 'initial = "steady"')
    lines = (session_dir / "step.csv").read_text().splitlines()
    lines = [lines[0] + ",Va,TL"] + [f"{row},6.0,1.0" for row in lines[1:]]
    (session_dir / "step.csv").write_text("\n".join(lines) + "\n")
    tr = load_session(session_dir).trace("step")
    assert tr.voltage_logged and tr.load_logged and tr.initial == "steady"
    np.testing.assert_array_equal(tr.voltage.times, tr.time)
    np.testing.assert_array_equal(tr.voltage.values, np.full(STEP_N, 6.0))
    np.testing.assert_array_equal(tr.load_torque.values, np.full(STEP_N, 1.0))


def test_a_schedule_changes_where_its_value_does():
    """A logged column holds one breakpoint per sample: only a new value is a change."""
    held = Schedule(np.arange(7) * 0.5, np.array([0.0, 0.0, 6.0, 6.0, 6.0, -6.0, -6.0]))
    np.testing.assert_array_equal(held.change_times(), [1.0, 2.5])
    assert Schedule(np.zeros(1), np.array([3.0])).change_times().size == 0
    assert Schedule(np.arange(3.0), np.full(3, 2.0)).change_times().size == 0


def test_free_form_kind_and_optional_current(session_dir):
    toml = session_dir / TOML
    replace_once(toml, 'kind = "step"', 'kind = "ramp test, day 2"')
    replace_once(toml, ', current = "ia" }', " }")
    tr = load_session(session_dir).trace("step")
    assert tr.kind == "ramp test, day 2" and tr.current is None


def test_blank_lines_skipped_and_line_numbers_stay_physical(session_dir):
    csv = session_dir / "step.csv"
    lines = csv.read_text().splitlines()
    lines.insert(3, "")  # a blank line 4; the old line 4 is now line 5
    lines[4] = "0.02,oops,0.5"
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(SessionError) as info:
        load_session(session_dir)
    assert info.value.where == "line 5" and info.value.path == csv
    assert "'oops'" in str(info.value)


def test_options_friction_duty_percent_and_step_reading(session_dir):
    toml = session_dir / TOML
    replace_once(toml, 'friction = "viscous"', 'friction = "coulomb"')
    replace_once(toml, "duty = 0.5", "duty = 50")
    replace_once(toml, 'current = "A", speed = "rad/s"',
                 'current = "mA", speed = "rpm", duty = "%"')
    text = toml.read_text() + (
        "\n[closed_form]\nK_decimals = 3\n\n[bench.J]\nvalue = 2.0\nunit = \"g*cm^2\"\n"
        "sd = 0.1\n\n[[step_reading]]\nname = \"fig\"\nvoltage = 12.97\nfinal_speed = 1590\n"
        "tau = 1160\nunits = { final_speed = \"rpm\", tau = \"ms\" }\n")
    toml.write_text(text)
    s = load_session(session_dir)
    assert s.friction == "coulomb" and s.closed_form_options == {"K_decimals": 3}
    op = s.operating_points[0]
    assert op.duty == pytest.approx(0.5, rel=1e-15)
    assert op.current == pytest.approx(3e-4, rel=1e-15)
    assert op.speed == pytest.approx(100.0 * RPM, rel=1e-15)
    (sr,) = s.step_readings
    assert sr.tau == pytest.approx(1.16, rel=1e-15)
    assert sr.final_speed == pytest.approx(1590 * RPM, rel=1e-15) and sr.initial_speed == 0.0


def test_truth_json(session_dir):
    truth = {"Ra": 2.0, "La": 1.5e-3, "K": 0.05, "B": 1e-5, "J": 1e-4, "Tc": 2e-3}
    (session_dir / "truth.json").write_text(json.dumps(dict(truth, note="ignored")))
    assert load_session(session_dir).truth == truth
    # a rig's true values are kept when they are numbers
    rig = {"Vdrop": 0.8, "dead_time": 2e-3}
    (session_dir / "truth.json").write_text(json.dumps(dict(truth, **rig, flag=True,
                                                            huge=1e301)))
    assert load_session(session_dir).truth == dict(truth, **rig)


def test_session_error_attributes(tmp_path):
    with pytest.raises(SessionError) as info:
        load_session(tmp_path)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.path == tmp_path / TOML and err.where is None
    assert str(err).startswith(f"{tmp_path / TOML}: file not found;")


def test_paper_session():
    path = bundled_session_dir("paper")
    s = load_session(path)
    assert s.name == "paper" and s.motor == "Paper rig PMDC motor"
    assert s.Ra.value == 8.5 and s.La.value == pytest.approx(5.621e-3, rel=1e-15)
    assert s.closed_form_options == {"K_decimals": 3}
    assert s.traces == ()  # the paper published no raw traces
    (op,) = s.operating_points
    assert (op.supply_voltage, op.duty, op.current, op.speed) == (24.0, 0.7, 0.22, 240.86)
    table2, figure7 = s.steady_tables
    np.testing.assert_array_equal(table2.voltage, [6.49, 7.78, 9.08, 10.38, 11.67, 12.97])
    np.testing.assert_array_equal(table2.speed,
                                  [74.61, 94.09, 113.57, 133.52, 154.57, 172.47])
    np.testing.assert_array_equal(figure7.voltage, [12.97] * 3)
    np.testing.assert_allclose(figure7.speed, np.array([1590.0, 1150.0, 750.0]) * RPM,
                               rtol=1e-15)
    np.testing.assert_array_equal(figure7.load_torque, [0.0, 0.01, 0.02])
    (fig4,) = s.step_readings
    assert (fig4.voltage, fig4.tau) == (12.97, 1.1598)  # printed 1.16; see session.toml
    assert fig4.final_speed == pytest.approx(166.5, abs=0.05)
    again = load_session(path / TOML)  # the session.toml path works as well as the directory
    assert again.name == "paper" and again.root == s.root and again.Ra == s.Ra


def test_model_table_declares_the_nuisances_to_fit(session_dir):
    assert load_session(session_dir).nuisances == ()
    toml = session_dir / "session.toml"
    text = toml.read_text(encoding="utf-8")
    toml.write_text(text + "\n[model]\nvoltage_drop = true\ndead_time = true\n", encoding="utf-8")
    assert load_session(session_dir).nuisances == ("dead_time", "voltage_drop")
    toml.write_text(text + "\n[model]\nvoltage_drop = 1\n", encoding="utf-8")
    with pytest.raises(SessionError, match=r"model\.voltage_drop: expected true or false"):
        load_session(session_dir)
    toml.write_text(text + "\n[model]\ndead_time = 1\n", encoding="utf-8")
    with pytest.raises(SessionError, match=r"model\.dead_time: expected true, false, "
                       r"\"per_trace\" or \"shared\", got"):
        load_session(session_dir)
    toml.write_text(text + "\n[model]\nbrush_drop = true\n", encoding="utf-8")
    with pytest.raises(SessionError, match="unknown key 'brush_drop'"):
        load_session(session_dir)


def test_a_current_limit_is_fitted_free_or_around_the_drivers_setting(session_dir):
    toml = session_dir / "session.toml"
    text = toml.read_text(encoding="utf-8")
    toml.write_text(text + "\n[model]\ncurrent_limit = true\n", encoding="utf-8")
    s = load_session(session_dir)
    assert s.nuisances == ("current_limit",) and s.current_limit_setting is None
    toml.write_text(text + "\n[model]\ncurrent_limit = 2.5\n", encoding="utf-8")
    s = load_session(session_dir)
    assert s.nuisances == ("current_limit",) and s.current_limit_setting == 2.5
    for bad in ("-1.0", "0", '"2 A"'):
        toml.write_text(text + f"\n[model]\ncurrent_limit = {bad}\n", encoding="utf-8")
        with pytest.raises(SessionError, match=r"model\.current_limit: expected true, false "
                           r"or the driver's limit in A"):
            load_session(session_dir)


def test_a_known_speed_dependent_drag_is_read_in_si(session_dir):
    replace_once(session_dir / "session.toml", 'voltage = [[0.0, 0.0], [0.1, 6.0]]',
                 'voltage = [[0.0, 0.0], [0.1, 6.0]]\ndrag = { constant = 0.01, viscous = 2e-5 }')
    tr = load_session(session_dir).traces[0]
    assert tr.drag == Drag(0.01, 2e-5) and not tr.drag.curved


def test_a_negative_or_empty_drag_names_the_key(session_dir):
    toml = session_dir / "session.toml"
    replace_once(toml, 'voltage = [[0.0, 0.0], [0.1, 6.0]]',
                 'voltage = [[0.0, 0.0], [0.1, 6.0]]\ndrag = { viscous = -1e-5 }')
    with pytest.raises(SessionError, match=r"drag\.viscous.*must be >= 0"):
        load_session(session_dir)
    replace_once(toml, 'drag = { viscous = -1e-5 }', 'drag = {}')
    with pytest.raises(SessionError, match="constant = "):
        load_session(session_dir)
