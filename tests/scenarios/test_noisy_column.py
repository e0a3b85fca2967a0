"""A staircase of both signs whose voltage is logged by an ADC (a noisy column), on a
motor with Coulomb friction, drawn by the independent bench simulator: the column is read
as the levels the driver held, and the stick-slip model fits it."""

import numpy as np
import pytest
from conftest import fit_and_assess, logged_stairs

from pmdc_bayes._headline import level_lines
from pmdc_bayes.stage_summary import columns_as_levels

TRUTH = {"Ra": 2.2, "La": 1.5e-3, "K": 0.045, "B": 2e-5, "J": 3e-5, "Tc": 4e-3}
RATE = 2000.0
LEVELS = ((0.0, 0.0), (0.05, 6.0), (0.35, 12.0), (0.65, -6.0), (0.95, -12.0))
COLUMN_SD = 0.05  # V


def _session(tmp_path):
    return logged_stairs(tmp_path, seed=4, motor="noisy column", friction="coulomb",
                         truth=TRUTH, levels=LEVELS, rate=RATE, noise=COLUMN_SD)


@pytest.mark.compiles
def test_a_noisy_voltage_column_is_read_as_its_levels_and_fits(tmp_path):
    session = _session(tmp_path)
    (trace,) = session.traces
    assert trace.voltage_logged
    assert np.allclose(trace.voltage.times, [t for t, _ in LEVELS])
    held = np.diff(np.append(trace.voltage.times, trace.time[-1] + 1 / RATE)) * RATE
    assert np.all(np.abs(trace.voltage.values - [v for _, v in LEVELS])
                  < 5 * COLUMN_SD / np.sqrt(held)), trace.voltage.values
    _, _, fit, verdict = fit_and_assess(session)
    assert verdict.verdict == "adequate", verdict.findings
    for name in ("K", "B", "J", "Tc"):
        assert abs(fit.values[name] - TRUTH[name]) < 3 * fit.sd[name], name


def test_the_run_says_a_column_was_read_as_its_levels(tmp_path):
    session = _session(tmp_path)
    read = columns_as_levels(session)
    assert set(read) == {"stairs"} and set(read["stairs"]) == {"voltage"}
    assert read["stairs"]["voltage"]["levels"] == len(LEVELS)
    assert abs(read["stairs"]["voltage"]["noise_sd"] / COLUMN_SD - 1.0) < 0.15
    (line,) = level_lines({"session": {"columns_as_levels": read}})
    assert line.startswith("stairs: the voltage column") and "5 levels" in line, line
