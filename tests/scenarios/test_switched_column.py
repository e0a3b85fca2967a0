"""A voltage column sampled from a switching driver's output (an H-bridge's PWM read by
an ADC far slower than it switches: each reading the supply or zero), on a staircase of
both signs drawn by the independent bench simulator: the column is read as the levels of
its duty, and the ideal motor fits it."""

import numpy as np
import pytest
from conftest import fit_and_assess, logged_stairs

from pmdc_bayes._headline import level_lines
from pmdc_bayes.stage_summary import columns_as_levels

TRUTH = {"Ra": 2.2, "La": 1.5e-3, "K": 0.045, "B": 2e-5, "J": 3e-5}
RATE = 2000.0
SUPPLY = 15.0  # V
LEVELS = ((0.0, 0.0), (0.05, 6.0), (0.35, 12.0), (0.65, -6.0), (0.95, -12.0))


def _session(tmp_path):
    return logged_stairs(tmp_path, seed=5, motor="switched column", truth=TRUTH,
                         levels=LEVELS, rate=RATE, supply=SUPPLY)


def test_the_column_is_read_as_the_levels_of_its_duty(tmp_path):
    session = _session(tmp_path)
    (trace,) = session.traces
    assert trace.voltage.switched
    starts = np.asarray([t for t, _ in LEVELS])
    assert trace.voltage.values.size == len(LEVELS), trace.voltage.times
    # each change shows at the first readings its duty tells from the last one's
    assert np.all(np.abs(trace.voltage.times - starts) <= 10 / RATE), trace.voltage.times
    z = (trace.voltage.values - [v for _, v in LEVELS]) / trace.voltage.se
    assert np.all(np.abs(z) < 4), z
    (line,) = level_lines({"session": {"columns_as_levels": columns_as_levels(session)}})
    assert "switching driver" in line and "5 levels of its duty" in line, line


@pytest.mark.compiles
def test_a_switched_voltage_column_fits_the_ideal_motor(tmp_path):
    _, _, fit, verdict = fit_and_assess(_session(tmp_path))
    assert verdict.verdict == "adequate", verdict.findings
    for name in ("K", "B", "J"):
        assert abs(fit.values[name] - TRUTH[name]) < 3 * fit.sd[name], name
