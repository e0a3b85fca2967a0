"""The session simulator: reproducible files, exact noise-free traces, sensor models,
plan errors, the command line, and the bundled demo session it generated."""

import copy  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
from pathlib import Path  # noqa: E402

import jax
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pmdc_bayes._errors import SessionError, UsageError  # noqa: E402
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.physics.solution import Params, experiment_from_trace, simulate  # noqa: E402
from pmdc_bayes.simulate.plan import check_plan  # noqa: E402
from pmdc_bayes.simulate.session import (  # noqa: E402
    load_plan,
    simulate_session,
    true_steady,
    true_trace,
)

DEMO = Path(__file__).resolve().parents[2] / "data" / "demo"
TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4, "Tc": 2.5e-3}
# Every trace in these tests has the same sample layout (0.5 s at 200 Hz, one step at
# 0.05 s), so the simulator compiles once for all of them.
TRACE = {"name": "step", "kind": "step", "duration": 0.5, "rate": 200.0,
         "voltage": [[0.0, 0.0], [0.05, 12.0]], "initial": "rest", "speed_unit": "rpm",
         "record_current": True, "speed_noise": 0.3, "speed_quantum": 0.0,
         "current_noise": 0.005}
PLAN = {
    "seed": 7,
    "motor": {"name": "Test motor", "friction": "coulomb"},
    "truth": TRUTH,
    "bench": {"Ra": {"sd": 0.1, "unit": "ohm"}, "La": {"sd": 0.2, "unit": "mH"}},
    "operating_point": [{"name": "chopper", "supply_voltage": 24.0, "duty": 0.7,
                         "speed_sd": 0.5, "current_sd": 0.002}],
    "steady_table": [{"name": "sweep", "voltages": [4.0, 8.0, 12.0], "speed_sd": 0.5,
                      "current_sd": 0.002}],
    "trace": [TRACE],
}
PLAN_TOML = """\
seed = 7
[motor]
name = "CLI motor"
friction = "coulomb"
[truth]
Ra = 8.5
La = 5.6e-3
K = 0.062
B = 4.5e-5
J = 5.9e-4
Tc = 2.5e-3
[bench.Ra]
sd = 0.1
unit = "ohm"
[bench.La]
sd = 0.2
unit = "mH"
[[operating_point]]
name = "chopper"
supply_voltage = 24.0
duty = 0.7
[[trace]]
name = "step"
kind = "step"
duration = 0.5
rate = 200.0
voltage = [[0.0, 0.0], [0.05, 12.0]]
"""


def plan(**trace_changes) -> dict:
    """A deep copy of the small plan, with changes to its one trace."""
    p = copy.deepcopy(PLAN)
    p["trace"][0].update(trace_changes)
    return p


def digests(root: Path) -> dict[str, str]:
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in sorted(root.iterdir())}




# Reproducibility


def test_same_seed_gives_byte_identical_files(tmp_path):
    a = digests(simulate_session(plan(), tmp_path / "a", seed=11))
    b = digests(simulate_session(plan(), tmp_path / "b", seed=11))
    assert set(a) == {"session.toml", "truth.json", "sweep.csv", "step.csv"}
    assert a == b


def test_different_seed_changes_the_noise_only(tmp_path):
    a = load_session(simulate_session(plan(), tmp_path / "a", seed=11))
    b = load_session(simulate_session(plan(), tmp_path / "b", seed=12))
    assert a.truth == b.truth
    np.testing.assert_array_equal(a.traces[0].time, b.traces[0].time)
    diff = a.traces[0].speed - b.traces[0].speed
    assert np.count_nonzero(diff) > 0.9 * diff.size
    # Two independent N(0, 0.3) draws: their difference has sd 0.3*sqrt(2) rad/s.
    np.testing.assert_allclose(np.std(diff), 0.3 * np.sqrt(2), rtol=0.2)
    assert a.Ra.value != b.Ra.value
    assert a.operating_points[0].speed != b.operating_points[0].speed


def test_adding_an_item_leaves_the_others_unchanged(tmp_path):
    a = digests(simulate_session(plan(), tmp_path / "a"))
    more = plan()
    more["trace"] = [dict(TRACE, name="another"), *more["trace"]]
    more["steady_table"].append({"name": "sweep2", "voltages": [5.0], "speed_sd": 0.5})
    b = digests(simulate_session(more, tmp_path / "b"))
    for name in ("step.csv", "sweep.csv", "truth.json"):
        assert a[name] == b[name], name


def test_bundled_demo_regenerates_byte_identically(tmp_path):
    out = simulate_session(DEMO / "plan.toml", tmp_path / "demo")
    generated = digests(out)
    committed = digests(DEMO)
    assert set(committed) - set(generated) == {"plan.toml", "README.md"}
    for name, digest in generated.items():
        assert committed[name] == digest, f"data/demo/{name} differs from a regeneration"


# The generated session


def test_generated_session_loads_with_the_truth(tmp_path):
    session = load_session(simulate_session(plan(), tmp_path / "s"))
    assert session.truth == TRUTH
    assert session.friction == "coulomb"
    assert [t.name for t in session.traces] == ["step"]
    # Bench values: truth + N(0, sd); 5 sd bounds.
    assert abs(session.Ra.value - TRUTH["Ra"]) < 5 * 0.1
    assert abs(session.La.value - TRUTH["La"]) < 5 * 0.2e-3
    np.testing.assert_allclose(session.La.sd, 0.2e-3, rtol=1e-12)
    op = session.operating_points[0]
    ia, w = true_steady(TRUTH, 16.8)
    assert abs(op.speed - w) < 5 * 0.5 and abs(op.current - ia) < 5 * 0.002
    table = session.steady_tables[0]
    ia, w = true_steady(TRUTH, np.array([4.0, 8.0, 12.0]))
    assert np.all(np.abs(table.speed - w) < 5 * 0.5)
    assert np.all(np.abs(table.current - ia) < 5 * 0.002)


def test_bundled_demo_loads_and_its_truth_matches_the_plan():
    session = load_session(DEMO)
    assert session.truth == load_plan(DEMO / "plan.toml")["truth"]
    assert session.friction == "coulomb"
    sizes = {t.name: t.n for t in session.traces}
    assert sizes == {"step_12v97": 2501, "step_6v49": 2501, "load_change": 4001,
                     "current_capture": 1201}
    assert all(t.current is not None for t in session.traces)


def test_coulomb_steady_state_formula():
    ia, w = true_steady(TRUTH, 16.8, 0.001)
    den = TRUTH["K"] ** 2 + TRUTH["Ra"] * TRUTH["B"]
    load = 0.001 + TRUTH["Tc"]
    np.testing.assert_allclose(w, (TRUTH["K"] * 16.8 - TRUTH["Ra"] * load) / den, rtol=1e-14)
    np.testing.assert_allclose(ia, (TRUTH["B"] * 16.8 + TRUTH["K"] * load) / den, rtol=1e-14)
    # Below breakaway the rotor is held: no speed, stall current.
    ia, w = true_steady(TRUTH, 0.2)
    assert w == 0.0
    np.testing.assert_allclose(ia, 0.2 / TRUTH["Ra"], rtol=1e-14)


# Sensor models


def test_noise_free_sensors_reproduce_the_model(tmp_path):
    quiet = plan(speed_noise=0.0, current_noise=0.0)
    session = load_session(simulate_session(quiet, tmp_path / "s"))
    trace = session.trace("step")
    model = jax.jit(simulate, static_argnames="coulomb")  # eager dispatch is slow
    with jax.enable_x64(True):  # the physics, called as the package calls it
        ia, w = model(Params(**TRUTH), experiment_from_trace(trace), coulomb=True)
    # The files hold 10 significant digits.
    np.testing.assert_allclose(trace.speed, np.asarray(w), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(trace.current, np.asarray(ia), rtol=1e-9, atol=1e-12)
    assert trace.speed[-1] > 50.0  # the step really moved the motor


def test_quantiser_rounds_to_multiples(tmp_path):
    p = plan(speed_unit="rad/s", speed_quantum=0.5, current_quantum=0.01)
    trace = load_session(simulate_session(p, tmp_path / "s")).trace("step")
    np.testing.assert_allclose(trace.speed / 0.5, np.round(trace.speed / 0.5), rtol=0,
                               atol=1e-9)
    np.testing.assert_allclose(trace.current / 0.01, np.round(trace.current / 0.01), rtol=0,
                               atol=1e-9)
    _, _, w = true_trace(TRUTH, check_plan(plan(speed_noise=0.0)).traces[0])
    assert np.all(np.abs(trace.speed - w) < 0.25 + 5 * 0.3)  # half a quantum + noise


def test_delay_shifts_the_response():
    spec = check_plan(plan()).traces[0]
    delayed = check_plan(plan(delay=0.05)).traces[0]  # 10 samples at 200 Hz
    t, ia, w = true_trace(TRUTH, spec)
    _, ia_d, w_d = true_trace(TRUTH, delayed)
    np.testing.assert_allclose(w_d[10:], w[:-10], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ia_d[10:], ia[:-10], rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(w_d[:10], np.zeros(10))  # clipped: still at rest
    assert np.max(np.abs(w_d - w)) > 1.0  # negative control: the delay matters


# Errors


def _set(path, value):
    def mutate(p):
        *keys, last = path
        node = p
        for k in keys:
            node = node[k]
        if value is KeyError:
            del node[last]
        else:
            node[last] = value

    return mutate


PLAN_ERRORS = [
    (_set(("truth", "K"), KeyError), "truth.K", "missing required key"),
    (_set(("truth", "Tc"), 0.01), "truth.Tc", "viscous"),
    (_set(("truth", "J"), -1.0), "truth.J", "must be"),
    (_set(("truth", "Rb"), 1.0), "truth.Rb", "unknown key"),
    (_set(("seed",), "one"), "seed", "whole number"),
    (_set(("bench", "La", "unit"), "henry"), "bench.La.unit", "unknown inductance unit"),
    (_set(("trace", 0, "speed_unit"), "mph"), "speed_unit", "unknown speed unit"),
    (_set(("trace", 0, "kind"), "ramp"), "kind", "use one of"),
    (_set(("trace", 0, "voltage"), [[0.0, 0.0], [0.0, 5.0]]), "voltage", "increase strictly"),
    (_set(("trace", 0, "speed_noise"), -0.1), "speed_noise", ">= 0"),
    (_set(("trace", 0, "delay"), 1.0), "delay", "shorter than the trace"),
    (_set(("trace", 0, "name"), "a/b"), "name", "file name"),
    (_set(("trace", 0, "name"), "sweep"), "name", "used twice"),
    (_set(("operating_point", 0, "duty"), 1.5), "duty", "fraction"),
    (_set(("steady_table", 0, "load_torques"), [0.0]), "load_torques", "one load torque"),
]


@pytest.mark.parametrize(("mutate", "where", "what"), PLAN_ERRORS,
                         ids=[e[1] + ":" + e[2] for e in PLAN_ERRORS])
def test_plan_errors_are_one_line(tmp_path, mutate, where, what):
    p = plan()
    if what == "viscous":
        p["motor"]["friction"] = "viscous"
    mutate(p)
    with pytest.raises(SessionError) as info:
        simulate_session(p, tmp_path / "s")
    message = str(info.value)
    assert "\n" not in message
    assert where in message and what in message, message
    assert not (tmp_path / "s").exists()


def test_missing_seed_and_missing_plan(tmp_path):
    p = plan()
    del p["seed"]
    with pytest.raises(SessionError, match="seed"):
        simulate_session(p, tmp_path / "s")
    with pytest.raises(SessionError, match="plan file not found"):
        simulate_session(tmp_path / "nope.toml", tmp_path / "s")


def test_force_replaces_only_generated_files(tmp_path):
    out = tmp_path / "s"
    simulate_session(plan(), out)
    (out / "README.md").write_text("notes\n")
    with pytest.raises(UsageError, match="already exists"):
        simulate_session(plan(), out)
    renamed = plan(name="renamed")
    simulate_session(renamed, out, force=True)
    names = {f.name for f in out.iterdir()}
    assert names == {"README.md", "session.toml", "truth.json", "sweep.csv", "renamed.csv"}
    assert not any(f.name.startswith(".") for f in tmp_path.iterdir())  # no temporary left


# Command line


def test_cli_simulate_then_refuses_to_overwrite(tmp_path, pmdc):
    (tmp_path / "plan.toml").write_text(PLAN_TOML)
    done = pmdc("simulate", tmp_path / "plan.toml", timeout=120)  # --out: the plan's dir
    assert done.returncode == 0, done.stderr
    assert "SIMULATED" in done.stdout
    session = load_session(tmp_path)
    assert session.motor == "CLI motor" and session.truth == TRUTH
    before = digests(tmp_path)
    again = pmdc("simulate", tmp_path / "plan.toml", "--out", tmp_path, timeout=120)
    assert again.returncode == 2
    lines = again.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in again.stderr
    assert "already exists" in lines[0] and "--force" in lines[0]
    assert digests(tmp_path) == before


def test_closed_form_on_demo_lumps_coulomb_friction_into_b(pmdc):
    done = pmdc("closed-form", DEMO, "--json", timeout=120)
    assert done.returncode == 0, done.stderr
    cf = json.loads(done.stdout)
    truth = json.loads((DEMO / "truth.json").read_text())
    _, w = true_steady(truth, 0.7 * 24.0)
    excess = truth["Tc"] / float(w)  # equation (19) at a Coulomb motor: B + Tc/ω
    assert cf["B"] > truth["B"]
    np.testing.assert_allclose(cf["B"] - truth["B"], excess, rtol=0.25)


def test_force_never_overwrites_a_hand_made_session(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "session.toml").write_text("[motor]\nname = \"my real motor\"\n")
    (out / "step.csv").write_text("t,speed\n0,0\n")
    with pytest.raises(UsageError, match="not generated by pmdc-bayes simulate"):
        simulate_session(plan(), out, force=True)
    assert (out / "session.toml").read_text() == "[motor]\nname = \"my real motor\"\n"
    assert (out / "step.csv").read_text() == "t,speed\n0,0\n"


@pytest.mark.parametrize("edit", ["trace", "csv"])
def test_force_never_overwrites_a_simulated_session_the_user_changed(tmp_path, edit):
    """A trace of the user's added to a simulated session, or a generated CSV edited:
    --force refuses rather than delete or overwrite the change."""
    out = simulate_session(plan(), tmp_path / "s")
    if edit == "trace":
        (out / "my_bench.csv").write_text("t,w\n0,0\n1,5\n")
        with (out / "session.toml").open("a") as fh:
            fh.write('\n[[trace]]\nname = "mine"\nkind = "step"\nfile = "my_bench.csv"\n')
        changed = "session.toml"
    else:
        changed = next(p.name for p in out.glob("*.csv"))
        with (out / changed).open("a") as fh:
            fh.write("\n")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(UsageError, match=f"{changed}: changed since pmdc-bayes simulate"):
        simulate_session(plan(), out, force=True, seed=7)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    # an untouched simulated session is replaced as before
    fresh = simulate_session(plan(), tmp_path / "t")
    assert simulate_session(plan(), fresh, force=True, seed=7) == fresh
