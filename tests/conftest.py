import os
import shutil
import subprocess
import sys
import tempfile

import jax
import pytest

# Commands run by the tests (in this process or as subprocesses) keep their compiled
# programs in a cache of this test run, never in the user's home directory; it is
# removed when the run ends.
_TEST_CACHE = None
if "PMDC_BAYES_CACHE" not in os.environ:
    _TEST_CACHE = tempfile.mkdtemp(prefix="pmdc-bayes-test-cache-")
    os.environ["PMDC_BAYES_CACHE"] = _TEST_CACHE


@pytest.fixture(autouse=True)
def _x64_off_as_a_caller_has_it():
    """Every test starts with JAX's 64-bit mode off, as a caller's process has it: a
    command run in-process switches it on for its own process, and must not leave it on
    for the tests after it."""
    jax.config.update("jax_enable_x64", False)
    yield
    jax.config.update("jax_enable_x64", False)


@pytest.fixture
def jax_x64():
    """JAX's 64-bit mode for a test that computes with the package's internals itself, as
    the package does inside its own 64-bit context.  The suite leaves the mode off, as a
    caller's process has it, so that an entry point of the package that forgets to
    switch it on fails its tests."""
    with jax.enable_x64(True):
        yield


def pytest_collection_modifyitems(config, items):
    """A statistical test and one that compiles a session's programs are both slow:
    ``-m "not slow"`` leaves out both, ``-m statistical`` or ``-m compiles`` either."""
    for item in items:
        if item.get_closest_marker("statistical") or item.get_closest_marker("compiles"):
            item.add_marker(pytest.mark.slow)


def pytest_sessionfinish(session, exitstatus):
    if _TEST_CACHE is not None:
        shutil.rmtree(_TEST_CACHE, ignore_errors=True)

# Shared fixtures: a small valid session written into ``tmp_path``.  Tests break one
# thing of it at a time (a key, a unit, a CSV cell) and check the error.

import json  # noqa: E402
import math  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import NamedTuple  # noqa: E402

import numpy as np  # noqa: E402

# The synthetic step in step.csv: 0 -> 6 V at t = 0.1 s, first-order speed response.
STEP_TAU = 0.2  # s
STEP_DT = 0.01  # s
STEP_T0 = 0.1  # s, time of the voltage step
STEP_FINAL_RPM = 1000.0
STEP_N = 151  # samples, t = 0 ... 1.5 s

SESSION_TOML = """\
[motor]
name = "Test motor"
friction = "viscous"

[bench.Ra]
value = 2.0
unit = "ohm"
sd = 0.05

[bench.La]
value = 1.5
unit = "mH"
sd = 0.04

[[operating_point]]
name = "op"
supply_voltage = 12.0
duty = 0.5
current = 0.3
speed = 100.0
units = { supply_voltage = "V", current = "A", speed = "rad/s" }

[[steady_table]]
name = "sweep"
file = "sweep.csv"
columns = { voltage = "Va", speed = "w" }
units = { voltage = "V", speed = "rad/s" }

[[trace]]
name = "step"
kind = "step"
file = "step.csv"
columns = { time = "t", speed = "speed_rpm", current = "ia" }
units = { time = "s", speed = "rpm", current = "A", voltage = "V" }
voltage = [[0.0, 0.0], [0.1, 6.0]]
"""

SWEEP_CSV = "Va,w\n2.0,10.0\n4.0,30.0\n6.0,50.0\n"


def step_rows() -> list[tuple[float, float, float]]:
    """(t s, speed rpm, current A) of the synthetic step, noiseless."""
    rows = []
    for k in range(STEP_N):
        t = round(k * STEP_DT, 10)
        x = 0.0 if t < STEP_T0 else 1.0 - math.exp(-(t - STEP_T0) / STEP_TAU)
        rows.append((t, STEP_FINAL_RPM * x, 0.05 + 0.5 * (1.0 - x) * (t >= STEP_T0)))
    return rows


def write_session(root: Path) -> Path:
    """Write the small valid session into ``root`` (created if needed) and return it."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "session.toml").write_text(SESSION_TOML, encoding="utf-8")
    (root / "sweep.csv").write_text(SWEEP_CSV, encoding="utf-8")
    lines = ["t,speed_rpm,ia"] + [f"{t:.2f},{w:.3f},{i:.4f}" for t, w, i in step_rows()]
    (root / "step.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return root


def replace_once(path: Path, old: str, new: str) -> None:
    """Replace the one occurrence of ``old`` in the file (fail loudly if not exactly one)."""
    text = path.read_text(encoding="utf-8")
    assert text.count(old) == 1, f"{old!r} occurs {text.count(old)} times in {path}"
    path.write_text(text.replace(old, new), encoding="utf-8")


def set_csv_cell(path: Path, line: int, column: str, text: str) -> None:
    """Overwrite one cell of a CSV file; ``line`` is the 1-based file line."""
    lines = path.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    cells = lines[line - 1].split(",")
    cells[header.index(column)] = text
    lines[line - 1] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


@pytest.fixture
def session_dir(tmp_path) -> Path:
    """A fresh copy of the small valid session, in ``tmp_path / "sess"``."""
    return write_session(tmp_path / "sess")


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


@pytest.fixture(scope="session")
def up_down_session(tmp_path_factory) -> Path:
    """The bench simulator's up-down step of seed 22 (to each sign of the voltage, 0.56
    ms between samples), logged with its signed voltage and current columns and a steady
    table, for tests that rewrite it as rigs log it (read only)."""
    from pmdc_bayes.simulate.fuzz import fuzz_session

    d = tmp_path_factory.mktemp("up_down") / "s"
    fuzz_session(22, out=d, shapes=("up-down",))
    return d


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop the compiled programs of a test module after it: hundreds of them kept in one
    process exhaust the compiler's memory on a 2-core CI machine."""
    yield
    from pmdc_bayes.inference import _runtime as cache

    cache.release()


class Cli:
    """``pmdc-bayes`` as a user runs it: in a process of its own, its output as text."""

    @staticmethod
    def argv(*args) -> list[str]:
        return [sys.executable, "-m", "pmdc_bayes", *map(str, args)]

    def __call__(self, *args, timeout: float | None = 1800,
                 **kw) -> subprocess.CompletedProcess:
        """Run ``pmdc-bayes ARGS`` to its end: its exit code, stdout and stderr."""
        return subprocess.run(self.argv(*args), capture_output=True, text=True,
                              timeout=timeout, **kw)

    def start(self, *args, **kw) -> subprocess.Popen:
        """Start ``pmdc-bayes ARGS`` (to interrupt it, or to watch what it writes)."""
        return subprocess.Popen(self.argv(*args), stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, **kw)


@pytest.fixture(scope="session")
def pmdc() -> Cli:
    """The command line, run as a user runs it (:class:`Cli`)."""
    return Cli()


# Simulation plans (the plan format of ``pmdc-bayes simulate``) built from their parts,
# so that tests share a motor, a bench, a steady table or a step rather than copy TOML.

def plan(*, seed: int, motor: str, truth: dict, bench: dict | None = None,
         friction: str | None = None, rig: dict | None = None, steady: tuple = (),
         traces: tuple = ()) -> dict:
    """A plan: ``bench`` maps a measured parameter to its ``(sd, unit)``; ``steady``
    and ``traces`` are its steady tables and traces (:func:`sweep`, :func:`step`)."""
    out = {"seed": seed, "motor": {"name": motor, **({"friction": friction} if friction
                                                      else {})}, "truth": dict(truth)}
    if bench:
        out["bench"] = {name: {"sd": sd, "unit": unit} for name, (sd, unit) in bench.items()}
    if rig is not None:  # an empty [rig] draws the traces through the rig's simulator
        out["rig"] = dict(rig)
    if steady:
        out["steady_table"] = list(steady)
    if traces:
        out["trace"] = list(traces)
    return out


def sweep(voltages, speed_sd: float, current_sd: float | None = None, *,
          name: str = "sweep") -> dict:
    """A steady table: the speed (and, with ``current_sd``, the current) at each voltage."""
    table = {"name": name, "voltages": list(voltages), "speed_sd": speed_sd}
    return table if current_sd is None else {**table, "current_sd": current_sd}


def step(name: str, volts: float, *, duration: float, rate: float, at: float = 0.01,
         **keys) -> dict:
    """A trace stepping from rest to ``volts`` at ``at`` seconds; ``keys`` the rest of
    its plan entry (noise levels, delay, ...)."""
    return {"name": name, "kind": "step", "duration": duration, "rate": rate,
            "voltage": [[0.0, 0.0], [at, volts]], **keys}


def logged_stairs(root: Path, *, seed: int, motor: str, truth: dict, levels, rate: float,
                  friction: str = "viscous", **column):
    """A staircase through ``levels`` (``(time, volts)`` pairs) at ``rate`` drawn by the
    bench simulator's rig beside a steady sweep, its voltage logged as a column
    (``log_voltage_column`` with ``column``: its noise, or a switching supply), written
    under ``root`` and loaded."""
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.simulate._fuzz_extra import log_voltage_column
    from pmdc_bayes.simulate._write import write_session_files
    from pmdc_bayes.simulate.plan import check_plan
    from pmdc_bayes.simulate.session import render_session

    stairs = {"name": "stairs", "kind": "free-form", "duration": 1.25, "rate": rate,
              "voltage": [list(p) for p in levels], "speed_noise": 0.3,
              "current_noise": 0.01}
    spec = check_plan(plan(seed=seed, motor=motor, friction=friction, truth=truth,
                           bench={"Ra": (0.05, "ohm")}, rig={},
                           steady=(sweep([4.0, 8.0, 12.0], 0.3, 0.005),),
                           traces=(stairs,)))
    files = log_voltage_column(render_session(spec, seed), spec, "stairs", seed=seed,
                               **column)
    write_session_files(files, root / "s", force=False)
    return load_session(root / "s")


def plan_toml(plan: dict) -> str:
    """``plan`` as the TOML file a user writes."""
    def value(v) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list | tuple):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(float(v)) if isinstance(v, float) else repr(v)

    def keys(table: dict) -> list[str]:
        return [f"{k} = {value(v)}" for k, v in table.items()]

    lines = [f"{k} = {value(v)}" for k, v in plan.items() if not isinstance(v, dict | list)]
    for name, v in plan.items():
        if isinstance(v, dict) and all(isinstance(x, dict) for x in v.values()) and v:
            for sub, table in v.items():
                lines += [f"[{name}.{sub}]", *keys(table)]
        elif isinstance(v, dict):
            lines += [f"[{name}]", *keys(v)]
        elif isinstance(v, list):
            for table in v:
                lines += [f"[[{name}]]", *keys(table)]
    return "\n".join(lines) + "\n"


# a small motor several plans share (SI)
SMALL_MOTOR = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5}


# A session fitted as the command fits it before its posterior: the seed, the model,
# the MAP (global search) and the adequacy verdict.

class Fitted(NamedTuple):
    seed: object
    model: object
    fit: object
    verdict: object


def fit_and_assess(session, *, nuisances: tuple | None = None, seed: int = 0) -> Fitted:
    """``session`` (with ``nuisances`` in its model, when given) fitted and judged."""
    import dataclasses

    from pmdc_bayes.inference.adequacy.verdict import assess
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed

    if nuisances is not None:
        session = dataclasses.replace(session, nuisances=tuple(nuisances))
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=seed)
    return Fitted(cf, model, fit, assess(model, fit, cf))
