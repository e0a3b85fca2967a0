"""The identifiability findings name each parameter in the coordinates the fit uses:
``log K`` for a positive parameter, the parameter itself for one that may be zero or
negative (a dead time, a sensor offset)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes.inference.fit.undetermined import identifiability

NAMES = ("Ra", "La", "K", "B", "J", "dead_time_step")
STEADY = np.arange(50) * 1e-4  # sample times at a steady rate


def _spec(transform):
    return SimpleNamespace(transform=transform, prior=SimpleNamespace(source="prior"))


def test_a_weak_direction_names_a_dead_time_without_a_log():
    corr = np.eye(6)
    corr[4, 5] = corr[5, 4] = 0.99995  # J and the dead time: their difference is tied
    fit = SimpleNamespace(names=NAMES, corr=corr, cov_log=np.diag([1e-4] * 6),
                          values={"La": 1e-3, "Ra": 2.0})
    model = SimpleNamespace(
        prior_sd=np.ones(6),
        registry={n: _spec("identity" if n == "dead_time_step" else "log") for n in NAMES},
        session=SimpleNamespace(traces=[SimpleNamespace(current=np.zeros(3), dt=1e-4,
                                                        time=STEADY, speed_logged=False)],
                                coast_downs=(), nuisances=()))
    (finding,) = [f for f in identifiability(model, fit)["findings"] if "fix the combination" in f]
    assert "·log J" in finding and "·dead_time_step" in finding
    assert "log dead_time_step" not in finding


def _log_model(names):
    """A Coulomb model of log-transformed parameters with one step trace logging the
    current fast."""
    trace = SimpleNamespace(current=np.zeros(3), dt=1e-4, time=STEADY, kind="step",
                            speed_logged=False,
                            load_torque=SimpleNamespace(values=np.zeros(1)))
    session = SimpleNamespace(traces=[trace], coast_downs=(), nuisances=(),
                              La=SimpleNamespace(source=""))
    return SimpleNamespace(prior_sd=np.ones(len(names)),
                           registry={n: _spec("log") for n in names}, session=session,
                           coulomb=True)


def test_a_tied_combination_is_the_one_the_data_fix_not_one_they_leave_open():
    """Strongly anti-correlated log B and log Tc: the data fix their sum (the
    correlation matrix's near-zero eigenvalue), while each alone trades against the
    other; the pair's correlation is reported with its sign."""
    names = ("Ra", "La", "K", "B", "J", "Tc")
    corr = np.eye(6)
    corr[3, 5] = corr[5, 3] = -0.999
    fit = SimpleNamespace(names=names, corr=corr, cov_log=np.diag([1e-4] * 6),
                          values={"La": 1e-3, "Ra": 2.0})
    model = _log_model(names)
    out = identifiability(model, fit)
    (tied,) = out["tied_combinations"]
    d = tied["direction"]
    assert d["B"] * d["Tc"] > 0 and abs(abs(d["B"]) - abs(d["Tc"])) < 1e-9  # the sum
    # the sum's variance, in standard units, is what the eigenvalue measures: tiny
    v = np.array([d[n] for n in names])
    assert v @ corr @ v / (v @ v) == pytest.approx(tied["eigenvalue"], rel=1e-9)
    assert tied["eigenvalue"] < 0.01
    (text,) = [f for f in out["findings"] if "fix the combination" in f]
    assert "+1.00·log B +1.00·log Tc" in text or "+1.00·log Tc +1.00·log B" in text
    assert any("B and Tc are correlated -1.00" in f for f in out["findings"])


def test_a_tied_combination_is_written_in_the_fits_coordinates():
    """The correlation matrix weighs θ_j/sd_j: with log B known to 0.01 and log Tc to 0.1,
    anti-correlated, the combination fixed is log B + 0.1·log Tc (its variance tiny),
    not log B + log Tc."""
    names = ("Ra", "La", "K", "B", "J", "Tc")
    sd = np.array([0.01, 0.01, 0.01, 0.01, 0.01, 0.1])
    corr = np.eye(6)
    corr[3, 5] = corr[5, 3] = -0.999
    cov = corr * np.outer(sd, sd)
    fit = SimpleNamespace(names=names, corr=corr, cov_log=cov, values={"La": 1e-3, "Ra": 2.0})
    model = _log_model(names)
    (tied,) = identifiability(model, fit)["tied_combinations"]
    c = np.array([tied["direction"][n] for n in names])
    assert c[3] == pytest.approx(1.0) and c[5] == pytest.approx(0.1, rel=1e-6)
    assert c @ cov @ c < 0.01 * cov[3, 3]  # fixed far more tightly than log B alone


def test_a_tied_combination_of_one_visible_part_is_recorded_but_not_worded():
    """log B known to 0.01 and log Tc to 1, anti-correlated: the combination fixed is
    log B + 0.01·log Tc, whose second part is too small to show; it is recorded, but not
    worded as "the combination +1.00·log B", which would name no trade-off."""
    names = ("Ra", "La", "K", "B", "J", "Tc")
    sd = np.array([0.01, 0.01, 0.01, 0.01, 0.01, 1.0])
    corr = np.eye(6)
    corr[3, 5] = corr[5, 3] = -0.999
    fit = SimpleNamespace(names=names, corr=corr, cov_log=corr * np.outer(sd, sd),
                          values={"La": 1e-3, "Ra": 2.0})
    out = identifiability(_log_model(names), fit)
    (tied,) = out["tied_combinations"]
    assert tied["direction"]["Tc"] == pytest.approx(0.01, rel=1e-6)
    assert not [f for f in out["findings"] if "fix the combination" in f]


def _loop_stamps(tick, seed=0, n=120):
    """The times of a loop of 10 ms and up to 0.8 ms of work a pass, each stamped by a
    clock of ``tick`` (truncated, as ``millis()`` and ``micros()`` do)."""
    t = np.r_[0.0, np.cumsum(0.010 + np.random.default_rng(seed).uniform(0.0, 8e-4, n))]
    return np.floor(t / tick + 1e-9) * tick


def _la_fit(traces, sd_la):
    names = ("Ra", "La", "K", "B", "J")
    session = SimpleNamespace(traces=traces, coast_downs=(), nuisances=(),
                              La=SimpleNamespace(source=""))
    model = SimpleNamespace(prior_sd=np.ones(5), registry={n: _spec("log") for n in names},
                            session=session, coulomb=False)
    fit = SimpleNamespace(names=names, corr=np.eye(5), cov_log=np.diag([1e-4] * 5),
                          values={"Ra": 2.0, "La": 1.5e-3, "K": 0.02, "B": 2e-6, "J": 5e-6},
                          sd={"Ra": 0.02, "La": sd_la})
    return identifiability(model, fit)


def _trace(time, current):
    return SimpleNamespace(time=time, current=current, dt=float(np.median(np.diff(time))),
                           kind="step", speed_logged=False, position=None,
                           load_torque=SimpleNamespace(values=np.zeros(1)))


def test_la_read_through_a_coarse_clocks_stamps_is_said_to_carry_their_error():
    """A loop's rows stamped to the millisecond: every row's time may be off by up to a
    tick, which shifts the response τe = La/Ra absorbs, so La (Ra 2 Ω) may be off by up
    to Ra·tick = 2 mH whatever its sd.  Stamped to the microsecond the shift is
    within La's sd; at a steady rate, or where the current La is read from has exact
    times, there is nothing to say."""
    ms = _loop_stamps(1e-3)
    out = _la_fit([_trace(ms, np.zeros(ms.size))], sd_la=1e-5)
    assert out["clock_tick_s"] == pytest.approx(1e-3)
    (said,) = [f for f in out["findings"] if "stamped to" in f]
    assert "stamped to 1 ms" in said and "Ra·tick = 2.0 ×1e-3 H" in said
    assert not [f for f in _la_fit([_trace(ms, np.zeros(ms.size))], sd_la=3e-3)["findings"]
                if "stamped to" in f]  # an sd wider than the stamps' error says it all
    us = _loop_stamps(1e-6)
    assert _la_fit([_trace(us, None)], sd_la=1e-5)["clock_tick_s"] == pytest.approx(1e-6)
    assert not [f for f in _la_fit([_trace(us, None)], sd_la=1e-5)["findings"]
                if "stamped to" in f]
    steady = np.arange(120) * 1e-3
    assert _la_fit([_trace(steady, None)], sd_la=1e-5)["clock_tick_s"] == 0.0
    # a speed-only trace stamped to the millisecond beside a current logged at a steady
    # rate: La is read from the current, whose times are exact
    out = _la_fit([_trace(ms, None), _trace(steady, np.zeros(steady.size))], sd_la=1e-5)
    assert out["clock_tick_s"] == 0.0
    assert not [f for f in out["findings"] if "stamped to" in f]
