"""A speed-only session whose logged voltage shows each step at the first sample after
the rig switched (a logger sampling the driver's output), drawn by the independent bench
simulator: the ideal model cancels the lateness by pressing La against zero, and the
verdict names the cause and proposes a dead time, which then fits it."""

import pytest
from conftest import fit_and_assess, plan, step, sweep

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session

RATE = 1000.0  # Hz; the rig switches 0.3 of a sample after a sample
SWITCH = 0.0503  # s
TRUTH = {"Ra": 4.0, "La": 2e-3, "K": 0.02, "B": 4e-6, "J": 5e-6}


def _session(tmp_path):
    traces = tuple(step(f"step_{v:g}v", v, duration=0.3, rate=RATE, at=SWITCH,
                        record_current=False, speed_noise=0.5) for v in (12.0, 6.0))
    root = simulate_session(plan(seed=3, motor="logged late", truth=TRUTH,
                                 bench={"Ra": (0.08, "ohm")},
                                 steady=(sweep([3.0, 6.0, 9.0, 12.0], 1.0, 0.0005),),
                                 traces=traces), tmp_path / "s")
    toml = root / "session.toml"
    logged = f"{(int(SWITCH * RATE) + 1) / RATE!r}"  # the first sample after the switch
    text = toml.read_text()
    assert text.count(f"[{SWITCH!r}, ") == 2
    toml.write_text(text.replace(f"[{SWITCH!r}, ", f"[{logged}, "))
    return load_session(root)


@pytest.mark.compiles
def test_a_response_leading_its_logged_voltage_is_named_and_a_dead_time_fits_it(tmp_path):
    session = _session(tmp_path)
    ideal = fit_and_assess(session).verdict
    assert ideal.verdict == "inadequate"
    assert any(f.where == "La" and f.failed for f in ideal.findings), ideal.findings
    assert any("--add dead-time" in line for line in ideal.diagnosis), ideal.diagnosis
    assert any(p.nuisance == "dead_time" for p in ideal.proposals), ideal.proposals
    _, _, fit, timed = fit_and_assess(session, nuisances=("dead_time",))
    assert timed.verdict == "adequate", timed.findings
    for name in ("K", "B", "J"):
        assert abs(fit.values[name] - TRUTH[name]) < 3 * fit.sd[name], name
