"""Position and encoder-edge traces as read from files: angle units, counts, one row
per edge with a direction bit, wrapping time counters, and the one-line errors."""

import math

import numpy as np
import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session

HEAD = """\
[motor]
name = "encoder motor"
[bench.Ra]
value = 2.0
unit = "ohm"
sd = 0.05
"""


def _write(root, trace_toml, csv_text, extra=""):
    root.mkdir(parents=True, exist_ok=True)
    (root / "session.toml").write_text(HEAD + extra + "[[trace]]\n" + trace_toml)
    (root / "t.csv").write_text(csv_text)
    return root


def _angles(n=50, step=3.0):
    return [(k * 0.01, k * step) for k in range(n)]


def test_a_position_column_in_degrees_is_read_in_radians_with_a_speed_estimate(tmp_path):
    csv = "t,deg\n" + "".join(f"{t:.2f},{a:.1f}\n" for t, a in _angles())
    s = load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", position = "deg" }\n'
                            'units = { position = "deg" }\nvoltage = [[0.0, 6.0]]\n'
                            'initial = "steady"\n', csv))
    tr = s.traces[0]
    assert not tr.speed_logged and tr.encoder_step == 0.0
    np.testing.assert_allclose(tr.position[5], math.radians(15.0))
    # 3 degrees per 10 ms is 300 deg/s: the estimate from the angle says so
    np.testing.assert_allclose(tr.speed, math.radians(300.0), rtol=1e-9)


def test_counts_become_radians_through_counts_per_rev(tmp_path):
    csv = "t,n\n" + "".join(f"{t:.2f},{int(a)}\n" for t, a in _angles())
    s = load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", position = "n" }\n'
                            'units = { position = "counts" }\ncounts_per_rev = 400\n'
                            'voltage = [[0.0, 6.0]]\n', csv))
    tr = s.traces[0]
    assert tr.encoder_step == pytest.approx(2 * math.pi / 400)
    np.testing.assert_allclose(tr.position[10], 30 * 2 * math.pi / 400)


def test_counts_without_counts_per_rev_name_the_key(tmp_path):
    csv = "t,n\n" + "".join(f"{t:.2f},{int(a)}\n" for t, a in _angles())
    with pytest.raises(SessionError, match="counts_per_rev"):
        load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", position = "n" }\n'
                            'units = { position = "counts" }\nvoltage = [[0.0, 6.0]]\n', csv))


def _edges_toml(extra=""):
    return (f'name = "e"\nkind = "step"\nfile = "t.csv"\ncolumns = {{ time = "us"{extra} }}\n'
            'units = { time = "us" }\nedges = true\ncounts_per_rev = 100\n'
            'voltage = [[1000.0, 0.0], [2000.0, 12.0]]\n')


def test_edges_give_one_count_per_row_after_an_unread_start_at_rest(tmp_path):
    times = [3000 + 400 * k for k in range(20)]
    csv = "us\n" + "".join(f"{t}\n" for t in times)
    tr = load_session(_write(tmp_path / "s", _edges_toml(), csv)).traces[0]
    q = 2 * math.pi / 100
    assert tr.n == 21 and tr.time[0] == pytest.approx(1000e-6)
    assert np.isnan(tr.position[0])
    np.testing.assert_allclose(tr.position[1:], q * np.arange(1, 21))
    assert tr.speed[0] == 0.0
    np.testing.assert_allclose(tr.speed[5:-5], q / 400e-6)


def test_a_direction_column_counts_backward_edges(tmp_path):
    times = [3000 + 400 * k for k in range(10)]
    dirs = [1, 1, 1, 1, 0, 0, -1, 1, 1, 1]
    csv = "us,dir\n" + "".join(f"{t},{d}\n" for t, d in zip(times, dirs, strict=True))
    tr = load_session(_write(tmp_path / "s", _edges_toml(', direction = "dir"'), csv)).traces[0]
    q = 2 * math.pi / 100
    # the boundaries crossed: back over 4, 3 and 2, then forward over 2, 3 and 4 again
    np.testing.assert_allclose(tr.position[1:] / q, [1, 2, 3, 4, 4, 3, 2, 2, 3, 4])


def test_a_wrapping_microsecond_counter_is_unwrapped(tmp_path):
    wrap = 2**16
    times = [(60000 + 1000 * k) % wrap for k in range(12)]  # wraps after 5 edges
    csv = "us\n" + "".join(f"{t}\n" for t in times)
    toml = _edges_toml().replace("voltage = [[1000.0, 0.0], [2000.0, 12.0]]",
                                 "voltage = [[50000.0, 0.0], [55000.0, 12.0]]")
    toml += f"time_wrap = {wrap}\n"
    tr = load_session(_write(tmp_path / "s", toml, csv)).traces[0]
    np.testing.assert_allclose(np.diff(tr.time[1:]), 1e-3)
    assert tr.time[-1] == pytest.approx((60000 + 11000) * 1e-6)


@pytest.mark.parametrize("toml_edit, csv_text, words", [
    (lambda t: t, "us,dir\n3000,2\n3400,1\n3800,1\n", None),
    (lambda t: t.replace("[[1000.0, 0.0], [2000.0, 12.0]]", "[[3000.0, 12.0]]"),
     "us\n3000\n3400\n3800\n", "before the first edge"),
    (lambda t: t + "time_wrap = 1000\n", "us\n3000\n3400\n3800\n", "time_wrap"),
    (lambda t: t.replace("counts_per_rev = 100\n", ""), "us\n3000\n3400\n3800\n",
     "counts_per_rev"),
    (lambda t: t.replace('columns = { time = "us"', 'columns = { time = "us", speed = "us"'),
     "us\n3000\n3400\n3800\n",
     "one row per encoder edge"),
    (lambda t: t.replace("edges = true", "edges = 1"), "us\n3000\n3400\n3800\n", "true or false"),
    # a wrapping microsecond timer logged without time_wrap: the fix names it
    (lambda t: t, "us\n4294966000\n4294966900\n300\n1200\n",
     "add time_wrap = 4294967296"),
    # a schedule written from 0 while the edges carry the counter's clock
    (lambda t: t, "us\n4294000000\n4294000400\n4294000800\n", "not on the time column's clock"),
])
def test_bad_encoder_input_is_one_line_naming_the_fix(tmp_path, toml_edit, csv_text, words):
    extra = ', direction = "dir"' if "dir" in csv_text else ""
    with pytest.raises(SessionError) as err:
        load_session(_write(tmp_path / "s", toml_edit(_edges_toml(extra)), csv_text))
    text = str(err.value)
    assert "\n" not in text
    assert (words or "direction 2") in text


def test_a_trace_needs_a_speed_a_position_or_edges(tmp_path):
    csv = "t,i\n0,0\n0.1,1\n0.2,2\n"
    with pytest.raises(SessionError, match="no speed or position column"):
        load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", current = "i" }\nvoltage = [[0.0, 6.0]]\n',
                            csv))


def test_a_direction_column_without_edges_is_refused(tmp_path):
    csv = "t,w,d\n0,1,1\n0.1,2,1\n0.2,3,1\n"
    with pytest.raises(SessionError, match="edges = true"):
        load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", speed = "w", direction = "d" }\n'
                            'voltage = [[0.0, 6.0]]\n', csv))


@pytest.mark.parametrize(("key", "words"), [
    ("speed_lag", "no trace logs a speed"), ("speed_gain", "counted angle"),
    ("speed_offset", "no trace logs a speed"),
    ("current_lag", "no driven trace logs a current"),
    ("current_offset", "no driven trace logs a current")])
def test_a_sensor_nuisance_with_no_such_sensor_is_refused(tmp_path, key, words):
    """An encoder trace's angle is counted, not read through a speed sensor: a speed lag,
    gain or offset (or a current sensor's, with no current) would fit a parameter the
    likelihood never sees."""
    times = [3000 + 400 * k for k in range(20)]
    csv = "us\n" + "".join(f"{t}\n" for t in times)
    root = _write(tmp_path / "s", _edges_toml(), csv, extra=f"[model]\n{key} = true\n")
    with pytest.raises(SessionError) as info:
        load_session(root)
    text = str(info.value)
    assert f"model.{key}" in text and words in text and "remove it" in text
    assert "\n" not in text


def test_add_of_a_sensor_nuisance_with_no_such_sensor_is_bad_input(tmp_path, pmdc):

    times = [3000 + 400 * k for k in range(20)]
    root = _write(tmp_path / "s", _edges_toml(), "us\n" + "".join(f"{t}\n" for t in times))
    proc = pmdc("fit", root, "--no-mcmc", "--add", "speed-lag", "--out", tmp_path / "run",
                timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert "--add speed-lag: no trace logs a speed" in proc.stderr
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "run").exists()


def _wrapping(tmp_path, counts, extra=""):
    csv = "t,n\n" + "".join(f"{k * 0.01:.2f},{c}\n" for k, c in enumerate(counts))
    return _write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                  'columns = { time = "t", position = "n" }\nunits = { position = "counts" }\n'
                  'counts_per_rev = 400\nvoltage = [[0.0, 6.0]]\ninitial = "steady"\n' + extra,
                  csv)


@pytest.mark.parametrize("offset,signed", [(65000, False), (32500, True), (-400, True)])
def test_a_16_bit_position_counter_that_wraps_reads_as_the_angle_it_counted(tmp_path, offset,
                                                                            signed):
    """A timer counting encoder edges in 16 bits, unsigned (0 ... 65535) or signed
    (-32768 ... 32767), wrapping forward, or backward through zero."""
    true = [offset + 90 * k for k in range(40)]
    low, span = (-32768, 65536) if signed else (0, 65536)
    logged = [(c - low) % span + low for c in true]
    assert logged != true or offset < 0
    tr = load_session(_wrapping(tmp_path, logged, "position_wrap = 65536\n")).traces[0]
    np.testing.assert_allclose(tr.position, (np.array(true) - true[0] + logged[0])
                               * 2 * math.pi / 400)


@pytest.mark.parametrize("modulus,step,n,unit", [
    (65536, 90, 40, "counts"),  # a 16-bit timer, wrapping once
    (65536, 2900, 100, "counts"),  # ... four times
    (4096, 130, 100, "counts"),  # a 12-bit absolute sensor: steps of 3 % of a turn
    (360, 11.5, 100, "deg"),  # an angle in degrees within a turn
])
def test_a_position_that_wraps_unstated_names_the_fix(tmp_path, modulus, step, n, unit):
    logged = [round((modulus - 3 * step + step * k) % modulus, 3) for k in range(n)]
    csv_unit = f'units = {{ position = "{unit}" }}\n'
    root = _wrapping(tmp_path, logged)
    toml = root / "session.toml"
    toml.write_text(toml.read_text().replace('units = { position = "counts" }\n', csv_unit))
    with pytest.raises(SessionError, match=rf"about {modulus} {unit}, and stays within that "
                                           rf"range: a sensor or counter that wraps; add "
                                           rf"position_wrap = {modulus}"):
        load_session(root)


@pytest.mark.parametrize("logged", [
    [int(300 * math.sin(k / 6.0)) for k in range(40)],  # steps of a few dozen counts
    [int(round(125 * math.sin(1.3 * k))) + 125 for k in range(40)],  # within 2^8, steps
])  # beyond half of it that no wrap explains (a quarter of it from a whole turn at least)
def test_a_position_that_turns_and_comes_back_is_not_taken_for_a_wrap(tmp_path, logged):
    assert load_session(_wrapping(tmp_path, logged)).traces[0].position is not None


def test_a_position_wrap_without_a_position_column_is_one_line(tmp_path):
    csv = "t,w\n" + "".join(f"{k * 0.01:.2f},{10.0 + k}\n" for k in range(10))
    with pytest.raises(SessionError, match="position_wrap: is only read with a position column"):
        load_session(_write(tmp_path / "s", 'name = "p"\nkind = "step"\nfile = "t.csv"\n'
                            'columns = { time = "t", speed = "w" }\nposition_wrap = 65536\n'
                            'voltage = [[0.0, 6.0]]\ninitial = "steady"\n', csv))


def _differenced(counts, dt=0.01, unit_scale=1.0, jitter=None):
    """A speed column: each interval's counts (of 2π/400 rad) over its length, times
    ``unit_scale`` (rad/s → the column's unit), the first row 0."""
    t = np.arange(len(counts)) * dt + (0.0 if jitter is None else jitter)
    w = np.concatenate([[0.0], np.diff(counts) * (2 * math.pi / 400) / dt]) * unit_scale
    return "t,w\n" + "".join(f"{a:.6f},{b:.10g}\n" for a, b in zip(t, w, strict=True))


_SPEED_TOML = ('name = "d"\nkind = "step"\nfile = "t.csv"\n'
               'columns = { time = "t", speed = "w" }\nunits = { speed = "rpm" }\n'
               'counts_per_rev = 400\nvoltage = [[0.0, 6.0]]\ninitial = "steady"\n')


@pytest.mark.parametrize("jitter", [None, "logger"])
def test_a_speed_differenced_from_counts_is_read_as_the_counted_angle(tmp_path, jitter):
    """Counts 0, 3, 7, 10, ... differenced over 10 ms and logged in rpm, with
    counts_per_rev: the trace reads the angle they add up to (one count 2π/400), not the
    speed; with a logger's jittered time stamps and its division by the nominal
    interval, the same."""
    counts = np.cumsum(np.r_[0, np.tile([3, 4, 3], 20)])
    shake = None if jitter is None else np.random.default_rng(1).uniform(-1e-4, 1e-4,
                                                                        counts.size)
    tr = load_session(_write(tmp_path / "s", _SPEED_TOML,
                             _differenced(counts, unit_scale=60 / (2 * math.pi),
                                          jitter=shake))).traces[0]
    assert not tr.speed_logged
    assert tr.encoder_step == pytest.approx(2 * math.pi / 400)
    np.testing.assert_allclose(tr.position, counts * 2 * math.pi / 400, atol=1e-12)


@pytest.mark.parametrize("counts, rows, words", [
    (np.r_[0.0, 3.0, 6.5, 10.0, 13.0], None, "row 3's speed times its interval is 3.5 counts"),
    (np.arange(0.0, 90.0, 3.0), (3,), "rows left out break (row"),
])
def test_a_speed_that_is_no_differenced_count_is_refused_with_counts_per_rev(tmp_path, counts,
                                                                            rows, words):
    csv = _differenced(counts, unit_scale=60 / (2 * math.pi))
    if rows:  # a row with no speed: the loader leaves it out
        lines = csv.splitlines()
        lines[rows[0] + 1] = lines[rows[0] + 1].split(",")[0] + ","
        csv = "\n".join(lines) + "\n"
    with pytest.raises(SessionError) as err:
        load_session(_write(tmp_path / "s", _SPEED_TOML, csv))
    assert "\n" not in str(err.value) and "counts_per_rev" in str(err.value)
    assert words in str(err.value)


def _loop_logged(rng, speed_at, n=120, tick_ms=1.0):
    """An Arduino loop's log: each pass ~10 ms plus up to 0.6 ms of work, the encoder's
    counts (of 2π/400 rad) over the pass's own interval (``micros()``) written as a
    speed in rad/s, the row stamped with ``millis()`` (the true time floored to
    ``tick_ms``); the rotor turning at ``speed_at(t)`` rad/s.  Returns the CSV text,
    the true times (s) and the counts."""
    t = np.r_[0.0, np.cumsum(0.010 + rng.uniform(0.0, 6e-4, n - 1))]
    fine = np.linspace(0.0, t[-1], 20001)
    w = speed_at(fine)
    angle = np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(fine))]
    q = 2 * math.pi / 400
    counts = np.floor(np.interp(t, fine, angle) / q + 1e-9)
    speed = np.r_[0.0, np.diff(counts) * q / np.diff(t)]
    stamps = np.floor(t * 1e3 / tick_ms) * tick_ms
    text = "ms,w\n" + "".join(f"{a:g},{b:.6f}\n" for a, b in zip(stamps, speed, strict=True))
    return text, t, counts


_LOOP_TOML = _SPEED_TOML.replace('units = { speed = "rpm" }', 'units = { time = "ms" }')
_LOOP_TOML = _LOOP_TOML.replace('time = "t"', 'time = "ms"')


def test_a_speed_divided_by_an_interval_the_log_does_not_hold_is_read_as_its_angle(tmp_path):
    """Counts over each loop's own ``micros()`` interval, stamped in whole milliseconds:
    whole against no logged or nominal interval, the speed is read as the angle it
    integrates over the logged intervals, which is the counted angle at the stamps: at
    each row within a count and the distance one millisecond turns (the stamps'
    rounding) of the counts at the true times; the nominal interval instead would be
    3 % (the loop's mean work) off by the end."""
    csv, t, counts = _loop_logged(np.random.default_rng(4),
                                  lambda s: 300.0 * (1.0 - np.exp(-s / 0.08)))
    tr = load_session(_write(tmp_path / "s", _LOOP_TOML, csv)).traces[0]
    q = 2 * math.pi / 400
    assert not tr.speed_logged and tr.encoder_step == pytest.approx(q)
    miss = np.abs(tr.position - (counts - counts[0]) * q)
    assert np.max(miss) < q + 2 * 300.0 * 1e-3
    assert np.max(miss) > 0.0  # not on the counts' lattice: the intervals are not logged
    nominal = np.r_[0.0, np.cumsum(np.diff(counts) * q / np.diff(t) * 0.010)]
    assert np.max(np.abs(nominal - (counts - counts[0]) * q)) > 10 * (q + 2 * 300.0 * 1e-3)


@pytest.mark.parametrize("at_rest", [True, False])
def test_a_measured_speed_declared_as_counts_over_unlogged_intervals_is_refused(tmp_path,
                                                                               at_rest):
    """A tachometer's speed (noise of 0.3 rad/s) stamped in whole milliseconds with
    counts_per_rev declared: at rest its readings are no whole count over any interval a
    millisecond from the logged one (a count needs 157 rad/s over 10 ms); turning at
    2 rad/s neither (a count there takes 79 ms)."""
    rng = np.random.default_rng(2)
    n = 60
    w = (0.0 if at_rest else 2.0) + 0.3 * rng.standard_normal(n)
    csv = "ms,w\n" + "".join(f"{10 * k},{b:.4f}\n" for k, b in enumerate(w))
    with pytest.raises(SessionError) as err:
        load_session(_write(tmp_path / "s", _LOOP_TOML, csv))
    assert "\n" not in str(err.value) and "counts_per_rev" in str(err.value)
    assert "two ticks of the time stamps' clock" in str(err.value)


def test_a_cut_last_line_leaves_a_differenced_speed_read(tmp_path):
    """A logger stopped mid-line: the last line a time and no speed (its fields cut),
    left out; no interval's counts lie after it, so the rows before it read as the
    counted angle, where a row missing between two others is refused (above)."""
    counts = np.arange(0.0, 90.0, 3.0)
    csv = _differenced(counts, unit_scale=60 / (2 * math.pi)) + "0.3"
    tr = load_session(_write(tmp_path / "s", _SPEED_TOML, csv)).traces[0]
    assert tr.rows_left_out == (len(counts) + 2,)
    np.testing.assert_allclose(tr.position, counts * 2 * math.pi / 400, atol=1e-12)
