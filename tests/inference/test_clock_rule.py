"""A failing channel of a trace whose rows a loop's clock stamps without setting their
pace: the diagnosis says how much a tick's error in time moves its readings against its
noise, so that a misfit the stamps alone can make is not read as the motor's."""

from types import SimpleNamespace

import numpy as np

from pmdc_bayes.inference.adequacy.clock_rule import clock_rules
from pmdc_bayes.inference.adequacy.findings import Check, Finding, Severity
from pmdc_bayes.io.channel import ChannelId


def _loop_times(tick, n=110, seed=1):
    """A loop of 10 ms and up to 0.8 ms of work a pass, stamped by a clock of ``tick``."""
    t = np.r_[0.0, np.cumsum(0.010 + np.random.default_rng(seed).uniform(0.0, 8e-4, n))]
    return np.floor(t / tick + 1e-9) * tick


def _model(time, tau, noise=0.005, seed=2, rise=False):
    """A trace whose current decays from 6 A with time constant ``tau`` after a step at
    0.2 s (or rises to 6 A from 0 with it), read with white noise ``noise``."""
    rng = np.random.default_rng(seed)
    after = np.exp(-np.clip(time - 0.2, 0.0, None) / tau)
    i = np.where(time < 0.2, 0.0, 6.0 * (1.0 - after if rise else after))
    tr = SimpleNamespace(name="step", time=time, speed=np.zeros(time.size),
                         speed_logged=False, current=i + noise * rng.standard_normal(i.size),
                         position=None)
    return SimpleNamespace(session=SimpleNamespace(traces=[tr]))


def _failing(signal):
    return [Finding(Check.STEP_START, ChannelId("step", signal), Severity.FAIL, "large",
                    "the model misses the start of the voltage steps")]


def test_a_failing_current_stamped_by_a_loops_millisecond_clock_is_said_to_be_the_stamps():
    """τ 25 ms: at its fastest the current falls 240 A/s, so a tick of 1 ms (sd 0.29 ms)
    moves a reading by about 0.07 A, some 14 times its 5 mA noise."""
    (said,) = clock_rules(_model(_loop_times(1e-3), 0.025), _failing("current"))
    assert said.startswith("step: its rows are stamped to 1 ms")
    moved = float(said.split("moves it by ")[1].split(" A")[0])
    assert 0.03 < moved < 0.1  # 240 A/s at most (less between samples 10 ms apart) × 0.29 ms


def test_nothing_is_said_where_the_stamps_cannot_make_the_misfit():
    """A microsecond clock, a steady rate, a channel that passes, or a current so slow a
    tick moves it by less than its noise (no jump at the step): nothing to say.  A jump
    between two samples is fast however slow the rest: a reading stamped before it may
    have been read after it."""
    assert clock_rules(_model(_loop_times(1e-6), 0.025), _failing("current")) == []
    steady = np.arange(110) * 0.010
    assert clock_rules(_model(steady, 0.025), _failing("current")) == []
    assert clock_rules(_model(_loop_times(1e-3), 0.025), _failing("speed")) == []
    assert clock_rules(_model(_loop_times(1e-3), 30.0, rise=True), _failing("current")) == []
    assert clock_rules(_model(_loop_times(1e-3), 30.0), _failing("current")) != []
