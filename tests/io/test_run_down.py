"""A coast-down recorded from before the armature was opened (an oscilloscope's
pre-trigger): refused with the ``opened`` to give, read from it when given; a coasting
rotor's record, from before 0 or from 0 through a lagging sensor, read as written."""

import numpy as np
import pytest

from pmdc_bayes import SessionError
from pmdc_bayes.io.loader import load_session

TOML = "session.toml"
TAU, W0, NOISE = 0.4, 300.0, 0.5  # s, rad/s, rad/s


def _coast(session_dir, t, w, extra="", name="coast"):
    (session_dir / f"{name}.csv").write_text(
        "t,w\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, w, strict=True)))
    with (session_dir / TOML).open("a") as f:
        f.write(f'\n[[trace]]\nname = "{name}"\nkind = "coast-down"\nfile = "{name}.csv"\n'
                f'columns = {{ time = "t", speed = "w" }}\n{extra}')


def _pre_triggered(rng, pre=0.1):
    t = np.round(np.arange(-pre, 2.0, 1e-3), 6)
    w = np.where(t < 0, W0, W0 * np.exp(-np.clip(t, 0, None) / TAU))
    return t, w + rng.normal(0.0, NOISE, t.size)


@pytest.mark.parametrize("pre", [0.02, 0.1, 1.0, 2.0, 3.0])
def test_a_coast_down_with_its_pre_trigger_is_refused_naming_opened(session_dir, rng, pre):
    """Up to a mid-screen trigger and beyond (a record of 2 s after the opening)."""
    _coast(session_dir, *_pre_triggered(rng, pre))
    with pytest.raises(SessionError, match=r"trace\['coast'\]\.file: the speed falls .* as "
                                           r"much .* as in the same time before.*give "
                                           r"opened = (\S+) \(where it began to fall, in s; "
                                           r"0 if the scope triggered on the opening\)") as e:
        load_session(session_dir)
    opened = float(e.value.args[0].split("opened = ")[1].split(" ")[0])
    assert 0.0 <= opened < 0.05  # where it began to fall, by 3 noise sds


def test_opened_is_in_the_trace_s_time_unit_and_within_the_record(session_dir, rng):
    """Opened at 50 ms of a record in ms from -100 ms; rows before it with a missed
    reading are not listed as left out."""
    t, w = _pre_triggered(rng)
    t_ms = np.round(1000.0 * t, 6)
    w = np.where(t < 0.05, W0, W0 * np.exp(-np.clip(t - 0.05, 0, None) / TAU))
    w[5] = np.nan
    _coast(session_dir, t_ms, w, 'units = { time = "ms" }\n')
    with pytest.raises(SessionError, match=r"give opened = (4[5-9]|50)\b.*in ms"):
        load_session(session_dir)
    text = (session_dir / TOML).read_text()
    (session_dir / TOML).write_text(text.replace('units = { time = "ms" }\n',
                                                 'units = { time = "ms" }\nopened = 50\n'))
    coast = load_session(session_dir).coast_downs[0]
    assert coast.time[0] == pytest.approx(0.05) and coast.rows_left_out == ()
    assert coast.n == np.count_nonzero(t_ms >= 50)
    (session_dir / TOML).write_text(text.replace('units = { time = "ms" }\n',
                                                 'units = { time = "ms" }\nopened = 5000\n'))
    with pytest.raises(SessionError, match=r"trace\['coast'\]\.opened: 5000 ms lies outside "
                                           r"the record \(-100 to"):
        load_session(session_dir)


def test_opened_reads_the_coast_down_from_the_time_the_armature_was_opened(session_dir, rng):
    t, w = _pre_triggered(rng)
    _coast(session_dir, t, w, "opened = 0\n")
    coast = load_session(session_dir).coast_downs[0]
    assert coast.time[0] == 0.0 and coast.n == np.count_nonzero(t >= 0)
    np.testing.assert_array_equal(coast.speed, w[t >= 0])


def test_a_coasting_rotor_is_read_as_written(session_dir, rng):
    """From before 0 (a trigger set earlier), with Coulomb friction's steady fall, and
    from 0 through a sensor lag whose reading holds at first (the fit's to find)."""
    t = np.round(np.arange(-0.1, 2.0, 1e-3), 6)
    for name, w in (("viscous", W0 * np.exp(-(t - t[0]) / TAU)),
                    ("coulomb", W0 - 100.0 * (t - t[0]))):
        _coast(session_dir, t, w + rng.normal(0.0, NOISE, t.size), name=name)
        assert load_session(session_dir).coast_downs[-1].n == t.size
    t0 = t - t[0]
    lag = 0.03  # the reading y of a first-order lag τs·dy/dt = ω − y, settled at W0
    lagged = W0 * (np.exp(-t0 / TAU) * TAU - np.exp(-t0 / lag) * lag) / (TAU - lag)
    for name, origin in (("lagged", 0.0), ("lagged_triggered", -1.0)):  # from its start
        _coast(session_dir, t0 + origin, lagged + rng.normal(0.0, NOISE, t.size), name=name)
        assert load_session(session_dir).coast_downs[-1].n == t.size
