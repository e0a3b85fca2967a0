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


@pytest.mark.parametrize("pre", [0.02, 0.1, 1.0])
def test_a_coast_down_with_its_pre_trigger_is_refused_naming_opened(session_dir, rng, pre):
    _coast(session_dir, *_pre_triggered(rng, pre))
    with pytest.raises(SessionError, match=r"trace\['coast'\]\.file: the speed falls .* as "
                                           r"much .* as in the same time before.*give "
                                           r"opened = 0 \(the time it was opened, in s\)"):
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
    _coast(session_dir, t0, lagged + rng.normal(0.0, NOISE, t.size), name="lagged")
    assert load_session(session_dir).coast_downs[-1].n == t.size
