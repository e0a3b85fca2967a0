"""A trace whose known load is not affine in the speed (a fan: quadratic drag; a brake's
measured curve), drawn by the independent rig simulator (LSODA on the curve itself):
declared, the model carries it and recovers the motor through the command line; left
out, the model is rejected; the session format reads the curve in the trace's units."""

import json
import subprocess
import sys

import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4, "Tc": 2.5e-3}
FAN = {"quadratic": 6e-7, "curve": [[0.0, 0.0], [80.0, 2e-3], [250.0, 9e-3]]}


def _plan():
    noise = {"speed_noise": 0.05, "current_noise": 0.002, "speed_unit": "rpm"}
    return {"seed": 3, "motor": {"name": "fan-loaded motor", "friction": "coulomb"},
            "truth": dict(TRUTH), "rig": {"dead_time": 0.0},
            "bench": {"Ra": {"sd": 0.1, "unit": "ohm"}, "La": {"sd": 0.5, "unit": "mH"}},
            "steady_table": [{"name": "steady", "voltages": [4.0, 8.0, 12.0],
                              "speed_sd": 0.3, "current_sd": 0.002}],
            "trace": [{"name": "step_12v", "kind": "step", "duration": 2.0, "rate": 1000.0,
                       "voltage": [[0.0, 0.0], [0.1, 12.0]], **noise},
                      {"name": "fan_12v", "kind": "step", "duration": 2.5, "rate": 500.0,
                       "voltage": [[0.0, 0.0], [0.1, 12.0], [1.5, 5.0]], "drag": FAN,
                       **noise}]}


def _fit(root, out):
    return subprocess.run([sys.executable, "-m", "pmdc_bayes", "fit", str(root), "--no-mcmc",
                           "--out", str(out), "--quiet"], capture_output=True, text=True)


@pytest.mark.slow
def test_a_declared_fan_is_carried_and_a_forgotten_one_rejected(tmp_path):
    root = simulate_session(_plan(), tmp_path / "s")
    toml = (root / "session.toml").read_text()
    assert "quadratic = " in toml and "curve = [[0" in toml  # declared in rpm
    run = _fit(root, tmp_path / "run")
    assert run.returncode == 0, run.stdout + run.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["adequacy"]["verdict"] == "adequate"
    for name, want in TRUTH.items():
        p = summary["parameters"][name]
        assert abs(p["map"] - want) < 3 * p["map_sd"], (name, p["map"], p["map_sd"], want)
    # the same data with the fan left out of the session: the model is rejected
    bare = tmp_path / "bare"
    bare.mkdir()
    for f in root.iterdir():
        if f.suffix == ".csv":
            (bare / f.name).write_bytes(f.read_bytes())
    lines = [ln for ln in toml.splitlines() if not ln.startswith("drag = ")]
    (bare / "session.toml").write_text("\n".join(lines) + "\n")
    run = _fit(bare, tmp_path / "run_bare")
    assert run.returncode == 3, run.stdout + run.stderr


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
