"""`pmdc-bayes fit` end to end on the demo: closed form → MAP → MCMC → summary.json."""

import json

import pytest

from pmdc_bayes.inference.sampling.arviz_import import az
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.pipeline import FitOptions, run_fit

CONTRACT = {"unit", "closed_form", "map", "map_sd", "mean", "sd", "hdi_3%", "hdi_97%",
            "ess_bulk", "r_hat"}


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "demo"
    return run_fit(bundled_session_dir("demo"), FitOptions(seed=1), out=out)


@pytest.mark.compiles
def test_summary_contract(demo_run):
    out, summary = demo_run
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["parameters"].keys() == {"Ra", "La", "K", "B", "J", "Tc"}
    for row in on_disk["parameters"].values():
        assert CONTRACT <= set(row)
    for key in ("derived", "diagnostics", "seed", "session", "versions"):
        assert key in on_disk
    # the demo leaves its model to the search, whose start the data do not reject: the
    # run goes on from that fit, timed as the search's stage, and fits no MAP of its own
    assert set(on_disk["diagnostics"]["wall_s"]) >= {"model_search", "mcmc", "report",
                                                     "total"}
    assert "model_selection" not in on_disk and "map" not in on_disk["diagnostics"]["wall_s"]
    assert on_disk["versions"]["jax"] and on_disk["versions"]["emcee"]
    assert on_disk["seed"] == 1


@pytest.mark.compiles
def test_demo_hdi_contains_truth_and_gates_pass(demo_run):
    out, summary = demo_run
    assert summary["diagnostics"]["gates_passed"], summary["diagnostics"]["failures"]
    assert summary["diagnostics"]["sampled_in_value"] == []  # its posterior is Gaussian in log
    for name, row in summary["parameters"].items():
        truth = summary["truth"][name]
        assert row["hdi_3%"] <= truth <= row["hdi_97%"], name
        assert row["r_hat"] <= 1.01 and row["ess_bulk"] >= 400


@pytest.mark.compiles
def test_posterior_file_has_the_arviz_groups(demo_run):
    """posterior.nc as a user opens it: every group, a channel per trace and quantity on
    its sample times with its unit, and ArviZ's summary, LOO, LOO-PIT and predictive
    plots working on the file read back."""
    import warnings

    import numpy as np

    out, _ = demo_run
    idata = az.from_netcdf(out / "posterior.nc")
    for group in ("posterior", "sample_stats", "observed_data", "log_likelihood",
                  "posterior_predictive"):
        assert group in idata.groups()
    assert set(idata.posterior.data_vars) >= {"Ra", "La", "K", "B", "J", "Tc"}
    assert idata.posterior["B"].attrs["units"] == "N*m*s/rad"
    speed = "step_12v97_speed"
    assert set(idata.observed_data.data_vars) == set(idata.log_likelihood.data_vars) == set(
        idata.posterior_predictive.data_vars) >= {speed, "step_12v97_current", "steady_speed"}
    assert idata.observed_data[speed].attrs["units"] == "rad/s"
    times = idata.observed_data[speed][f"{speed}_time"].values
    assert times[0] >= 0.0 and np.all(np.diff(times) > 0)  # seconds, in order
    assert idata.posterior_predictive[speed].dims == ("chain", "draw", f"{speed}_time")
    table = az.summary(idata, var_names=["K", "B"], round_to="none")
    assert 0 < table.loc["B", "sd"] < table.loc["B", "mean"]  # B is not "0.000"
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto",
                                category=UserWarning)
        warnings.filterwarnings("ignore", message="Passing a dict or None as alias_mapping")
        loo = az.loo(idata, var_name=speed, pointwise=True)
        assert loo.loo_i.shape == times.shape and np.isfinite(loo.elpd_loo)
        pit = az.loo_pit(idata, y=speed)
        assert pit.shape == times.shape and np.all((pit >= 0) & (pit <= 1))
        import matplotlib.pyplot as plt

        az.plot_ppc(idata, var_names=[speed], num_pp_samples=20)
        az.plot_loo_pit(idata, y=speed)
        plt.close("all")


@pytest.mark.compiles
def test_derived_quantities_from_draws(demo_run):
    _, summary = demo_run
    q = summary["derived"]["quantities"]
    p = summary["parameters"]
    tau_m = p["J"]["mean"] * p["Ra"]["mean"] / (p["B"]["mean"] * p["Ra"]["mean"]
                                                 + p["K"]["mean"] ** 2)
    assert set(q) >= {"tau_m", "tau_e", "gain", "no_load_speed", "no_load_current",
                      "stall_torque"}
    # The draw-wise mean of a smooth function is its value at the mean to O(sd²), and the
    # relative sds here are ~1e-4.
    assert q["tau_m"]["mean"] == pytest.approx(tau_m, rel=1e-5)
    assert q["tau_m"]["hdi_3%"] < q["tau_m"]["mean"] < q["tau_m"]["hdi_97%"]


@pytest.mark.compiles
def test_fit_command_refuses_existing_run_without_force(demo_run, pmdc):
    out, _ = demo_run
    proc = pmdc("fit", "demo", "--no-mcmc", "--out", out)
    assert proc.returncode == 2
    assert "already exists" in proc.stderr and "Traceback" not in proc.stderr
    assert (out / "posterior.nc").is_file()  # the earlier run is untouched


def _fit_cli(pmdc, *args):
    return pmdc("fit", *args, timeout=600)


def _snapshot(root):
    return {p.relative_to(root): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_force_never_replaces_a_session_a_file_or_a_foreign_folder(session_dir, tmp_path, pmdc):
    """--force replaces only an earlier run: the checks come before any fitting."""
    before = _snapshot(session_dir)
    proc = _fit_cli(pmdc, session_dir, "--no-mcmc", "--out", session_dir, "--force")
    assert proc.returncode == 2, proc.stderr
    assert "session directory" in proc.stderr and "Traceback" not in proc.stderr
    assert _snapshot(session_dir) == before
    note = tmp_path / "notes.txt"
    note.write_text("mine")
    proc = _fit_cli(pmdc, session_dir, "--no-mcmc", "--out", note, "--force")
    assert proc.returncode == 2 and note.read_text() == "mine"
    folder = tmp_path / "photos"
    folder.mkdir()
    (folder / "a.jpg").write_bytes(b"\xff\xd8")
    proc = _fit_cli(pmdc, session_dir, "--no-mcmc", "--out", folder, "--force")
    assert proc.returncode == 2 and "not a pmdc-bayes run" in proc.stderr
    assert (folder / "a.jpg").read_bytes() == b"\xff\xd8"
    (folder / "summary.json").write_text("{}")  # a summary.json of one's own is no marker
    proc = _fit_cli(pmdc, session_dir, "--no-mcmc", "--out", folder, "--force")
    assert proc.returncode == 2 and "not a pmdc-bayes run" in proc.stderr
    assert (folder / "a.jpg").read_bytes() == b"\xff\xd8"
    proc = _fit_cli(pmdc, session_dir, "--no-mcmc", "--out", tmp_path / ("x" * 300))
    assert proc.returncode == 2 and "choose a shorter --out" in proc.stderr


@pytest.mark.compiles
def test_force_replaces_an_earlier_run(demo_run, pmdc):
    out, _ = demo_run
    assert (out / ".pmdc-bayes-run").is_file()
    proc = _fit_cli(pmdc, "demo", "--no-mcmc", "--out", out, "--force")
    assert proc.returncode == 0, proc.stderr
    assert not (out / "posterior.nc").exists() and (out / "summary.json").is_file()
