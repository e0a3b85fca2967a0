"""Benches as they log their drive and their shaft: a voltage logged as a PWM duty (a
fraction, a percentage or counts of the timer's full scale) of a stated supply, and a
gearmotor measured at its output shaft (``[motor] gear_ratio``).  Each is read into the
same SI session as the bundled demo (simulated on the bench simulator) written in volts
at the motor shaft; a duty or ratio that makes no sense is one line naming the key."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import replace_once

from pmdc_bayes.io.loader import load_session

DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"
RATIO = 19.2


@pytest.fixture
def demo(tmp_path) -> Path:
    d = tmp_path / "demo"
    shutil.copytree(DEMO, d)
    (d / "truth.json").unlink()
    return d


def _scale_column(path: Path, column: str, factor: float) -> None:
    header, *rows = path.read_text().splitlines()
    k = header.split(",").index(column)
    out = [header]
    for row in rows:
        cells = row.split(",")
        cells[k] = repr(float(cells[k]) * factor)
        out.append(",".join(cells))
    path.write_text("\n".join(out) + "\n")


def _with_voltage_column(d: Path, name: str, volts_to_cell) -> None:
    """The demo's 13 V step written as a logged voltage column, each cell
    ``volts_to_cell(V)``."""
    path = d / f"{name}.csv"
    header, *rows = path.read_text().splitlines()
    out = [header + ",u"]
    for row in rows:
        volts = 12.97 if float(row.split(",")[0]) >= 0.5 else 0.0
        out.append(f"{row},{volts_to_cell(volts)}")
    path.write_text("\n".join(out) + "\n")
    replace_once(d / "session.toml", 'columns = { time = "t", speed = "speed", current = "ia" }\n'
                 'units = { time = "s", speed = "rpm", current = "A", voltage = "V", '
                 'load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 12.97]]',
                 'columns = { time = "t", speed = "speed", current = "ia", voltage = "u" }\n'
                 'units = { time = "s", speed = "rpm", current = "A", voltage = "V", '
                 'load_torque = "N*m" }')


def _same_session(a, b, rtol=1e-12):
    for ta, tb in zip(a.traces, b.traces, strict=True):
        np.testing.assert_allclose(ta.speed, tb.speed, rtol=rtol, atol=0)
        np.testing.assert_allclose(ta.voltage.values, tb.voltage.values, rtol=rtol, atol=0)
        np.testing.assert_allclose(ta.load_torque.values, tb.load_torque.values, rtol=rtol,
                                   atol=0)
        np.testing.assert_array_equal(ta.voltage.times, tb.voltage.times)
    for pa, pb in zip(a.operating_points, b.operating_points, strict=True):
        assert pa.speed == pytest.approx(pb.speed, rel=rtol)
        assert pa.voltage == pytest.approx(pb.voltage, rel=rtol)
    for sa, sb in zip(a.steady_tables, b.steady_tables, strict=True):
        np.testing.assert_allclose(sa.speed, sb.speed, rtol=rtol, atol=0)


def test_a_gearmotor_logged_at_its_output_is_read_at_the_motor_shaft(demo):
    for name in ("step_12v97", "step_6v49", "load_change", "current_capture"):
        _scale_column(demo / f"{name}.csv", "speed", 1 / RATIO)
    _scale_column(demo / "table2.csv", "w", 1 / RATIO)
    toml = demo / "session.toml"
    replace_once(toml, "speed = 241.6106288", f"speed = {241.6106288 / RATIO!r}")
    replace_once(toml, "load_torque = [[0, 0], [27, 0.01], [54, 0.02]]",
                 f"load_torque = [[0, 0], [27, {0.01 * RATIO!r}], [54, {0.02 * RATIO!r}]]")
    replace_once(toml, 'friction = "coulomb"', f'friction = "coulomb"\ngear_ratio = {RATIO}')
    geared, plain = load_session(demo), load_session(DEMO)
    assert geared.gear_ratio == RATIO and plain.gear_ratio == 1.0
    _same_session(geared, plain)
    # the output shaft's numbers were really different: the test compares converted values
    assert np.max(load_session(DEMO).traces[0].speed) > 10 * np.max(
        np.loadtxt(demo / "step_12v97.csv", delimiter=",", skiprows=1)[:, 1]) * 2 * np.pi / 60


@pytest.mark.parametrize("unit, extra, cell", [
    ("%", "", lambda v: repr(v / 24.0 * 100.0)),
    ("1", "", lambda v: repr(v / 24.0)),
    ("pwm", "pwm_full_scale = 255\n", lambda v: repr(v / 24.0 * 255.0)),
])
def test_a_voltage_logged_as_a_duty_is_the_supply_times_the_duty(demo, unit, extra, cell):
    plain = demo.parent / "plain"
    shutil.copytree(demo, plain)
    _with_voltage_column(plain, "step_12v97", repr)
    _with_voltage_column(demo, "step_12v97", cell)
    text = (demo / "session.toml").read_text()
    head, tail = text.split('name = "step_12v97"', 1)
    tail = tail.replace('voltage = "V"', f'voltage = "{unit}"', 1)
    (demo / "session.toml").write_text(
        head + f'name = "step_12v97"\nsupply_voltage = 24.0\n{extra}' + tail)
    duty, volts = load_session(demo), load_session(plain)
    assert duty.traces[0].voltage_logged
    assert np.max(duty.traces[0].voltage.values) == pytest.approx(12.97, rel=1e-12)
    _same_session(duty, volts)


def test_a_duty_column_that_moves_at_every_sample_is_read_as_written(demo):
    """A controller's output logged as its duty (a speed loop's command, new at every
    sample) is the voltage the driver applied: not a noisy reading to be levelled."""
    moves = iter(np.random.default_rng(0).normal(0.0, 0.3, 10**6))
    _with_voltage_column(demo, "step_12v97", lambda v: repr(float(v + next(moves)) / 24.0))
    text = (demo / "session.toml").read_text()
    head, tail = text.split('name = "step_12v97"', 1)
    (demo / "session.toml").write_text(head + 'name = "step_12v97"\nsupply_voltage = 24.0\n'
                                       + tail.replace('voltage = "V"', 'voltage = "1"', 1))
    tr = load_session(demo).traces[0]
    assert tr.voltage.se is None and tr.voltage.times.size == tr.time.size


def test_a_duty_schedule_is_read_the_same_way(demo):
    toml = demo / "session.toml"
    replace_once(toml, 'voltage = "V", load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 12.97]]',
                 'voltage = "%", load_torque = "N*m" }\nsupply_voltage = 24\n'
                 f'voltage = [[0, 0], [0.5, {12.97 / 24 * 100!r}]]')
    _same_session(load_session(demo), load_session(DEMO))


def _closed_form(pmdc, d):
    return pmdc("closed-form", d, timeout=120)


OLD = 'voltage = "V", load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 12.97]]'


@pytest.mark.parametrize("new, field, fix", [
    ('voltage = "%", load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 54]]',
     "supply_voltage", "supply_voltage = 12.0"),
    (OLD + "\nsupply_voltage = 24", "supply_voltage", "units.voltage"),
    ('voltage = "%", load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 130]]\n'
     "supply_voltage = 24", "voltage", "beyond full scale"),
    ('voltage = "pwm", load_torque = "N*m" }\nvoltage = [[0, 0], [0.5, 130]]\n'
     "supply_voltage = 24", "pwm_full_scale", "pwm_full_scale"),
], ids=["duty without supply", "supply without duty", "over full scale", "pwm without scale"])
def test_a_duty_that_cannot_be_read_is_one_line_naming_the_key(demo, new, field, fix, pmdc):
    replace_once(demo / "session.toml", OLD, new)
    r = _closed_form(pmdc, demo)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert "session.toml" in lines[0] and field in lines[0] and fix in lines[0]


def test_a_gear_ratio_that_is_not_positive_is_refused(demo, pmdc):
    replace_once(demo / "session.toml", 'friction = "coulomb"', 'friction = "coulomb"\n'
                 "gear_ratio = -5")
    r = _closed_form(pmdc, demo)
    assert r.returncode == 2 and "gear_ratio" in r.stderr and "positive" in r.stderr


def test_every_quantity_at_the_output_shaft_is_moved_to_the_motor_shaft():
    """Speeds and angles times the ratio, torques divided by it, a drag T(ω_out) as
    T(ω/n)/n at the motor shaft (its viscous part over n², quadratic over n³)."""
    import dataclasses

    from pmdc_bayes.io import gear
    from pmdc_bayes.io.drag import Drag
    from pmdc_bayes.io.session import Schedule, SteadyTable, StepReading, Trace

    n = 12.5
    drag = Drag(constant=0.02, viscous=1e-3, quadratic=2e-5, curve=((0.0, 0.0), (10.0, 0.05)))
    moved = gear.motor_shaft_drag(drag, n)
    for w_out in (0.5, 3.0, 9.0):  # the same power at either shaft: T_m·ω_m = T_out·ω_out
        t_out = drag.constant + drag.viscous * w_out + drag.quadratic * w_out**2
        t_m = moved.constant + moved.viscous * n * w_out + moved.quadratic * (n * w_out) ** 2
        assert t_m * n * w_out == pytest.approx(t_out * w_out, rel=1e-12)
    assert moved.curve == ((0.0, 0.0), (10.0 * n, 0.05 / n))
    tr = Trace(name="t", kind="step", file=Path("t.csv"), time=np.arange(3.0),
               speed=np.array([0.0, 1.0, 2.0]), current=None,
               voltage=Schedule(np.zeros(1), np.ones(1)),
               load_torque=Schedule(np.zeros(1), np.array([0.3])), initial=(0.1, 2.0),
               position=np.array([0.0, 0.5, 1.5]), encoder_step=0.01, drag=drag)
    m = gear.motor_shaft_trace(tr, n)
    np.testing.assert_allclose(m.speed, tr.speed * n)
    np.testing.assert_allclose(m.position, tr.position * n)
    assert m.encoder_step == pytest.approx(0.01 * n)
    assert m.initial == (0.1, pytest.approx(2.0 * n))  # (current, speed)
    assert m.load_torque.values[0] == pytest.approx(0.3 / n)
    assert m.drag == moved
    coast = dataclasses.replace(tr, kind="coast-down", position=None, drag=Drag())
    assert gear.motor_shaft_trace(coast, n).position is None
    tab = SteadyTable("s", Path("s.csv"), np.ones(2), np.array([10.0, 20.0]), None,
                      np.array([0.0, 0.4]))
    mt = gear.motor_shaft_table(tab, n)
    np.testing.assert_allclose(mt.speed, tab.speed * n)
    np.testing.assert_allclose(mt.load_torque, tab.load_torque / n)
    sr = gear.motor_shaft_reading(StepReading("r", 6.0, 30.0, 0.2, 5.0), n)
    assert (sr.final_speed, sr.initial_speed, sr.tau) == (30.0 * n, 5.0 * n, 0.2)
