"""A speed-only session (no current anywhere, no chopper point, no bench La) fits end
to end through the command line: the closed form says why it does not apply, the fit
seeds itself from the data, recovers what speed can tell, and says what it cannot."""

import json

import pytest
from conftest import plan, plan_toml, step, sweep

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import LA_ASSUMED
from pmdc_bayes.simulate.session import simulate_session

RA, LA, K, B, J = 2.0, 2e-3, 0.05, 2e-5, 2e-5
DEN = RA * B + K**2

_STEP = {"duration": 0.15, "rate": 4000.0, "record_current": False, "speed_noise": 0.2}
PLAN = plan_toml(plan(
    seed=3, motor="speed-only motor", truth={"Ra": RA, "La": LA, "K": K, "B": B, "J": J},
    bench={"Ra": (0.06, "ohm")}, steady=(sweep([3.0, 6.0, 9.0, 12.0], 0.2),),
    traces=(step("step_12v", 12.0, **_STEP), step("step_6v", 6.0, **_STEP))))


@pytest.fixture(scope="module")
def run(tmp_path_factory, pmdc):
    root = tmp_path_factory.mktemp("speed_only")
    plan = root / "plan.toml"
    plan.write_text(PLAN)
    session = simulate_session(plan, root / "session")
    loaded = load_session(session)
    assert loaded.La.source == LA_ASSUMED
    assert all(tr.current is None for tr in loaded.traces)
    assert all(t.current is None for t in loaded.steady_tables) and not loaded.operating_points
    out = root / "run"
    proc = pmdc("fit", session, "--no-mcmc", "--out", out, timeout=900)
    return proc, out


@pytest.mark.compiles
def test_a_speed_only_session_fits_end_to_end(run):
    proc, out = run
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0].startswith("Model adequate")
    summary = json.loads((out / "summary.json").read_text())
    cf = summary["closed_form"]
    assert cf["applicable"] is False and "steady current" in cf["reason"]
    assert all(summary["parameters"][n]["closed_form"] is None for n in ("K", "B", "J"))
    assert "does not apply" in (out / "report.md").read_text()


@pytest.mark.compiles
def test_speed_alone_determines_the_gain_and_time_constant_not_the_split(run):
    _, out = run
    summary = json.loads((out / "summary.json").read_text())
    p = {n: summary["parameters"][n]["map"] for n in ("Ra", "K", "B", "J")}
    den = p["Ra"] * p["B"] + p["K"] ** 2
    assert p["K"] / den == pytest.approx(K / DEN, rel=0.01)  # steady gain
    assert p["Ra"] * p["J"] / den == pytest.approx(RA * J / DEN, rel=0.03)  # time constant
    # the data cannot split the damping between back-emf and friction: the fit says so
    ident = summary["identifiability"]
    assert "B" in ident["prior_dominated"]
    assert any(f.startswith("B is determined by its prior alone") for f in ident["findings"])
    k = summary["parameters"]["K"]
    assert k["map_sd"] / k["map"] > 0.1  # no false precision on K
    # La was not measured; the onset of fast-sampled steps still determines it, and the
    # run says that a dead time or a speed-sensor lag would look the same
    assert ident["posterior_to_prior_width"]["La"] < 0.2
    assert summary["parameters"]["La"]["map"] == pytest.approx(LA, rel=0.2)
    la = [f for f in ident["findings"] if f.startswith("La = ")]
    assert len(la) == 1 and "upper bound" in la[0] and "dead time" in la[0]


def _with_bench(run, tmp_path, **bench):
    """The speed-only session with further bench entries appended to its session.toml."""
    import shutil

    _, out = run
    session = tmp_path / "session"
    shutil.copytree(out.parent / "session", session)
    extra = "".join(f'\n[bench.{k}]\nvalue = {v}\nsd = {sd}\nunit = "{unit}"\n'
                    for k, (v, sd, unit) in bench.items())
    toml = session / "session.toml"
    toml.write_text(toml.read_text() + extra)
    return load_session(session)


@pytest.mark.compiles
def test_a_bench_K_is_a_prior_that_splits_the_damping(run, tmp_path):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    session = _with_bench(run, tmp_path, K=(K * 1.01, K * 0.01, "V*s/rad"))
    assert set(session.bench) == {"K"} and session.bench["K"].sd == pytest.approx(K * 0.01)
    res = fit_session(session, FitOptions(mcmc=False))
    spec = res.model.registry["K"]
    assert (spec.prior.kind, spec.prior.source) == ("normal", "bench")
    fit = res.fit
    # K now carries the bench's 1 % (not the > 10 % of speed alone), and the steady gain
    # then fixes B: both recovered within 3 sd of the truth
    assert fit.sd["K"] / fit.values["K"] < 0.015
    for name, true in (("K", K), ("B", B), ("J", J)):
        assert abs(fit.values[name] - true) < 3 * fit.sd[name], (name, fit.values[name])
    assert res.adequacy.verdict == "adequate"
    assert res.summary["adequacy"]["bench"]["K"]["z"] == pytest.approx(
        (fit.values["K"] - K * 1.01) / (K * 0.01))


@pytest.mark.compiles
def test_a_bench_J_the_data_contradict_is_a_bench_conflict(run, tmp_path):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    # an inertia measured (or typed) a factor 3 too large, claimed to 2 %
    session = _with_bench(run, tmp_path, J=(3 * J, 0.02 * 3 * J, "kg*m^2"))
    res = fit_session(session, FitOptions(mcmc=False))
    assert res.adequacy.verdict == "inadequate"
    assert any(f.check == "bench conflict" and f.where == "J" and f.severity == "fail"
               for f in res.adequacy.findings)
