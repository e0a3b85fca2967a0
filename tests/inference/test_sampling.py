"""Posterior sampling: reproducibility, -inf for impossible parameters, convergence
gates, recovery of a known motor, the ArviZ record and LOO, derived quantities, and a
negative control (an unidentifiable parameter must fail the gates)."""

import math  # noqa: E402
import re  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import types  # noqa: E402
import warnings  # noqa: E402

import jax
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pmdc_bayes.inference.fit.joint import fit_map  # noqa: E402
from pmdc_bayes.inference.model import objective  # noqa: E402
from pmdc_bayes.inference.sampling.derived import derived_quantities  # noqa: E402
from pmdc_bayes.inference.sampling.idata import _padded_pointwise, lumped  # noqa: E402
from pmdc_bayes.inference.sampling.logprob import LogProb as _LogProb  # noqa: E402
from pmdc_bayes.inference.sampling.moves import SHARE_TRUSTED  # noqa: E402
from pmdc_bayes.inference.sampling.posterior import (  # noqa: E402
    Stop,
    _log_posterior_batch,
    az,
    gates,
    loo_compare,
    sample_posterior,
    summarize,
)
from pmdc_bayes.inference.sampling.rule import PILOT  # noqa: E402
from pmdc_bayes.inference.sampling.stopping import stop_message  # noqa: E402
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.paper.closed_form import ClosedForm, closed_form  # noqa: E402
from pmdc_bayes.simulate.session import simulate_session  # noqa: E402

TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4}
BENCH = {"Ra": {"sd": 0.1, "unit": "ohm"}, "La": {"sd": 0.2, "unit": "mH"}}
CHOPPER = {"name": "chopper", "supply_voltage": 24.0, "duty": 0.7, "speed_sd": 0.5,
           "current_sd": 0.002}
PLAN = {
    "seed": 3,
    "motor": {"name": "Tiny motor", "friction": "viscous"},
    "truth": TRUTH,
    "bench": BENCH,
    "operating_point": [CHOPPER],
    "steady_table": [{"name": "sweep", "voltages": [4.0, 8.0, 12.0], "speed_sd": 0.5,
                      "current_sd": 0.002}],
    # One short step (200 samples) so the model compiles in seconds.
    "trace": [{"name": "step", "kind": "step", "duration": 1.0, "rate": 200.0,
               "voltage": [[0.0, 0.0], [0.05, 12.0]], "initial": "rest",
               "speed_unit": "rad/s", "record_current": True, "speed_noise": 0.3,
               "current_noise": 0.005}],
}
# a fixed length: a rule never met, and no giving up before the cap
QUICK = {"max_steps": 300, "min_tau_multiple": 1e9, "budget": math.inf, "progress": False}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    session = load_session(simulate_session(PLAN, tmp_path_factory.mktemp("tiny") / "s"))
    model = objective.build_model(session, closed_form(session))
    return model, fit_map(model)


# Reproducibility and robustness


def test_same_seed_same_draws_other_seed_other_draws(tiny):
    model, fit = tiny
    a = sample_posterior(model, fit, seed=5, **QUICK)
    b = sample_posterior(model, fit, seed=5, **QUICK)
    c = sample_posterior(model, fit, seed=6, **QUICK)
    np.testing.assert_array_equal(a.draws, b.draws)
    np.testing.assert_array_equal(a.log_prob, b.log_prob)
    assert a.draws.shape == (32, 300 - a.burn_in, 5)
    n = min(a.draws.shape[1], c.draws.shape[1])  # burn-in depends on the τ estimate
    assert not np.any(a.draws[:, -n:] == c.draws[:, -n:])  # continuous: nothing in common
    assert a.capped and "max_steps=300" in a.message and a.stop is Stop.STEP_CAP


def test_a_sampler_out_of_time_stops_with_the_reason_and_a_usable_record(tiny):
    """A time limit stops a run that has not converged (here it never can) between
    chunks, says so and how long it would need, and still returns its draws."""
    model, fit = tiny
    post = sample_posterior(model, fit, seed=5, max_steps=10**6, min_tau_multiple=1e9,
                            budget=math.inf, progress=False, max_seconds=0.5)
    assert post.capped and post.stop is Stop.TIME_LIMIT
    assert "s of sampling (the limit, 0.5 s;" in post.message
    assert "would be needed" in post.message and "--max-sampling-seconds" in post.message
    assert 0 < post.n_steps < 10**6 and post.draws.shape[1] == post.n_steps - post.burn_in
    assert post.idata.posterior.attrs["capped"] == 1
    # the gates fail with the reason first
    passed, failures = gates(summarize(post), posterior=post)
    assert not passed and failures[0].startswith("run capped: stopped after")
    # a run that converges before the limit is the same run without it
    a = sample_posterior(model, fit, seed=5, **QUICK)
    b = sample_posterior(model, fit, seed=5, max_seconds=3600.0, **QUICK)
    np.testing.assert_array_equal(a.draws, b.draws)


def _busy(n: int):
    """``n`` processes spinning on the CPU: a busy machine."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]


def test_the_stop_and_the_draws_do_not_depend_on_the_machines_load(tiny):
    """The same seed gives the same draws, stop, message and verdict on a machine kept
    busy by two spinning processes, with a generous wall-time limit and a larger step
    cap, as on the machine as it is: for a run the rule stops and for one that gives up
    because the rule projects more steps than its budget (50 × τ_max beyond 120 steps),
before the steps the rule needs."""
    model, fit = tiny
    idle = sample_posterior(model, fit, seed=7, progress=False)
    over = sample_posterior(model, fit, seed=7, budget=120, progress=False)
    spinners = _busy(2)
    try:
        busy = sample_posterior(model, fit, seed=7, max_steps=10**6, max_seconds=3600.0,
                                progress=False)
        busy_over = sample_posterior(model, fit, seed=7, max_steps=10**6, budget=120,
                                     max_seconds=3600.0, progress=False)
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    assert idle.stop is Stop.CONVERGED and not idle.capped
    assert over.stop is Stop.OVER_BUDGET and over.n_steps < idle.n_steps
    assert over.message.startswith(f"gave up after {over.n_steps} steps: the chain would "
                                   "need about"), over.message
    for a, b in ((idle, busy), (over, busy_over)):
        np.testing.assert_array_equal(a.draws, b.draws)
        np.testing.assert_array_equal(a.log_prob, b.log_prob)
        assert (a.n_steps, a.burn_in, a.stop, a.message) == \
            (b.n_steps, b.burn_in, b.stop, b.message)
        assert gates(summarize(a), posterior=a) == gates(summarize(b), posterior=b)
    assert gates(summarize(over), posterior=over)[1][0].startswith("run capped: gave up")


def test_the_progress_bar_starts_at_what_the_rule_needs_not_at_the_cap(tiny, capsys):
    model, fit = tiny
    sample_posterior(model, fit, seed=5, max_steps=10**6, progress=True)
    err = capsys.readouterr().err
    totals = [int(t) for t in re.findall(r"\| *\d+/(\d+) \[", err)]
    assert totals and totals[0] <= 300  # the first estimate and one to compare it with
    assert max(totals) < 10**5  # never the cap


def test_a_chain_long_enough_stopped_early_says_what_it_still_lacks(tiny):
    """Stopped at its first check (the pilot's 50 steps) with 1 × τ_max asked for: the
    chain is long enough, so the reason is τ not yet seen to settle, never fewer steps than were
    run."""
    model, fit = tiny
    post = sample_posterior(model, fit, seed=5, max_steps=10**6, min_tau_multiple=1.0,
                            progress=False, max_seconds=0.0)
    assert post.capped and post.n_steps == PILOT
    assert "but τ estimated only once, not yet seen to settle" in post.message, post.message
    assert "would be needed" not in post.message
    kw = {"min_tau_multiple": 50.0, "elapsed": 60.0, "max_seconds": 60.0}
    names = ("Ra", "J")
    settled = stop_message(2000, [3.0, 20.0], names, settled=True, **kw)
    assert "× τ_max long with τ settled (slowest parameter J, τ ≈ 20 steps)" in settled
    assert "not yet at the gates (R-hat ≤ 1.01" in settled and "would be needed" not in settled
    short = stop_message(200, [3.0, 20.0], names, settled=True, **kw)
    assert "about 1000 steps, ~300 s here, would be needed" in short
    capped = stop_message(2000, [3.0, 20.0], names, settled=False, min_tau_multiple=50.0,
                          max_steps=2000)
    assert capped.startswith("stopped at max_steps=2000, the chain 100 × τ_max long but τ "
                             "still changing by more than 5 % between checks")
    assert "--max-sampling-seconds" not in capped


def test_impossible_parameters_have_minus_inf_log_posterior(tiny):
    model, _ = tiny
    batch_fn = _log_posterior_batch(model)
    log_prob = _LogProb(batch_fn, 8, model.registry.is_log())
    theta = np.asarray(model.theta(TRUTH))
    far = np.array([theta + 60.0, theta - 60.0, np.r_[theta[:4], 300.0], np.full(5, 709.0),
                    np.full(5, -745.0)])
    impossible = np.array([np.full(5, 1e3), np.full(5, np.nan), np.full(5, np.inf),
                           np.r_[theta[:4], -np.inf]])
    lp = log_prob(np.concatenate([theta[None], far, impossible]))
    assert np.isfinite(lp[0])
    assert not np.any(np.isnan(lp)) and np.all(lp[1:] < lp[0])  # finite or -inf, lower
    np.testing.assert_array_equal(lp[-4:], np.full(4, -np.inf))

    def broken(_):
        raise RuntimeError("solver failed")

    every_log = np.ones(far.shape[1], bool)
    np.testing.assert_array_equal(_LogProb(broken, 8, every_log)(far[:2]), [-np.inf, -np.inf])


def test_a_parameter_sampled_in_value_may_lie_beyond_the_logarithms_range():
    """The guard against exp's overflow holds for logarithms only: a coast-down's
    initial speed of 1,300 rad/s (sampled in value) is a density like any other, and
    the sampler started from it (every walker was refused before)."""
    seen = []

    def fn(thetas):
        seen.append(np.asarray(thetas))
        return np.zeros(thetas.shape[0])

    walkers = np.array([[np.log(2.0), 1300.0], [np.log(2.0), -1300.0], [750.0, 1.0]])
    lp = _LogProb(fn, 4, is_log=[True, False])(walkers)
    np.testing.assert_array_equal(lp, [0.0, 0.0, -np.inf])
    lp = _LogProb(fn, 4, [True, True])(walkers)  # both logarithms: every walker beyond
    np.testing.assert_array_equal(lp, np.full(3, -np.inf))


def test_the_log_posterior_runs_in_64_bits_in_every_sampler_thread():
    """The ensembles step in threads, and JAX's 64-bit mode is a thread's own setting:
    the walkers reach the log-posterior in float64 whichever thread asks (the caller's
    global setting left off)."""
    import threading

    import jax.numpy as jnp

    seen = []

    def record(thetas):
        seen.append(thetas.dtype)
        return jnp.sum(thetas, axis=1)

    walkers = np.array([[1.0 + 1e-12, 2.0], [3.0, 4.0]])
    before = jax.config.jax_enable_x64
    jax.config.update("jax_enable_x64", False)  # as a caller may have it
    try:
        log_prob = _LogProb(record, 2, [True, True])
        worker = threading.Thread(target=lambda: seen.append(log_prob(walkers)))
        worker.start()
        worker.join()
        assert not jax.config.jax_enable_x64
    finally:
        jax.config.update("jax_enable_x64", before)
    assert seen[0] == jnp.float64 and seen[1][0] == 3.0 + 1e-12


# Gates


def _row(r_hat=1.001, ess_bulk=2000.0, ess_tail=2000.0):
    return {"mean": 1.0, "sd": 0.1, "hdi_3%": 0.8, "hdi_97%": 1.2, "ess_bulk": ess_bulk,
            "ess_tail": ess_tail, "r_hat": r_hat}


def test_gates_name_the_parameter_and_the_reason():
    ok, failures = gates({"K": _row(), "J": _row()})
    assert ok and failures == []
    ok, failures = gates({"K": _row(), "J": _row(r_hat=1.03), "Tc": _row(ess_bulk=120.0)})
    assert not ok
    assert failures == ["J: R-hat 1.030 > 1.01 (chains have not mixed)",
                        "Tc: bulk ESS 120 < 400"]
    ok, failures = gates({"B": _row(r_hat=np.nan, ess_tail=50.0)}, r_hat_max=1.05, ess_min=100)
    assert not ok and all(f.startswith("B: ") for f in failures) and len(failures) == 2
    capped = types.SimpleNamespace(capped=True, message="slowest parameter J")
    ok, failures = gates({"K": _row()}, posterior=capped)
    assert not ok and "capped" in failures[0] and "J" in failures[0]


# Recovery, ArviZ record, LOO


@pytest.mark.compiles
def test_recovers_the_truth_and_passes_the_gates(tiny):
    model, fit = tiny
    post = sample_posterior(model, fit, seed=1, max_steps=6000, progress=False)
    assert not post.capped, post.message
    summary = summarize(post)
    ok, failures = gates(summary, posterior=post)
    assert ok, failures
    # Fixed data and seed: with 5 parameters each 94 % interval misses with probability
    # 0.06, so this is a check of calibration at one realisation, not a proof of it.
    for name, value in TRUTH.items():
        assert summary[name]["hdi_3%"] <= value <= summary[name]["hdi_97%"], (name, summary)
    # the central 90 % interval: the draws' 5 % and 95 % quantiles, about the median
    draws = post.draws_si()
    for name in TRUTH:
        row, d = summary[name], np.asarray(draws[name]).ravel()
        assert row["q5%"] < row["median"] < row["q95%"]
        assert np.mean(d < row["q5%"]) == pytest.approx(0.05, abs=2 / d.size ** 0.5)
        assert np.mean(d > row["q95%"]) == pytest.approx(0.05, abs=2 / d.size ** 0.5)
    # The Laplace approximation agrees with the sample for the well-identified K and J.
    for name in ("K", "J"):
        np.testing.assert_allclose(summary[name]["sd"], fit.sd[name], rtol=0.2)
    # the chain after the proposals' last refit (if any) is 50 τ long; burn-in is
    # everything before that refit and 2 τ after it
    adapted = post.idata.posterior.attrs["adapted"]
    assert post.n_steps - adapted >= 50 * max(post.tau.values())
    assert post.burn_in == adapted + int(np.ceil(2 * max(post.tau.values())))
    # this near-Gaussian posterior is one the Laplace proposals fit: after the pilot
    # they take nine steps in ten, and the pilot is burn-in
    assert post.idata.posterior.attrs["independence_share"] == SHARE_TRUSTED
    assert adapted >= PILOT


def test_inference_data_groups_and_loo(tiny, jax_x64):
    model, fit = tiny
    post = sample_posterior(model, fit, seed=2, ll_draws=200, **QUICK)
    idata = post.idata
    for group in ("posterior", "sample_stats", "observed_data", "log_likelihood",
                  "posterior_predictive"):
        assert hasattr(idata, group), group
    assert set(idata.posterior.data_vars) == set(TRUTH)
    np.testing.assert_allclose(idata.posterior["J"].values, post.draws[..., 4], rtol=1e-15)
    assert idata.posterior["J"].attrs["units"] == "kg*m^2"
    channels = {"step_speed", "step_current", "steady_speed", "steady_current"}
    assert set(idata.observed_data.data_vars) == channels
    tr = model.session.traces[0]
    np.testing.assert_allclose(idata.observed_data["step_speed"].values, tr.speed,
                               rtol=0, atol=0)
    # a trace's channels are on its sample times, in its units
    np.testing.assert_array_equal(idata.observed_data["step_speed"]["step_speed_time"], tr.time)
    assert idata.observed_data["step_current"].attrs["units"] == "A"
    n_obs = sum(c.n for c in model.channels)
    assert set(idata.log_likelihood.data_vars) == channels
    assert sum(idata.log_likelihood[v].shape[-1] for v in channels) == n_obs
    ll = idata.log_likelihood["step_speed"]
    assert ll.sizes["chain"] == 32 and ll.sizes["chain"] * ll.sizes["draw"] <= 200 + 32
    assert all(np.all(np.isfinite(idata.log_likelihood[v].values)) for v in channels)
    # The padded, compiled pointwise log-likelihood equals the model's own method.
    theta = np.asarray(fit.theta)
    dens, masks = _padded_pointwise(model, theta)
    ours = np.concatenate([np.asarray(d)[np.asarray(m)] for d, m in zip(dens, masks, strict=True)])
    ref = np.concatenate([np.asarray(x) for x in model.pointwise_log_likelihood(theta)])
    np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
    # The stored log-likelihood of a kept draw is the model's, channel by channel, to
    # float64 precision: PSIS-LOO reads its differences between draws, which on a
    # precise posterior are below float32's resolution.
    assert all(idata.log_likelihood[v].dtype == np.float64 for v in channels)
    c, k = 3, 2
    draw = int(ll["draw"][k])
    per_channel = model.pointwise_log_likelihood(post.draws_log[c, draw])
    for name, ref in zip(("step_speed", "step_current", "steady_speed", "steady_current"),
                         per_channel, strict=False):
        np.testing.assert_allclose(idata.log_likelihood[name].values[c, k], np.asarray(ref),
                                   rtol=1e-10, atol=1e-10)
    # The replicates scatter about the data by the channel's noise level: their
    # residual from the observation has the sd of the data's own noise (a replicate of
    # the wrong channel, or without noise, would not).
    rep = idata.posterior_predictive["step_speed"]
    assert rep.dims == ("chain", "draw", "step_speed_time")
    resid = (rep - idata.observed_data["step_speed"]).values
    sd_noise = fit.noise_sd[ChannelId("step", "speed")]
    assert 0.8 * np.sqrt(2) * sd_noise < resid.std() < 1.25 * np.sqrt(2) * sd_noise
    with warnings.catch_warnings():
        # PSIS may warn that some Pareto k are high on so short a chain; LOO must still run.
        warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto",
                                category=UserWarning)
        loo = az.loo(idata, var_name="step_speed", pointwise=True)
        assert loo.loo_i.shape == (tr.n,) and np.isfinite(loo.elpd_loo)
        whole = az.loo(lumped(idata), pointwise=True)
        assert whole.loo_i.shape == (n_obs,)
        # the session's LOO is the channels' together, observation by observation
        names = list(idata.log_likelihood.data_vars)
        at = sum(idata.log_likelihood[v].shape[-1] for v in names[:names.index("step_speed")])
        np.testing.assert_allclose(whole.loo_i.values[at:at + tr.n], loo.loo_i.values,
                                   rtol=1e-10)
        pit = az.loo_pit(idata, y="step_speed")
        assert pit.shape == (tr.n,) and np.all((pit >= 0) & (pit <= 1))
        import matplotlib.pyplot as plt

        # ArviZ 0.23's plots call a matplotlib helper that matplotlib >= 3.11 deprecates
        warnings.filterwarnings("ignore", message="Passing a dict or None as alias_mapping")
        az.plot_ppc(idata, var_names=["step_speed"], num_pp_samples=20)
        az.plot_loo_pit(idata, y="step_speed")
        plt.close("all")
    table = az.summary(idata, var_names=["K", "J"])
    assert list(table.index) == ["K", "J"] and (table["ess_bulk"] > 0).all()
    # Two samples of the same model: same elpd within its Monte Carlo noise.
    other = sample_posterior(model, fit, seed=3, ll_draws=200, **QUICK).idata
    rows = loo_compare({"a": idata, "b": other})
    assert [r["rank"] for r in rows] == [0, 1] and {r["model"] for r in rows} == {"a", "b"}
    assert abs(rows[1]["elpd_diff"]) < 3 * rows[0]["se"]


# Derived quantities


def test_derived_quantities_by_hand():
    draws = {"Ra": np.array([2.0, 4.0]), "La": np.array([1e-3, 2e-3]),
             "K": np.array([0.1, 0.2]), "B": np.array([1e-4, 2e-4]),
             "J": np.array([1e-5, 3e-5]), "Tc": np.array([0.01, 0.02])}
    out = derived_quantities(draws, voltage=12.0)
    d1, d2 = 2.0 * 1e-4 + 0.01, 4.0 * 2e-4 + 0.04  # B·Ra + K²
    expect = {
        "tau_m": [1e-5 * 2.0 / d1, 3e-5 * 4.0 / d2],
        "tau_e": [5e-4, 5e-4],
        "gain": [0.1 / d1, 0.2 / d2],
        "no_load_speed": [(1.2 - 0.02) / d1, (2.4 - 0.08) / d2],
        "no_load_current": [(12e-4 + 1e-3) / d1, (24e-4 + 4e-3) / d2],
        "stall_torque": [0.6 - 0.01, 0.6 - 0.02],
        "stall_current": [6.0, 3.0],
        "Kv": [60 / (2 * np.pi * 0.1), 60 / (2 * np.pi * 0.2)],
    }
    assert set(out) == set(expect)
    for name, values in expect.items():
        np.testing.assert_allclose(out[name]["mean"], np.mean(values), rtol=1e-12, err_msg=name)
        np.testing.assert_allclose(out[name]["sd"], np.std(values, ddof=1), rtol=1e-9,
                                   atol=1e-15, err_msg=name)
        np.testing.assert_allclose([out[name]["hdi_3%"], out[name]["hdi_97%"]],
                                   [min(values), max(values)], rtol=1e-12, err_msg=name)
    assert out["Kv"]["unit"] == "rpm/V" and out["tau_m"]["unit"] == "s"
    viscous = derived_quantities({k: v for k, v in draws.items() if k != "Tc"}, voltage=12.0)
    np.testing.assert_allclose(viscous["no_load_speed"]["mean"], np.mean([1.2 / d1, 2.4 / d2]),
                               rtol=1e-12)


# Negative control


def test_unidentifiable_friction_gives_up_and_fails_the_gates(tmp_path, monkeypatch,
                                                             jax_x64):
    """One operating point cannot split the friction torque between B·ω and Tc, nor say
    anything of J and La: with flat priors the posterior is a long curved ridge in
    (log B, log Tc), unbounded in J and La, that the ensemble cannot cross in a short
    run: the steps the rule projects exceed the budget long before the cap, and the
    slowest parameter is one the data leave to the flat priors."""
    truth = dict(TRUTH, Tc=2.5e-3)
    plan = {"seed": 3, "motor": {"name": "Ridge", "friction": "coulomb"}, "truth": truth,
            "bench": BENCH, "operating_point": [CHOPPER]}
    session = load_session(simulate_session(plan, tmp_path / "s"))
    seed = ClosedForm(*(truth[k] for k in ("Ra", "La", "K", "B", "J")), 0.1, 1.0, {})
    monkeypatch.setattr(objective, "PRIOR_FACTOR", 1e20)  # flat priors on K, B, J, Tc
    model = objective.build_model(session, seed)
    theta = np.asarray(model.theta(truth))
    # The MAP does not exist (flat ridge); start the walkers in a small ball on it.
    start = types.SimpleNamespace(theta=theta, cov_log=np.diag(np.full(6, 1e-4)))
    with warnings.catch_warnings():
        # Draws of the unidentified J and B reach 1e±60 and beyond; ArviZ's ESS/MCSE
        # arithmetic may overflow on them.  Only the gate verdict matters here.
        warnings.filterwarnings("ignore", category=RuntimeWarning, module="arviz")
        warnings.filterwarnings("ignore", category=RuntimeWarning, module="numpy")
        post = sample_posterior(model, start, seed=0, max_steps=2000, progress=False)
        ok, failures = gates(summarize(post), posterior=post)
    assert post.capped and not ok
    assert post.stop is Stop.OVER_BUDGET and post.n_steps < 2000  # it gives up early
    slowest = max(post.tau, key=post.tau.get)
    assert slowest in ("B", "Tc", "J", "La"), post.tau
    assert f"slowest parameter {slowest}" in post.message
    assert any(f.startswith(f"{slowest}: ") for f in failures), failures
