"""A trace whose known load is not affine in the speed (a fan: quadratic drag; a brake's
measured curve), drawn by the independent rig simulator (LSODA on the curve itself):
declared, the model carries it and recovers the motor through the command line, the
fan's trace at the session's top voltage (not taken for an unloaded level); left out
or declared too strong, the model is rejected and the diagnosis says which; the
session format reads the curve in the trace's units and refuses one that would drive
the motor; a load that makes the model overflow is a failed fit (exit 1), not a crash."""

import json
from types import SimpleNamespace

import pytest
from conftest import replace_once

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.adequacy.model_checks import drag_checks
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Drag
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4, "Tc": 2.5e-3}
FAN = {"quadratic": 6e-7, "curve": [[0.0, 0.0], [80.0, 2e-3], [250.0, 9e-3]]}


def _plan():
    noise = {"speed_noise": 0.05, "current_noise": 0.002, "speed_unit": "rpm"}
    return {"seed": 3, "motor": {"name": "fan-loaded motor", "friction": "coulomb"},
            "truth": dict(TRUTH), "rig": {"dead_time": 0.0},
            "bench": {"Ra": {"sd": 0.1, "unit": "ohm"}, "La": {"sd": 0.5, "unit": "mH"}},
            "steady_table": [{"name": "steady", "voltages": [3.0, 6.0, 9.0],
                              "speed_sd": 0.3, "current_sd": 0.002}],
            "trace": [{"name": "step_9v", "kind": "step", "duration": 2.0, "rate": 1000.0,
                       "voltage": [[0.0, 0.0], [0.1, 9.0]], **noise},
                      {"name": "fan_12v", "kind": "step", "duration": 2.5, "rate": 500.0,
                       "voltage": [[0.0, 0.0], [0.1, 12.0], [1.5, 5.0]], "drag": FAN,
                       **noise}]}


def _fit(pmdc, root, out, *extra):
    return pmdc("fit", root, "--no-mcmc", "--out", out, "--quiet", *extra)


def _variant(root, where, edit):
    """A copy of the session ``root`` in ``where`` with its session.toml's lines edited
    by ``edit`` (a function of a line, None to drop it)."""
    where.mkdir()
    for f in root.iterdir():
        if f.suffix == ".csv":
            (where / f.name).write_bytes(f.read_bytes())
    lines = [edit(ln) for ln in (root / "session.toml").read_text().splitlines()]
    (where / "session.toml").write_text("\n".join(ln for ln in lines if ln is not None) + "\n")
    return where


@pytest.mark.compiles
def test_a_declared_fan_is_carried_and_a_forgotten_one_rejected(tmp_path, pmdc):
    root = simulate_session(_plan(), tmp_path / "s")
    toml = (root / "session.toml").read_text()
    assert "quadratic = " in toml and "curve = [[0" in toml  # declared in rpm
    run = _fit(pmdc, root, tmp_path / "run")
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    for name, want in TRUTH.items():
        p = summary["parameters"][name]
        assert abs(p["map"] - want) < 3 * p["map_sd"], (name, p["map"], p["map_sd"], want)
    # the same data with the fan left out of the session: the model is rejected
    bare = _variant(root, tmp_path / "bare", lambda ln: None if ln.startswith("drag = ") else ln)
    run = _fit(pmdc, bare, tmp_path / "run_bare", "--no-search")
    assert run.returncode == 3, run.stdout + run.stderr
    # declared 60 % too strong: rejected, and the diagnosis says the drag is too strong
    strong = _variant(root, tmp_path / "strong", lambda ln: ln.replace(
        "quadratic = 6e-07", "quadratic = 9.6e-07").replace("0.002]", "0.0032]").replace(
        "0.009]", "0.0144]"))
    assert "quadratic = 9.6e-07" in (strong / "session.toml").read_text()
    run = _fit(pmdc, strong, tmp_path / "run_strong", "--no-search")
    assert run.returncode == 3, run.stdout + run.stderr
    assert "fan_12v: settles" in run.stderr and "declared too strong" in run.stderr


def test_the_curve_is_read_in_the_trace_s_units_and_checked(session_dir):
    toml = session_dir / "session.toml"
    text = toml.read_text()
    units = 'units = { time = "s", speed = "rpm", current = "A", voltage = "V" }'
    assert units in text
    toml.write_text(text.replace(units, units[:-2] + ', load_torque = "mN*m" }').replace(
        'voltage = [[0.0, 0.0], [0.1, 6.0]]',
        'voltage = [[0.0, 0.0], [0.1, 6.0]]\n'
        'drag = { quadratic = 1e-7, curve = [[0, 0], [1000, 2.5], [3000, 9.0]] }'))
    (tr,) = load_session(session_dir).traces
    assert tr.drag.quadratic == 1e-7 and tr.drag.curved
    rpm = 2 * 3.141592653589793 / 60
    assert tr.drag.curve[1] == pytest.approx((1000 * rpm, 2.5e-3))
    assert tr.drag.curve[2] == pytest.approx((3000 * rpm, 9e-3))
    good = toml.read_text()
    curve = "curve = [[0, 0], [1000, 2.5], [3000, 9.0]]"
    for bad, message in [
            ("curve = [[10, 0], [1000, 2.5]]", r"drag\.curve\[0\].*start at \[0, 0\]"),
            ("curve = [[0, 0], [1000, 2.5], [900, 3.0]]",
             r"drag\.curve\[2\].*increase strictly"),
            ("curve = [[0, 0]]", r"drag\.curve.*at least two"),
            ("curve = [[0, 0], [1000, -1.0]]", r"drag\.curve\[1\]\.torque.*>= 0"),
            (curve.replace("quadratic", "") + ", quadratic = -1e-7", r"drag\.quadratic.*>= 0")]:
        toml.write_text(good.replace(curve, bad).replace("quadratic = 1e-7, ", ""))
        with pytest.raises(SessionError, match=message):
            load_session(session_dir)


def test_a_curve_whose_last_slope_would_drive_the_motor_is_refused(session_dir):
    toml = session_dir / "session.toml"
    # the trace reaches 1000 rpm; the curve, measured to 600 rpm, falls at its end
    replace_once(toml, 'voltage = [[0.0, 0.0], [0.1, 6.0]]', 'voltage = [[0.0, 0.0], [0.1, 6.0]]'
                 '\ndrag = { curve = [[0, 0], [400, 2.0], [600, 1.0]] }')
    replace_once(toml, 'voltage = "V" }', 'voltage = "V", load_torque = "mN*m" }')
    with pytest.raises(SessionError, match=r"drag\.curve.*to 999.1 rpm.*negative torque"):
        load_session(session_dir)
    replace_once(toml, "[600, 1.0]", "[600, 2.5]")  # rising: extended, with a warning
    session = load_session(session_dir)
    (warn,) = drag_checks(SimpleNamespace(session=session))
    assert warn.severity == "warn" and warn.where == "step" and "1.67 times" in warn.message
    replace_once(toml, "[600, 2.5]", "[1000, 2.5]")  # measured to the top speed
    assert drag_checks(SimpleNamespace(session=load_session(session_dir))) == []


def test_a_load_that_makes_the_model_overflow_is_a_failed_fit(session_dir, tmp_path, pmdc):
    replace_once(session_dir / "session.toml", 'voltage = [[0.0, 0.0], [0.1, 6.0]]',
                 'voltage = [[0.0, 0.0], [0.1, 6.0]]\ndrag = { quadratic = 1e300 }')
    run = _fit(pmdc, session_dir, tmp_path / "run")
    assert run.returncode == 1, run.stdout + run.stderr
    assert run.stderr.count("\n") == 1 and "the MAP fit failed" in run.stderr
    assert "internal error" not in run.stderr and not (tmp_path / "run").exists()


def test_from_arrays_takes_a_trace_s_drag_record(tmp_path):
    import numpy as np

    import pmdc_bayes

    rpm = 2 * np.pi / 60
    t = np.linspace(0.0, 1.0, 201)
    w = 100 * (1 - np.exp(-t / 0.1))
    drag = Drag(constant=1e-3, quadratic=2e-7, curve=((0.0, 0.0), (1000 * rpm, 2e-3)))
    s = pmdc_bayes.Session.from_arrays(
        Ra=(2.0, 0.05), traces={"fan": {"time": t, "speed": w / rpm, "voltage": 6.0,
                                        "units": {"speed": "rpm", "load_torque": "mN*m"},
                                        "drag": drag}})
    got = s.trace("fan").drag
    assert got.constant == 1e-3 and got.quadratic == 2e-7
    np.testing.assert_allclose(np.asarray(got.curve), np.asarray(drag.curve), rtol=1e-9)


def test_a_record_of_no_drag_and_a_speed_only_session_whose_traces_all_carry_one(tmp_path):
    import numpy as np

    import pmdc_bayes
    from pmdc_bayes.inference.model.seed import fit_seed

    t = np.linspace(0.0, 1.0, 201)
    w = 100 * (1 - np.exp(-np.maximum(t - 0.1, 0.0) / 0.1))
    trace = {"time": t, "speed": w, "voltage": [[0.0, 0.0], [0.1, 6.0]]}
    s = pmdc_bayes.Session.from_arrays(Ra=(2.0, 0.05), traces={"plain": {**trace,
                                                                        "drag": Drag()}})
    assert s.trace("plain").drag == Drag()
    # speed only, every trace loaded by a declared drag: the seed reads their levels
    s = pmdc_bayes.Session.from_arrays(Ra=(2.0, 0.05), traces={"fan": {
        **trace, "drag": {"quadratic": 1e-7}}})
    seed = fit_seed(s)
    assert not seed.applicable and seed.K > 0 and seed.J > 0
