"""The joint MAP fit, its Laplace uncertainty, identifiability and the fit command."""

import copy
import json

import jax
import numpy as np
import pytest

from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.fit.undetermined import identifiability
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.paper.closed_form import closed_form
from pmdc_bayes.paper.consistency import consistency_checks


@pytest.fixture(scope="module")
def demo_fit():
    s = load_session(bundled_session_dir("demo"))
    model = build_model(s, closed_form(s))
    return s, model, fit_map(model)


@pytest.fixture(scope="module")
def paper_fit():
    s = load_session(bundled_session_dir("paper"))
    cf = closed_form(s)
    model = build_model(s, cf)
    return s, cf, model, fit_map(model)


@pytest.mark.compiles
def test_demo_map_recovers_truth(demo_fit):
    s, model, fit = demo_fit
    assert fit.ok, fit.message
    assert all(st["agrees"] for st in fit.starts if st["origin"] != "over the prior's range")
    assert max(st["log_posterior"] for st in fit.starts) == fit.log_posterior
    for name in model.names:
        truth = s.truth[name]
        # Within 3 Laplace standard deviations of the truth...
        assert abs(fit.values[name] - truth) <= 3.0 * fit.sd[name], name
        # ...and the mechanical parameters within 1 % (the requirement).
        if name in ("K", "B", "J", "Tc"):
            assert fit.values[name] == pytest.approx(truth, rel=0.01), name


@pytest.mark.compiles
def test_demo_map_beats_closed_form_b_bias(demo_fit):
    s, model, fit = demo_fit
    cf = closed_form(s)
    # The closed form lumps Coulomb friction into B; the joint fit separates them.
    assert abs(cf.B - s.truth["B"]) > 10 * abs(fit.values["B"] - s.truth["B"])


@pytest.mark.compiles
def test_demo_gradient_of_objective_matches_finite_differences(demo_fit, jax_x64):
    s, model, fit = demo_fit
    theta = np.asarray(fit.theta) + 0.01
    f = jax.jit(model.log_posterior)
    g = np.asarray(jax.grad(model.log_posterior)(theta))
    for k in range(theta.size):
        h = 1e-6
        e = np.zeros_like(theta)
        e[k] = h
        fd = (float(f(theta + e)) - float(f(theta - e))) / (2 * h)
        # Central differences on a log-posterior of size ~1e5: rounding ~1e-16·1e5/1e-6
        # = 1e-5 absolute, truncation O(h²); 1e-4 relative covers both.
        assert g[k] == pytest.approx(fd, rel=1e-4, abs=1e-3)


@pytest.mark.compiles
def test_paper_fit_and_consistency(paper_fit):
    s, cf, model, fit = paper_fit
    assert fit.ok, fit.message
    checks = consistency_checks(s, cf)
    assert checks["closed_form_gain"] == pytest.approx(14.33, abs=0.01)
    ratio = checks["load_sensitivity_measured"] / checks["load_sensitivity_closed_form"]
    assert ratio == pytest.approx(2.33, abs=0.05)
    assert checks["steady_slope"] == pytest.approx(15.22, abs=0.01)
    assert checks["steady_offset"] == pytest.approx(-24.3, abs=0.1)


@pytest.mark.compiles
def test_paper_identifiability_flags_what_steady_data_cannot_separate(paper_fit):
    s, cf, model, fit = paper_fit
    ident = identifiability(model, fit)
    text = " ".join(ident["findings"])
    # No trace logs current: La can only come from the bench.
    assert "La is determined by the bench prior alone" in text
    # Steady points and one time constant leave K, B, J strongly correlated.
    assert "K and B are" in text and "correlated" in text
    assert ident["condition_number"] > 100


@pytest.mark.compiles
def test_demo_identifiability_does_not_flag_la(demo_fit):
    s, model, fit = demo_fit
    ident = identifiability(model, fit)
    assert not any(f.startswith("La is") for f in ident["findings"])
    assert not any("speed sensor's scale" in f for f in ident["findings"])  # a known load
    assert "La" not in ident["prior_dominated"]


@pytest.mark.compiles
def test_fit_command_writes_summary_and_refuses_to_overwrite(tmp_path, pmdc):
    out = tmp_path / "run"
    proc = pmdc("fit", "paper", "--no-mcmc", "--no-search", "--out", out, "--allow-inadequate")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    for name in ("Ra", "La", "K", "B", "J"):
        row = summary["parameters"][name]
        assert set(row) >= {"unit", "closed_form", "map", "map_sd"}
    assert summary["parameters"]["K"]["closed_form"] == pytest.approx(0.062, abs=1e-12)
    assert summary["identifiability"]["findings"]
    again = pmdc("fit", "paper", "--no-mcmc", "--no-search", "--out", out, "--allow-inadequate")
    assert again.returncode == 2
    assert "already exists" in again.stderr and "Traceback" not in again.stderr
    assert len(again.stderr.strip().splitlines()) == 1
    assert not list(tmp_path.glob(".run.*"))  # no temporary directory left behind


def _traced(kernel) -> list[int]:
    """How many times each program behind a compiled kernel was traced: the jitted
    function itself, or (when an earlier run in this process enabled the disk cache)
    each program loaded from disk, one per signature of its arguments."""
    programs = {id(p): p for p in kernel.programs.values()}.values()
    return [len(programs)] + [p._cache_size() for p in programs]


@pytest.mark.compiles
def test_fit_compiles_once_per_session_structure(demo_fit):
    import dataclasses

    from pmdc_bayes.inference import _runtime as _cache

    s, model, fit = demo_fit
    rng = np.random.default_rng(0)
    traces = tuple(dataclasses.replace(tr, speed=tr.speed + 0.3 * rng.standard_normal(tr.n))
                   for tr in s.traces)
    other = dataclasses.replace(s, traces=traces,
                                Ra=dataclasses.replace(s.Ra, value=8.45))
    model2 = build_model(other, closed_form(other))
    assert model2.structure_key() == model.structure_key()
    kernels = [fn for key, fn in _cache._IN_MEMORY.items()
               if key[0] == "optimistix-step" and key[1:] == model.structure_key()]
    assert kernels
    before = dict(_cache._IN_MEMORY)
    assert all(_traced(k) == [1] * len(_traced(k)) for k in kernels)  # traced once...
    fit2 = fit_map(model2)
    assert fit2.ok
    assert dict(_cache._IN_MEMORY).keys() == before.keys()  # ...nothing new was built...
    assert all(_traced(k) == [1] * len(_traced(k)) for k in kernels)  # ...and reused


@pytest.mark.compiles
def test_friction_option_reports_goodness_of_fit_and_tc(tmp_path, pmdc):
    runs = {}
    for friction in ("viscous", "coulomb"):
        out = tmp_path / friction
        proc = pmdc("fit", "demo", "--no-mcmc", "--friction", friction, "--out", out)
        runs[friction] = json.loads((out / "summary.json").read_text())
        # The demo motor has Coulomb friction: the data reject the viscous model.
        verdict = runs[friction]["adequacy"]["verdict"]
        assert (proc.returncode, verdict) == ((0, "adequate") if friction == "coulomb"
                                              else (3, "inadequate")), proc.stderr
        assert proc.stdout.splitlines()[0].startswith(
            "Model adequate" if friction == "coulomb" else "MODEL INADEQUATE")
    assert "Tc" not in runs["viscous"]["parameters"]
    assert runs["coulomb"]["parameters"]["Tc"]["map"] > 0
    # The demo motor has Coulomb friction: the viscous model fits no trace better, and
    # the half-voltage step and the load change (where Coulomb and viscous friction
    # differ most) clearly worse.
    rms = {f: runs[f]["residuals"]["map"] for f in runs}
    for trace in rms["coulomb"]:
        assert rms["viscous"][trace]["speed"] >= rms["coulomb"][trace]["speed"], trace
    for trace in ("step_6v49", "load_change"):
        assert rms["viscous"][trace]["speed"] > 1.5 * rms["coulomb"][trace]["speed"], trace


@pytest.mark.compiles
def test_speed_only_steps_flag_the_j_b_k_degeneracy():
    import dataclasses

    s = load_session(bundled_session_dir("demo"))
    steps = tuple(dataclasses.replace(tr, current=None) for tr in s.traces
                  if tr.name in ("step_12v97", "step_6v49"))
    only_speed = dataclasses.replace(s, traces=steps, operating_points=(), steady_tables=(),
                                     friction="viscous")
    # The closed form needs a steady current: seed it from the full session's.
    model = build_model(only_speed, closed_form(s))
    fit = fit_map(model)
    ident = identifiability(model, fit)
    text = " ".join(ident["findings"])
    # Speed alone fixes the gain K/(B·Ra + K²) and the time constant, not K, B and J
    # separately: each comes out strongly correlated with another or set by its prior,
    # and the report says what would help.
    pairs = [(a, b) for a, b in (("K", "B"), ("K", "J"), ("B", "J"))
             if f"{a} and {b} are correlated" in text]
    assert pairs, text
    for name in ("K", "B", "J"):
        assert any(name in pair for pair in pairs) or (
            f"{name} is determined by its prior alone" in text), (name, text)
    assert "load step or a coast-down" in text
    assert "La is determined by the bench prior alone: no trace logs the current" in text
    # a gain on a sensed speed is K/g, B/g², J/g² exactly: said while nothing fixes it
    assert "The speed sensor's scale is taken as exact" in text
    from pmdc_bayes.io.readings import Measurement
    fixed = [dataclasses.replace(only_speed, bench={"J": Measurement(1e-5, 1e-6, "kg*m^2")}),
             dataclasses.replace(only_speed, nuisances=("speed_gain",)),
             dataclasses.replace(only_speed, operating_points=s.operating_points),
             dataclasses.replace(only_speed, traces=tuple(
                 dataclasses.replace(tr, load_torque=dataclasses.replace(
                     tr.load_torque, values=np.full(np.shape(tr.load_torque.values), 1e-3)))
                 for tr in steps))]
    for session in fixed:
        other = copy.copy(model)
        other.session = session
        ident = identifiability(other, fit)
        assert not any("speed sensor's scale" in f for f in ident["findings"])


def test_optima_of_nearly_equal_density_span_the_uncertainty():
    """Two distinct optima as probable as each other, a unit apart in θ: the covariance
    is their mixture's (each one's curvature plus the spread between them), not the
    MAP's curvature alone; one far less probable is left out."""
    from types import SimpleNamespace

    from pmdc_bayes.inference.fit import joint as fitmod

    local = np.diag([1e-4, 1e-4])
    states = [SimpleNamespace(theta=np.array([0.0, 0.0]), terms=None),
              SimpleNamespace(theta=np.array([1.0, 0.0]), terms=None)]
    logp = np.array([10.0, 10.0])
    orig = fitmod.laplace
    fitmod.laplace = lambda model, theta, terms: (local, None)
    try:
        mix, mass = fitmod._mixture(None, states, [0, 1], logp, 0, local)
        far, _ = fitmod._mixture(None, states, [0, 1], np.array([10.0, -30.0]), 0, local)
        fitmod.laplace = lambda model, theta, terms: (9 * local, None)  # 3x wider
        wide, wide_mass = fitmod._mixture(None, states, [0, 1], logp, 0, local)
    finally:
        fitmod.laplace = orig
    assert mix[0, 0] == pytest.approx(1e-4 + 0.25) and mix[1, 1] == pytest.approx(1e-4)
    assert mass == pytest.approx(np.log(2.0))  # twice the MAP's Laplace mass
    assert far[0, 0] == pytest.approx(1e-4, rel=1e-9)
    # an optimum as high but three times wider per direction holds nine times the mass
    assert wide_mass == pytest.approx(np.log(10.0))
    assert wide[1, 1] == pytest.approx(0.1 * 1e-4 + 0.9 * 9e-4)


def test_the_evidence_of_several_optima_is_their_laplace_mass_not_their_spread():
    """Two optima of equal height and curvature double the evidence (log 2) whatever
    their distance: the mixture's wide covariance does not enter the evidence."""
    from types import SimpleNamespace

    from pmdc_bayes.selection import laplace_log_evidence

    model = SimpleNamespace(data={"prior_scale": np.ones(2)}, registry=SimpleNamespace(specs=()))
    local = np.diag([1e-4, 1e-4])
    one = SimpleNamespace(cov_log=local, log_posterior=5.0, overflows=False)
    two = SimpleNamespace(cov_log=local + np.diag([100.0, 0.0]), cov_map=local,
                          log_mass=float(np.log(2.0)), log_posterior=5.0, overflows=False)
    assert laplace_log_evidence(model, two) - laplace_log_evidence(model, one) == \
        pytest.approx(np.log(2.0))


@pytest.mark.compiles
def test_a_thin_curved_ridge_is_not_reported_as_a_point(tmp_path):
    """A speed-only encoder-edge step with no current anywhere (a fuzzed session of the
    independent bench simulator): the edges fix a combination of K, B and J to a part
    in a million along a curved ridge on which the starts stop at optima of equal
    density far apart.  The MAP's curvature alone put K 200 sd from the truth; the
    central 99 % interval spanning the optima covers K, B and J."""
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.simulate.fuzz import fuzz_session

    fz = fuzz_session(61, out=tmp_path / "s61")
    session = load_session(fz.path)
    model = build_model(session, fit_seed(session))
    fit = fit_map(model)
    assert fit.n_modes > 1
    for name in ("K", "B", "J"):
        i = list(fit.names).index(name)
        z = (np.log(fz.truth[name]) - fit.theta[i]) / np.sqrt(fit.cov_log[i, i])
        assert abs(z) < 2.576, (name, z)


def test_the_laplace_inverse_keeps_directions_held_to_twenty_decades_apart():
    """A dead time known to microseconds beside a drop known to a factor (curvatures
    1e15 and 1): the covariance is the exact inverse, not the largest eigenvalue's
    floor imposed on the loose directions; a direction of zero curvature comes out
    wide and finite."""
    from pmdc_bayes.inference.fit.curvature import invert_curvature

    rng = np.random.default_rng(3)
    a = rng.standard_normal((5, 5))
    unit = a @ a.T + 0.5 * np.eye(5)
    d = np.diag(1.0 / np.sqrt(np.diag(unit)))
    unit = d @ unit @ d  # unit diagonal, well conditioned
    scale = np.array([3e7, 1.0, 4e-3, 1e-2, 2e4])
    H = unit * np.outer(scale, scale)
    exact = np.linalg.inv(unit) / np.outer(scale, scale)
    np.testing.assert_allclose(invert_curvature(H), exact, rtol=1e-9)
    flat = np.diag([1e15, 1.0, 0.0])
    cov = invert_curvature(flat)
    assert np.all(np.isfinite(cov)) and cov[2, 2] > 1e14 * cov[1, 1]
    assert cov[0, 0] == pytest.approx(1e-15) and cov[1, 1] == pytest.approx(1.0)
