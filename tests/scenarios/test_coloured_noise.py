"""Coloured noise (``coloured_noise``): a channel's errors as AR(1).  The whitened
likelihood against the AR(1) Gaussian density written out in full; a step of the
independent bench simulator (LSODA) read through a sensor whose noise is correlated
from sample to sample: the ideal model rejected with coloured noise proposed, the model
with it adequate with its correlation and K found; the search choosing it, and not
choosing it over a dead time the noise does not explain."""

import csv
import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest
from conftest import SMALL_MOTOR, plan, step

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.coloured import ar_name, previous_index, start_residuals
from pmdc_bayes.inference.model.noise import NU0
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Session
from pmdc_bayes.search import search_model
from pmdc_bayes.simulate.session import simulate_session

RHO = 0.9

BENCH = {"Ra": (0.05, "ohm"), "La": (0.1, "mH")}

def _plan(dead_time: float, white: float) -> dict:
    return plan(seed=3, motor="a tachometer through a filter", truth=SMALL_MOTOR, bench=BENCH,
                rig={"dead_time": dead_time},
                traces=({"name": "steps", "kind": "step", "duration": 0.6, "rate": 2000.0,
                         "voltage": [[0.0, 0.0], [0.01, 6.0], [0.3, 2.0]],
                         "record_current": False, "speed_noise": white},))


def _session(tmp_path, *, ar_sd=0.0, white=0.3, dead_time=0.0, seed=11):
    """The plan drawn by the bench simulator, then AR(1) noise of marginal sd ``ar_sd``
    added to its logged speed (as a filtering sensor would)."""
    root = simulate_session(_plan(dead_time, white), tmp_path / "s")
    if ar_sd > 0:
        path = root / "steps.csv"
        rows = list(csv.reader(path.read_text().splitlines()))
        head, data = rows[0], np.array(rows[1:], float)
        j = head.index("speed")
        rng = np.random.default_rng(seed)
        e = np.zeros(len(data))
        w = rng.standard_normal(len(data)) * ar_sd * np.sqrt(1 - RHO**2)
        e[0] = rng.standard_normal() * ar_sd
        for k in range(1, len(e)):
            e[k] = RHO * e[k - 1] + w[k]
        data[:, j] += e
        with path.open("w", newline="") as fh:
            out = csv.writer(fh)
            out.writerow(head)
            out.writerows([[f"{v:.10g}" for v in row] for row in data])
    return load_session(root)


def test_previous_readings_skip_a_missed_one_and_restart_each_record():
    observed = np.array([True, True, False, True, True, True, True])
    first = np.array([True, False, False, False, False, True, False])
    pos = np.array([0, 1, 2, 3, 5, 6, 7])  # a padded slot at 4
    prev = previous_index(observed, first, pos, (8,))
    assert prev.tolist() == [-1, 0, -1, -1, -1, 3, -1, 6]


def test_start_residual_is_the_whitening_jacobian_and_smooth_at_zero(jax_x64):
    rho = jnp.asarray([0.0, 1e-5, 0.5, -0.9, 0.99])
    r = np.asarray(start_residuals(rho, jnp.full(5, 3.0)))
    np.testing.assert_allclose(-0.5 * r**2, 1.5 * np.log1p(-np.asarray(rho) ** 2),
                               rtol=1e-9, atol=1e-15)


@x64
def test_the_whitened_likelihood_is_the_ar1_density_written_out(tmp_path):
    """The model's log-likelihood plus its whitening Jacobian equals the AR(1)
    Gaussian density (covariance ρ^|i−j|/(1−ρ²) per contiguous run of readings, a
    missed reading starting a new run) with each channel's noise level integrated out
    as the objective integrates it."""
    rng = np.random.default_rng(0)
    t = np.arange(400) / 1000.0
    w = 100.0 * (1 - np.exp(-t / 0.03)) + rng.standard_normal(t.size)
    i = 1.0 * np.exp(-t / 0.03) + 0.01 * rng.standard_normal(t.size)
    Session.from_arrays(
        Ra=(2.0, 0.05), La=(2e-3, 2e-4),
        traces={"step": {"time": t, "speed": w, "current": i, "voltage": 6.0,
                         "initial": "rest"}},
        model={"coloured_noise": True}, directory=tmp_path / "s")
    [path] = (tmp_path / "s").glob("*.csv")
    rows = list(csv.reader(path.read_text().splitlines()))
    rows[151][rows[0].index("speed")] = ""  # a missed reading
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    session = load_session(tmp_path / "s")
    model = build_model(session, fit_seed(session))
    names = list(model.names)
    theta = np.asarray(model.theta_seed()).copy()
    rhos = {ChannelId("step", "speed"): 0.7, ChannelId("step", "current"): -0.4}
    for channel, rho in rhos.items():
        theta[names.index(ar_name(channel))] = np.arctanh(rho)
    theta = jnp.asarray(theta)
    n_reg = len(names)
    model_ll = float(model.log_likelihood(theta)
                     - 0.5 * jnp.sum(model.prior_residuals(theta)[n_reg:] ** 2))
    raw = model._parts(theta, model.data, whitened=False)
    pointwise = model.pointwise_log_likelihood(theta)
    direct = 0.0
    for c, ch in enumerate(model.channels):
        if ch.n == 0:
            continue
        r, m, chan = next((r, m, k) for r, m, k in raw
                          if np.any(np.asarray(m) & (np.asarray(k) == c)[:, None]))
        r = np.asarray(r)[np.asarray(m) & (np.asarray(chan) == c)[:, None]]
        rho = rhos.get(ch.id, 0.0)
        runs = [r[:150], r[150:]]  # either side of the missed reading (its row left out)
        q, logdet = 0.0, 0.0
        for e in runs:
            k = np.arange(e.size)
            cov = rho ** np.abs(k[:, None] - k[None, :]) / (1 - rho**2)
            q += float(e @ np.linalg.solve(cov, e))
            logdet += float(np.linalg.slogdet(cov)[1])
        direct += -0.5 * (ch.n + NU0) * np.log(NU0 * ch.s0**2 + q) - 0.5 * logdet
        # each reading's density (LOO's) at the channel's fitted level: together the
        # AR(1) Gaussian density of the runs
        var = (NU0 * ch.s0**2 + q) / (ch.n + NU0)
        joint = -0.5 * (ch.n * np.log(2 * np.pi * var) + logdet + q / var)
        assert float(np.sum(np.asarray(pointwise[c]))) == pytest.approx(joint, rel=1e-10)
    assert model_ll == pytest.approx(direct, rel=1e-10)


@x64
def test_white_channels_read_the_same_with_their_correlation_at_zero(tmp_path):
    session = _session(tmp_path)
    plain = build_model(session, fit_seed(session))
    coloured = build_model(dataclasses.replace(session, nuisances=("coloured_noise",)),
                           fit_seed(session))
    theta = np.asarray(plain.theta_seed())
    full = jnp.asarray(np.concatenate([theta, [0.0]]))
    assert float(coloured.log_likelihood(full)) == pytest.approx(
        float(plain.log_likelihood(jnp.asarray(theta))), rel=1e-12)


def test_a_filtering_sensor_is_rejected_as_white_and_fitted_as_coloured(tmp_path):
    session = _session(tmp_path, ar_sd=6.0)
    cf = fit_seed(session)
    model = build_model(session, cf)
    ideal = assess(model, fit_map(model), cf)
    assert ideal.verdict == "inadequate"
    assert ("coloured_noise", "steps") in [(p.nuisance, p.trace) for p in ideal.proposals]
    s = dataclasses.replace(session, nuisances=("coloured_noise",))
    cf = fit_seed(s)
    model = build_model(s, cf)
    fit = fit_map(model)
    assert assess(model, fit, cf).verdict == "adequate"
    phi = fit.values[ar_name(ChannelId("steps", "speed"))]
    assert abs(phi - np.arctanh(RHO)) < 3 * fit.sd[ar_name(ChannelId("steps", "speed"))]
    assert abs(fit.values["K"] - 0.05) < 3 * fit.sd["K"]


@pytest.mark.compiles
def test_the_search_takes_coloured_noise_where_it_is_and_a_dead_time_where_that_is(tmp_path):
    coloured = search_model(_session(tmp_path / "ar", ar_sd=6.0))
    assert coloured["terms"] == ["coloured_noise:steps"], coloured["candidates"]
    assert coloured["model"] == {"coloured_noise": ["steps"]}
    delayed = search_model(_session(tmp_path / "dt", dead_time=0.004, white=0.3))
    assert "dead_time" in delayed["terms"], delayed["candidates"]
    assert not any(t.startswith("coloured_noise") for t in delayed["terms"])


def test_coloured_noise_names_its_traces_and_refuses_others(tmp_path):
    from pmdc_bayes._errors import SessionError
    from pmdc_bayes.terms import model_table, terms_of

    t = np.arange(200) / 1000.0
    rng = np.random.default_rng(1)

    def trace():
        return {"time": t, "speed": 50.0 * (1 - np.exp(-t / 0.02)) + rng.standard_normal(t.size),
                "voltage": 6.0, "initial": "rest"}

    session = Session.from_arrays(Ra=(2.0, 0.05), traces={"a": trace(), "b": trace()},
                                  model={"coloured_noise": ["b"]})
    model = build_model(session, fit_seed(session))
    ar = [n for n in model.names if n.startswith("noise_ar")]
    assert ar == [ar_name(ChannelId("b", "speed"))]
    assert terms_of(session) == {"coloured_noise:b"}
    assert model_table(session, terms_of(session))[0] == {"coloured_noise": ["b"]}
    with pytest.raises(SessionError, match="coloured_noise"):
        Session.from_arrays(Ra=(2.0, 0.05), traces={"a": trace()},
                            model={"coloured_noise": ["c"]})


def test_the_simulators_coloured_speed_noise_has_its_correlation_and_sd(tmp_path):
    from pmdc_bayes.simulate.plan import check_plan
    from pmdc_bayes.simulate.session import sample_trace

    plan = _plan(0.0, 2.0)
    del plan["rig"]
    tr = plan["trace"][0]
    tr.update(duration=5.0, rate=1000.0, voltage=[[0.0, 6.0]], initial="steady",
              speed_noise_correlation=0.9)
    spec = check_plan(plan)
    steady = sample_trace(spec.truth, spec.traces[0], seed=5)["speed"]
    e = steady - np.median(steady)
    assert abs(np.std(e) / 2.0 - 1.0) < 0.15
    assert abs(np.corrcoef(e[1:], e[:-1])[0, 1] - 0.9) < 0.03
    tr["speed_noise_correlation"] = 1.0
    with pytest.raises(Exception, match="speed_noise_correlation"):
        check_plan(plan)


def test_a_quantised_channels_row_records_white_noise():
    from pmdc_bayes.inference.adequacy.trace_checks import channel_tests

    rng = np.random.default_rng(2)
    yhat = np.linspace(0.0, 50.0, 400)
    y = 0.5 * np.round((yhat + 0.2 * rng.standard_normal(400)) / 0.5)
    row, _, _ = channel_tests(ChannelId("t", "speed"), y, yhat, None, 0.2, 0.2, rng, quantum=0.5)
    assert row["noise_correlation"] == 0.0


def test_coloured_noise_with_only_quantised_readings_is_refused():
    """A speed on a logger's lattice has nothing coloured noise could fit: asked for in
    the session or with ``add``, it is bad input naming why, not a model without it."""
    import pmdc_bayes
    from pmdc_bayes._errors import SessionError, UsageError

    t = np.arange(300) / 1000.0
    rng = np.random.default_rng(4)
    speed = 0.5 * np.round((50.0 * (1 - np.exp(-t / 0.02))
                            + 0.3 * rng.standard_normal(t.size)) / 0.5)
    trace = {"time": t, "speed": speed, "voltage": 6.0, "initial": "rest"}
    with pytest.raises(SessionError, match="coloured_noise.*quantis"):
        Session.from_arrays(Ra=(2.0, 0.05), traces={"a": trace},
                            model={"coloured_noise": True})
    session = Session.from_arrays(Ra=(2.0, 0.05), traces={"a": trace})
    with pytest.raises(UsageError, match="coloured_noise.*quantis"):
        pmdc_bayes.fit(session, add="coloured_noise", mcmc=False)
    analogue = dict(trace, speed=speed + 0.01 * rng.standard_normal(t.size))
    coloured = Session.from_arrays(Ra=(2.0, 0.05), traces={"a": analogue},
                                   model={"coloured_noise": True})
    assert coloured.coloured_noise_traces() == ("a",)


def test_a_search_may_add_coloured_noise_on_traces_the_session_does_not_name():
    """Coloured noise named on one trace, that trace held out: the search's universe still
    holds coloured noise on the others (each trace with an analogue channel)."""
    from pmdc_bayes.supersets import Supersets
    from pmdc_bayes.terms import NOISE, terms_of

    t = np.arange(200) / 1000.0
    rng = np.random.default_rng(3)

    def trace():
        return {"time": t, "speed": 50.0 * (1 - np.exp(-t / 0.02)) + rng.standard_normal(t.size),
                "voltage": 6.0, "initial": "rest"}

    session = Session.from_arrays(Ra=(2.0, 0.05), traces={n: trace() for n in "abc"},
                                  model={"coloured_noise": ["a"]}).without_traces(["a"])
    universe = Supersets(session, terms_of(session), free_friction=False).universe
    assert {NOISE + "b", NOISE + "c"} <= universe


def test_holding_out_the_only_trace_coloured_noise_names_is_bad_input():
    import pmdc_bayes
    from pmdc_bayes._errors import UsageError

    t = np.arange(200) / 1000.0
    rng = np.random.default_rng(5)
    traces = {n: {"time": t, "voltage": 6.0, "initial": "rest",
                  "speed": 50.0 * (1 - np.exp(-t / 0.02)) + rng.standard_normal(t.size)}
              for n in "ab"}
    session = Session.from_arrays(Ra=(2.0, 0.05), traces=traces,
                                  model={"coloured_noise": ["a"]})
    with pytest.raises(UsageError, match="holdout a.*coloured_noise"):
        pmdc_bayes.fit(session, holdout="a", mcmc=False)


_FILTERED = {"record_current": False, "speed_noise": 2.0, "speed_noise_correlation": 0.9}
SIBLINGS = plan(seed=8, motor="one tachometer through a filter on every trace",
                truth=SMALL_MOTOR, bench=BENCH,
                traces=({"name": "long", "kind": "step", "duration": 0.6, "rate": 2000.0,
                         "voltage": [[0.0, 0.0], [0.01, 6.0], [0.3, 2.0]], **_FILTERED},
                        step("short", 4.0, duration=0.08, rate=2000.0, at=0.005, **_FILTERED)))


@pytest.mark.compiles
def test_coloured_noise_taken_on_one_trace_is_tried_on_the_others(tmp_path):
    """One filtering sensor logs both traces; one trace's correlated errors alone may
    pass the misfit check (here the long one's: without the mend the search took
    coloured noise on the short trace only).  Once the search takes coloured noise on
    one trace it tries it on the other, and the chosen model holds it on both."""
    from pmdc_bayes.search import run_search

    root = simulate_session(SIBLINGS, tmp_path / "s")
    found = run_search(load_session(root), seed=0)
    terms = set(found.record["terms"])
    assert {"coloured_noise:long", "coloured_noise:short"} <= terms, found.record["terms"]
    assert found.chosen.adequacy.verdict == "adequate"


def test_a_holdout_naming_no_trace_is_refused_before_the_search(monkeypatch):
    """A session that leaves its model to the search: a ``--holdout`` naming no trace is
    bad input at once, not after the search has fitted its candidates."""
    import pmdc_bayes
    import pmdc_bayes.search
    from pmdc_bayes._errors import UsageError

    def searched(*a, **k):
        raise AssertionError("the search ran before the holdout was checked")

    monkeypatch.setattr(pmdc_bayes.search, "run_search", searched)
    t = np.arange(200) / 1000.0
    trace = {"time": t, "voltage": 6.0, "initial": "rest", "speed": 50.0 * (1 - np.exp(-t / 0.02))}
    session = Session.from_arrays(Ra=(2.0, 0.05), traces={"a": trace, "b": trace})
    with pytest.raises(UsageError, match="holdout 'c' names no trace; traces are: a, b"):
        pmdc_bayes.fit(session, holdout="c", mcmc=False)
