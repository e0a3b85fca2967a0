"""A steady sampling rate stamped by a coarse clock (an Arduino's ``millis()`` at a few
hundred hertz): its rows are read at the steady rate's times, not at the stamps' rounding;
stamps of a rate that itself varies, or of a fine clock, are read as written, and the
clock's tick (``clock_tick``) is what the former's times are uncertain by."""

import numpy as np
import pytest

from pmdc_bayes.io.lattice import clock_tick
from pmdc_bayes.io.loader import load_session

NAME = "tr0_up_down.csv"


@pytest.fixture
def logged(up_down_session):
    """A bench-simulator session of one up-down trace, its samples at a steady rate."""
    return up_down_session


def _restamped(src, dst, stamps, unit="ms", every=4):
    """``src`` with every ``every``-th row of its trace kept, each stamped by
    ``stamps(t)`` (t its time in s) in ``unit``."""
    dst.mkdir()
    for f in src.iterdir():
        if f.name != NAME:
            (dst / f.name).write_bytes(f.read_bytes())
    head, *rows = (src / NAME).read_text().splitlines()
    rows = rows[::every]
    t = np.array([float(r.split(",")[0]) for r in rows])
    out = [head] + [",".join([s, *r.split(",")[1:]]) for s, r in zip(stamps(t), rows,
                                                                      strict=True)]
    (dst / NAME).write_text("\n".join(out) + "\n")
    toml = (src / "session.toml").read_text()
    (dst / "session.toml").write_text(toml.replace('units = { time = "s",',
                                                   f'units = {{ time = "{unit}",', 1))
    return t


@pytest.mark.parametrize("comment", [False, True])
def test_millisecond_stamps_of_a_steady_rate_read_at_its_times(logged, tmp_path, comment):
    """Rows 2.2 ms apart from 1.3 ms on, stamped in whole milliseconds, are each up to
    0.5 ms off: read at the line they round, each within a few microseconds of its time
    (the first too), a comment line among the rows leaving no gap in the rate."""
    t = _restamped(logged, tmp_path / "ms", lambda t: [str(round(x * 1e3 + 1.3)) for x in t])
    if comment:
        f = tmp_path / "ms" / NAME
        lines = f.read_text().splitlines()
        f.write_text("\n".join([*lines[:300], "# a note the logger wrote", *lines[300:]])
                     + "\n")
    got = load_session(tmp_path / "ms").traces[0].time
    true = t + 1.3e-3
    assert np.max(np.abs(np.round(true * 1e3) / 1e3 - true)) > 4e-4  # the stamps' rounding
    assert np.max(np.abs(got - true)) < 5e-5
    assert clock_tick(got) == 0.0  # a steady rate's times, known to far better than a tick


def test_stamps_strewn_more_than_a_clock_s_rounding_are_read_as_written(logged, tmp_path):
    """Samples up to 0.7 ms about a steady rate's times, on a millisecond clock: their
    stamps stray from its line by more than the clock's rounding, so they are the
    times."""
    rng = np.random.default_rng(4)
    n = len((logged / NAME).read_text().splitlines()[1::6])
    stamps = np.round(np.arange(n) * 3.3 + 5.0 + rng.uniform(-0.7, 0.7, n)).astype(int)
    _restamped(logged, tmp_path / "strewn", lambda t: [str(s) for s in stamps], every=6)
    got = load_session(tmp_path / "strewn").traces[0].time
    np.testing.assert_array_equal(got, stamps * 1e-3)
    assert clock_tick(got) == pytest.approx(1e-3)


def test_seconds_written_to_the_millisecond_read_at_the_steady_rate_too(logged, tmp_path):
    t = _restamped(logged, tmp_path / "s3", lambda t: [f"{x:.3f}" for x in t], unit="s")
    got = load_session(tmp_path / "s3").traces[0].time
    assert np.max(np.abs(got - t)) < 2e-5
    assert clock_tick(got) == 0.0


def test_stamps_of_a_rate_that_varies_are_read_as_written(logged, tmp_path):
    """A loop timed by the same clock samples 2 or 3 ms apart as it happens: the stamps
    are the times, and stray from any straight line by far more than half a millisecond."""
    rng = np.random.default_rng(3)
    n = len((logged / NAME).read_text().splitlines()[1::4])
    stamps = np.cumsum(rng.choice([2, 3], size=n)) - 2
    _restamped(logged, tmp_path / "loop", lambda t: [str(s) for s in stamps])
    got = load_session(tmp_path / "loop").traces[0].time
    np.testing.assert_array_equal(got, stamps * 1e-3)
    assert clock_tick(got) == pytest.approx(1e-3)


def test_fine_stamps_are_read_as_written(logged, tmp_path):
    t = _restamped(logged, tmp_path / "fine", lambda t: [repr(float(x)) for x in t],
                   unit="s")
    got = load_session(tmp_path / "fine").traces[0].time
    np.testing.assert_array_equal(got, t)
    assert clock_tick(got) == 0.0


def test_seconds_since_1970_to_the_microsecond_are_read_as_written(logged, tmp_path):
    """A computer's clock (``time.time()``) written to the microsecond: at 1.76e9 s the
    stamps' resolution cannot be told from their rounding as numbers, and a loop's
    jitter is its times: no line is put through them."""
    rng = np.random.default_rng(5)
    n = len((logged / NAME).read_text().splitlines()[1::4])
    stamps = 1.7648e9 + np.cumsum(2.2e-3 + rng.normal(0.0, 2e-4, n))
    _restamped(logged, tmp_path / "epoch", lambda t: [f"{s:.6f}" for s in stamps], unit="s")
    got = load_session(tmp_path / "epoch").traces[0].time
    written = np.array([float(f"{s:.6f}") for s in stamps])
    np.testing.assert_allclose(np.diff(got), np.diff(written), rtol=0, atol=1e-6)
    assert clock_tick(got) == 0.0  # a resolution its rounding as numbers cannot show
    assert np.std(np.diff(got)) > 1e-4
