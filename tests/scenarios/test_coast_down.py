"""Coast-down traces (the armature open, the rotor running down): the equation against
an ODE solver, the session format, and fits of sessions whose coast-downs were
integrated by SciPy (not by the package's model)."""

import json
import shutil
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest
from conftest import plan, plan_toml, step, sweep
from scipy.integrate import solve_ivp

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.adequacy.findings import Check, Finding, Severity
from pmdc_bayes.inference.adequacy.model_checks import coast_start_notes
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.run_down import hold_then_fall
from pmdc_bayes.physics import motor
from pmdc_bayes.simulate.session import simulate_session

RA, LA, K, B, J = 2.0, 2e-3, 0.05, 2e-5, 2e-5


def _ode_coast(b, j, tc, w0, t):
    """Run-down integrated by LSODA, with the stop located as an event and then held."""
    stop = lambda _, w: w[0]  # noqa: E731
    stop.terminal, stop.direction = True, -np.sign(w0)
    sol = solve_ivp(lambda _, w: [(-b * w[0] - tc * np.sign(w[0])) / j], (0.0, t[-1]),
                    [w0], method="LSODA", rtol=1e-11, atol=1e-11, events=stop,
                    dense_output=True)
    if sol.status != 1:  # never stopped
        return sol.sol(t)[0]
    t_end = sol.t[-1]
    return np.where(t < t_end, sol.sol(np.minimum(t, t_end))[0], 0.0)


@pytest.mark.parametrize(("b", "tc", "w0"), [
    (2e-5, 0.0, 236.0),  # viscous: exponential
    (2e-5, 1e-3, 236.0),  # Coulomb: stops inside the record
    (4.5e-5, 2.5e-3, -80.0),  # turning backwards
    (1e-12, 1e-3, 150.0),  # almost no viscous friction: a linear run-down
])
def test_the_coast_down_equation_matches_an_ode_solver(b, tc, w0):
    t = np.linspace(0.0, 4.0, 801)
    ref = _ode_coast(b, J, tc, w0, t)
    for xp in (np, jnp):
        got = np.asarray(motor.coast_down(xp.asarray(b), J, w0, xp.asarray(t), tc))
        np.testing.assert_allclose(got, ref, rtol=1e-7, atol=1e-6 * abs(w0))
    if tc > 0 and b < 1e-6:
        assert got[-1] == 0.0 and np.argmax(got == 0.0) > 0  # stopped and held


def _write_coast(session_dir, name, t, w, *, extra=""):
    with open(session_dir / f"{name}.csv", "w") as fh:
        fh.write("t,w\n")
        fh.writelines(f"{a:.5f},{v:.6f}\n" for a, v in zip(t, w, strict=True))
    with open(session_dir / "session.toml", "a") as fh:
        fh.write(f'\n[[trace]]\nname = "{name}"\nkind = "coast-down"\nfile = "{name}.csv"\n'
                 f'columns = {{ time = "t", speed = "w" }}\n{extra}')


def test_a_coast_down_is_read_apart_from_the_driven_traces(tmp_path):
    session = tmp_path / "s"
    shutil.copytree(bundled_session_dir("demo"), session)
    t = np.linspace(0.0, 2.0, 50)
    _write_coast(session, "run_down", t, 100.0 * np.exp(-t),
                 extra='units = { speed = "rpm" }\n')
    s = load_session(session)
    assert [tr.name for tr in s.coast_downs] == ["run_down"]
    assert "run_down" not in [tr.name for tr in s.traces] and len(s.traces) == 4
    cd = s.coast_downs[0]
    assert cd.current is None and cd.speed[0] == pytest.approx(100.0 * np.pi / 30)


@pytest.mark.parametrize(("extra", "where", "what"), [
    ('voltage = [[0.0, 12.0]]\n', "trace['run_down'].voltage", "unknown key"),
    ('initial = "steady"\n', "trace['run_down'].initial", "unknown key"),
])
def test_a_coast_down_with_drive_keys_is_bad_input(tmp_path, extra, where, what, pmdc):
    session = tmp_path / "s"
    shutil.copytree(bundled_session_dir("demo"), session)
    _write_coast(session, "run_down", np.linspace(0, 1, 10), np.linspace(5, 1, 10),
                 extra=extra)
    with pytest.raises(SessionError) as info:
        load_session(session)
    assert where in str(info.value) and what in str(info.value)
    proc = pmdc("fit", session, "--out", tmp_path / "run")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert not (tmp_path / "run").exists()


SPEED_ONLY_PLAN = plan_toml(plan(
    seed=3, motor="speed-only motor with a run-down",
    truth={"Ra": RA, "La": LA, "K": K, "B": B, "J": J}, bench={"Ra": (0.06, "ohm")},
    steady=(sweep([3.0, 6.0, 9.0, 12.0], 0.2),),
    traces=(step("step_12v", 12.0, duration=0.15, rate=4000.0, record_current=False,
                 speed_noise=0.2),)))


def _speed_only_with_coast(root, *, tc=0.0):
    (root / "plan.toml").write_text(SPEED_ONLY_PLAN)
    session = simulate_session(root / "plan.toml", root / "session")
    t = np.arange(0.0, 3.0, 0.005)
    w0 = K * 12.0 / (RA * B + K * K)
    w = _ode_coast(B, J, tc, w0, t) + np.random.default_rng(7).normal(0.0, 0.2, t.size)
    _write_coast(session, "run_down", t, w)
    return session


@pytest.mark.compiles
def test_a_coast_down_splits_the_damping_of_a_speed_only_session(tmp_path, pmdc):
    session = _speed_only_with_coast(tmp_path)
    out = tmp_path / "run"
    proc = pmdc("fit", session, "--out", out, "--seed", "1", timeout=1500)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    assert "run_down: speed" in summary["adequacy"]["channels"]
    p = summary["parameters"]
    # speed alone left K > 10 % uncertain (test_speed_only); with the run-down, K is
    # determined to well under 1 %, and the truth lies within 3 posterior sd
    assert p["K"]["sd"] / p["K"]["mean"] < 0.01
    for name, true in (("K", K), ("B", B), ("J", J)):
        assert abs(p[name]["mean"] - true) < 3 * p[name]["sd"], (name, p[name])
        assert p[name]["r_hat"] < 1.01
    w0 = K * 12.0 / (RA * B + K * K)
    row = p["initial_speed_run_down"]
    assert row["unit"] == "rad/s" and abs(row["mean"] - w0) < 3 * row["sd"]
    assert "B" not in summary["identifiability"]["prior_dominated"]
    assert (out / "posterior.nc").exists()
    assert "run_down: speed" in (out / "report.md").read_text()


@pytest.mark.compiles
def test_a_coulomb_run_down_rejects_the_viscous_model(tmp_path):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    session = load_session(_speed_only_with_coast(tmp_path, tc=2e-3))
    res = fit_session(session, FitOptions(mcmc=False))  # the session's friction: viscous
    assert res.adequacy.verdict == "inadequate"
    assert any(f.where == ChannelId("run_down", "speed") and f.severity == "fail"
               for f in res.adequacy.findings)
    res = fit_session(session, FitOptions(mcmc=False, friction="coulomb"))
    fit = res.fit
    assert res.adequacy.verdict == "adequate", [f.message for f in res.adequacy.findings]
    for name, true in (("Tc", 2e-3), ("B", B), ("J", J)):
        assert abs(fit.values[name] - true) < 3 * fit.sd[name], (name, fit.values[name])


def _held_run_down(hold, rng, *, sd=0.3, w0=241.6, dt=0.01, span=8.5):
    """A run-down of the demo's motor from ``hold`` s into a record from 0 (the speed
    held at ``w0`` before), read with white noise of ``sd``."""
    t = np.arange(0.0, span, dt)
    w = np.where(t < hold, w0, _ode_coast(4.5e-5, 5.9e-4, 2.5e-3, w0,
                                         np.clip(t - hold, 0.0, None)))
    return t, w + rng.normal(0.0, sd, t.size)


@pytest.mark.parametrize("hold", [0.15, 0.5, 2.0])
def test_a_hold_before_the_opening_is_found_in_a_record_from_zero(hold):
    rng = np.random.default_rng(7)
    for _ in range(10):
        t, w = _held_run_down(hold, rng)
        h = hold_then_fall(t, w)
        assert h is not None and hold - 0.02 <= h.opened <= hold + 0.1
        assert h.ratio > 1.5
    for _ in range(30):  # the armature opened at the record's start: nothing held
        t, w = _held_run_down(0.0, rng)
        assert hold_then_fall(t, w) is None


def test_the_fits_finding_on_a_held_coast_down_names_when_it_was_opened():
    rng = np.random.default_rng(3)
    t, w = _held_run_down(0.5, rng)
    t2, w2 = _held_run_down(0.0, rng)
    coasts = [SimpleNamespace(name="held", time=t, speed=w, time_unit="s"),
              SimpleNamespace(name="plain", time=t2, speed=w2, time_unit="s")]
    model = SimpleNamespace(session=SimpleNamespace(coast_downs=coasts))
    findings = [Finding(Check.RESIDUAL_WHITENESS, ChannelId(name, "speed"), Severity.WARN,
                        "", "not white", suggestion)
                for name, suggestion in (("held", ""), ("plain", ""), ("held", "keep"))]
    out = coast_start_notes(model, findings)
    assert out[1] == findings[1] and out[2] == findings[2]  # the first on a channel told
    note = out[0].suggestion
    assert "trace['held'].opened = 0.5" in note and "until t = 0.5" in note
    assert out[0].where == findings[0].where and out[0].severity is Severity.WARN


@pytest.mark.slow
def test_a_coast_down_logged_from_before_its_opening_is_named_after_the_fit(tmp_path):
    """The demo's motor with a run-down logged in ms from 0, its first 0.5 s driven: the
    fit misses the hold, and the finding on the run-down's speed gives the opening in
    the trace's unit; with it given, the run-down is fitted whole."""
    from pmdc_bayes.inference.adequacy.verdict import assess
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed

    session = tmp_path / "s"
    shutil.copytree(bundled_session_dir("demo"), session)
    t, w = _held_run_down(0.5, np.random.default_rng(1))
    _write_coast(session, "run_down", 1000.0 * t, w,
                 extra='units = { time = "ms", speed = "rad/s" }\n')
    notes = {}
    for opened in ("", "opened = 500\n"):
        text = (session / "session.toml").read_text()
        units = 'units = { time = "ms", speed = "rad/s" }\n'
        assert text.count(units) == 1
        (session / "session.toml").write_text(text.replace(units, units + opened))
        s = load_session(session)
        cf = fit_seed(s)
        model = build_model(s, cf)
        fit = fit_map(model, seed=0)
        a = assess(model, fit, cf)
        notes[opened] = [f.suggestion for f in a.findings
                         if f.where == ChannelId("run_down", "speed") and "opened" in f.suggestion]
    assert len(notes[""]) == 1 and "trace['run_down'].opened = 5" in notes[""][0]
    assert " ms and then falls" in notes[""][0]
    assert notes["opened = 500\n"] == []
