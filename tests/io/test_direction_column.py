"""A driver logged by its pins: the PWM duty (or a voltage) as a magnitude and a
direction bit in a column of its own.  Named as ``columns.direction``, the bit signs the
voltage (and a driver's current sense beside it), so a motor driven both ways reads as
the signed columns would; a voltage column that is signed already, a bit that is neither
1, 0 nor -1, or a direction with no voltage column to sign is refused with the field and
the fix."""

import numpy as np
import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.model.reversal import reversed_speed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.robust import difference_sd
from pmdc_bayes.simulate.fuzz import fuzz_session

COLUMNS = 'columns = { time = "t", speed = "speed", current = "ia", voltage = "va" }'
UNITS = 'units = { time = "s", speed = "rad/s", current = "A", voltage = "V"'


@pytest.fixture
def both_ways(up_down_session):
    """An up-down step (to each sign of the voltage) logged with its signed voltage."""
    return up_down_session


def _as_pins(src, dst, *, duty: float | None = None, bit=lambda v: 1 if v >= 0 else 0,
             declare: bool = True, signed: bool = False, name="tr0_up_down.csv",
             sensed: bool = False, tacho: bool = False) -> None:
    """``src``'s session with its voltage column written as a magnitude (a duty in % of
    ``duty`` volts, where given) and a ``dir`` column of ``bit``; with ``sensed``, its
    current as a magnitude too (a driver's current-sense pin); with ``tacho``, its speed
    (a tachometer or a one-channel Hall sensor, which read no direction)."""
    dst.mkdir()
    for f in src.iterdir():
        if f.name != name:
            (dst / f.name).write_bytes(f.read_bytes())
    lines = (src / name).read_text().splitlines()
    head = lines[0].split(",")
    j = head.index("va")
    out = [",".join([*head, "dir"])]
    for line in lines[1:]:
        cells = line.split(",")
        v = float(cells[j])
        m = v if signed else abs(v)
        cells[j] = repr(m / duty * 100.0 if duty else m)
        for column, yes in (("ia", sensed), ("speed", tacho)):
            if yes:
                cells[head.index(column)] = repr(abs(float(cells[head.index(column)])))
        out.append(",".join([*cells, str(bit(v))]))
    (dst / name).write_text("\n".join(out) + "\n")
    toml = (src / "session.toml").read_text()
    assert toml.count(COLUMNS) == 1 and toml.count(UNITS) == 1
    if declare:
        toml = toml.replace(COLUMNS, COLUMNS[:-2] + ', direction = "dir" }')
    if duty:
        toml = toml.replace(UNITS, f"supply_voltage = {duty!r}\n"
                            + UNITS.replace('voltage = "V"', 'voltage = "%"'))
    (dst / "session.toml").write_text(toml)


@pytest.mark.parametrize("duty", [None, 90.0])
def test_a_magnitude_and_its_direction_bit_read_as_the_signed_voltage(both_ways, tmp_path,
                                                                     duty):
    _as_pins(both_ways, tmp_path / "pins", duty=duty)
    want = load_session(both_ways).traces[0].voltage
    got = load_session(tmp_path / "pins").traces[0].voltage
    assert want.values.min() < 0 < want.values.max()
    np.testing.assert_allclose(got.times, want.times)
    np.testing.assert_allclose(got.values, want.values, rtol=1e-9, atol=1e-12)


def test_an_undeclared_direction_is_refused_as_a_reversal_naming_the_column(tmp_path):
    """Without columns.direction a step driven in reverse reads a positive voltage and
    a negative speed, where the steady table turns with its voltage: refused, the
    trace and the fix named."""
    name = "tr0_step_from_rest.csv"
    fuzz_session(5, out=tmp_path / "s", shapes=("step from rest",), trace_current=True)
    want = load_session(tmp_path / "s").traces[0].voltage
    assert want.values.min() < 0 and reversed_speed(load_session(tmp_path / "s")) is None
    _as_pins(tmp_path / "s", tmp_path / "pins", declare=False, name=name)
    found = reversed_speed(load_session(tmp_path / "pins"))
    assert found is not None and found.file.name == name
    assert "name that column columns.direction" in found.why
    _as_pins(tmp_path / "s", tmp_path / "declared", name=name)
    assert reversed_speed(load_session(tmp_path / "declared")) is None


@pytest.mark.parametrize(("kw", "says"), [
    ({"signed": True}, "it is signed already"),
    ({"bit": lambda v: 2 if v >= 0 else 0}, "direction 2 is not 1 (forward)"),
])
def test_a_direction_that_cannot_sign_the_voltage_is_refused(both_ways, tmp_path, kw, says):
    """With the line of the file that shows it."""
    _as_pins(both_ways, tmp_path / "pins", **kw)
    with pytest.raises(SessionError, match="direction") as err:
        load_session(tmp_path / "pins")
    assert says in str(err.value)
    lines = (tmp_path / "pins" / "tr0_up_down.csv").read_text().splitlines()
    cells = lines[int(err.value.where.removeprefix("line ")) - 1].split(",")
    if "signed" in kw:
        assert float(cells[-2]) < 0
    else:
        assert cells[-1] == "2"


def test_a_measured_magnitude_reading_a_little_below_zero_at_rest_is_signed(both_ways,
                                                                           tmp_path):
    """A voltage measured as a magnitude whose zero sits a little below 0 V (an ADC's
    offset, within its noise) is not a signed column."""
    _as_pins(both_ways, tmp_path / "pins")
    csv = tmp_path / "pins" / "tr0_up_down.csv"
    lines = csv.read_text().splitlines()
    noise = np.random.default_rng(3).normal(-0.03, 0.02, len(lines) - 1)
    out = [lines[0]]
    for line, e in zip(lines[1:], noise, strict=True):
        cells = line.split(",")
        cells[-2] = repr(float(cells[-2]) + float(e))
        out.append(",".join(cells))
    csv.write_text("\n".join(out) + "\n")
    assert min(float(c.split(",")[-2]) for c in out[1:]) < 0
    v = load_session(tmp_path / "pins").traces[0].voltage.values
    assert v.min() < -1.0 < 1.0 < v.max()


def test_a_direction_with_no_voltage_column_is_refused(both_ways, tmp_path):
    d = tmp_path / "pins"
    _as_pins(both_ways, d)
    toml = (d / "session.toml").read_text()
    (d / "session.toml").write_text(toml.replace(', voltage = "va", direction = "dir" }',
                                                 ', direction = "dir" }\nvoltage = '
                                                 '[[0.0, 1.0]]'))
    with pytest.raises(SessionError, match="columns.direction") as err:
        load_session(d)
    assert "add columns.voltage" in str(err.value)


@pytest.mark.parametrize("sensed", [True, False])
def test_a_current_sense_beside_the_direction_bit_reads_as_the_signed_current(
        both_ways, tmp_path, sensed):
    """A driver's current-sense pin reads the current's magnitude whichever way it
    drives: beside its direction bit it is signed by it, as the signed current; a current
    sensor that reads both ways (negative readings beyond its offset) is kept as logged."""
    _as_pins(both_ways, tmp_path / "pins", sensed=sensed)
    want = load_session(both_ways).traces[0]
    got = load_session(tmp_path / "pins").traces[0]
    v = want.voltage.at(want.time)
    driven = np.abs(v) > 0.5 * np.abs(v).max()
    assert np.any(want.current[driven & (v < 0)] < 0)  # driven backwards, a negative current
    if not sensed:
        np.testing.assert_array_equal(got.current, want.current)
        return
    agree = np.sign(want.current) == np.sign(v)
    assert agree[driven].mean() > 0.9
    np.testing.assert_allclose(got.current[driven & agree], want.current[driven & agree],
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(np.abs(got.current), np.abs(want.current), rtol=1e-9,
                               atol=1e-12)


@pytest.mark.parametrize("declare", [True, False])
def test_a_speed_read_as_a_magnitude_is_signed_where_the_rotor_turns(both_ways, tmp_path,
                                                                    declare):
    """A tachometer that reads no direction, beside a direction bit or a signed voltage:
    the rotor turns the way it was first driven and takes each new direction where it
    turned round (its slowest reading between the two drives), as the signed speed; a
    speed that reads both ways is kept as logged."""
    _as_pins(both_ways, tmp_path / "pins", tacho=True, signed=not declare, declare=declare)
    want = load_session(both_ways).traces[0]
    got = load_session(tmp_path / "pins").traces[0]
    v = want.voltage.at(want.time)
    assert np.any(want.speed[v < 0] < -0.5 * np.abs(want.speed).max())  # it turns back
    np.testing.assert_allclose(np.abs(got.speed), np.abs(want.speed), rtol=1e-12)
    clear = np.abs(want.speed) > 10 * difference_sd(want.speed)
    assert clear.sum() > 0.5 * clear.size
    np.testing.assert_array_equal(np.sign(got.speed[clear]), np.sign(want.speed[clear]))
    _as_pins(both_ways, tmp_path / "signed", declare=declare, signed=not declare)
    np.testing.assert_array_equal(load_session(tmp_path / "signed").traces[0].speed,
                                  want.speed)


def _negated(src, dst, name):
    """``src`` driven the other way: the trace ``name``'s voltage, speed and current
    negated."""
    dst.mkdir()
    for f in src.iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    head, *rows = (src / name).read_text().splitlines()
    cols = head.split(",")
    flip = [cols.index(c) for c in ("va", "speed", "ia")]
    out = [head]
    for row in rows:
        cells = row.split(",")
        for j in flip:
            cells[j] = repr(-float(cells[j]))
        out.append(",".join(cells))
    (dst / name).write_text("\n".join(out) + "\n")


@pytest.mark.parametrize("backwards", [False, True])
def test_a_current_sense_at_0_v_reads_the_braking_current(tmp_path, backwards):
    """At 0 V after driving, the driver shorts the armature and the motor, still turning,
    brakes: its current runs against the direction last driven (whatever the bit reads
    at rest: 1 here), and a current sense's magnitude is signed so."""
    name = "tr1_up_down.csv"
    fuzz_session(44, out=tmp_path / "s", shapes=("up-down",), trace_current=True)
    src = tmp_path / "s"
    if backwards:
        _negated(src, tmp_path / "neg", name)
        src = tmp_path / "neg"
    _as_pins(src, tmp_path / "pins", sensed=True, name=name,
             bit=lambda v: 0 if v < 0 else 1)
    want = load_session(src).traces[1]
    got = load_session(tmp_path / "pins").traces[1]
    v = want.voltage.at(want.time)
    sign = -1.0 if backwards else 1.0
    rest = (np.abs(v) < 0.02 * np.abs(v).max()) & (np.cumsum(sign * v > 0) > 0)
    braking = rest & (sign * want.current < -10.0 * difference_sd(want.current))
    assert braking.sum() >= 100 and np.all(sign * v >= 0)
    np.testing.assert_allclose(got.current[braking], want.current[braking], rtol=1e-9)


def test_a_sense_read_below_zero_at_rest_is_still_a_magnitude(both_ways, tmp_path):
    """A current sense zeroed in software reads a little below zero at rest; where the
    motor is driven backwards it reads positive: a magnitude, signed."""
    _as_pins(both_ways, tmp_path / "pins", sensed=True)
    f = tmp_path / "pins" / "tr0_up_down.csv"
    head, *rows = f.read_text().splitlines()
    j = head.split(",").index("ia")
    top = max(abs(float(r.split(",")[j])) for r in rows)
    out = [head]
    for row in rows:
        cells = row.split(",")
        cells[j] = repr(float(cells[j]) - 0.05 * top)
        out.append(",".join(cells))
    f.write_text("\n".join(out) + "\n")
    want = load_session(both_ways).traces[0]
    got = load_session(tmp_path / "pins").traces[0]
    v = want.voltage.at(want.time)
    back = v < -0.5 * np.abs(v).max()
    assert np.median(got.current[back]) < 0 and np.median(want.current[back]) < 0


def test_a_brief_drive_backwards_that_only_slows_the_rotor_keeps_the_speed_as_logged():
    """A voltage below zero for less time than the rotor takes to turn round (a random
    sequence, a sweep about a positive mean, a braking pulse): the logged speed only
    falls there and stays positive, as a signed reading does; nothing is signed."""
    from pmdc_bayes.io._inputs import signed_speed
    from pmdc_bayes.io.session import Schedule

    t = np.arange(0.0, 1.0, 1e-3)
    volts = Schedule(np.array([0.0, 0.1, 0.4, 0.45]), np.array([0.0, 12.0, -6.0, 12.0]))
    w = np.where(t < 0.1, 0.0, 400.0 * (1.0 - np.exp(-(t - 0.1) / 0.05)))
    braked = (t >= 0.4) & (t < 0.47)  # a sensor's lag: the reading slows on a little
    w[braked] = w[braked][0] * np.exp(-(t[braked] - 0.4) / 0.08)  # slows, never turns
    after = t >= 0.47
    w[after] = 400.0 + (w[braked][-1] - 400.0) * np.exp(-(t[after] - 0.47) / 0.05)
    noisy = w + np.random.default_rng(3).normal(0.0, 0.5, t.size)
    load = Schedule(np.array([0.0]), np.array([0.0]))
    kept = signed_speed(noisy, t, {"voltage": volts, "load_torque": load})
    np.testing.assert_array_equal(kept, noisy)
