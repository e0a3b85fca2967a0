import os
import shutil
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


def pytest_sessionfinish(session, exitstatus):
    if _TEST_CACHE is not None:
        shutil.rmtree(_TEST_CACHE, ignore_errors=True)

# Shared fixtures: a small valid session written into ``tmp_path``.  Tests break one
# thing of it at a time (a key, a unit, a CSV cell) and check the error.

import math  # noqa: E402
from pathlib import Path  # noqa: E402

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


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop the compiled programs of a test module after it: hundreds of them kept in one
    process exhaust the compiler's memory on a 2-core CI machine."""
    yield
    from pmdc_bayes.inference import _runtime as cache

    cache.release()
