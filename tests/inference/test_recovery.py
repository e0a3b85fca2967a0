"""Parameter recovery on synthetic sessions with known truth (issue 4).

A table of motors from a 2 W hobby motor to a 200 W servo (``recovery_cases.py``),
with and without load changes, with and without current logging, viscous and
Coulomb friction: simulate a session, apply the closed form, fit the MAP, and check
that every parameter lies within 3 Laplace standard deviations of the truth.
Then a negative control (a wrong logged voltage must show in the residuals) and two
known weaknesses, kept as strict expected failures so that a fix is noticed.

Seeds are fixed, so every check is deterministic.  With ~55 checks at 3σ the chance
that one of them fails by chance, if the z-scores were exactly N(0, 1), is about
1 − 0.9973⁵⁵ ≈ 14 %; the seeds below were fixed before looking at the results
(``SEED_BASE`` + the motor's row).
"""



import re  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from recovery_cases import (  # noqa: E402
    CURRENT_NOISE,
    MOTORS,
    SPEED_NOISE,
    STEADY_NOISE,
    plan_for,
)

from pmdc_bayes.inference.fit.joint import fit_map  # noqa: E402
from pmdc_bayes.inference.model.objective import build_model  # noqa: E402
from pmdc_bayes.io.channel import ChannelId  # noqa: E402
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.paper.closed_form import closed_form  # noqa: E402
from pmdc_bayes.simulate.session import simulate_session  # noqa: E402
from pmdc_bayes.stage_summary import trace_rms  # noqa: E402

SEED_BASE = 100
BY_NAME = {m.name: m for m in MOTORS}
SEEDS = {m.name: SEED_BASE + k for k, m in enumerate(MOTORS)}
# servo-200W: its no-load current (~17 mA) is below the steady current noise (48 mA),
# so the closed-form B of equation (19) is negative for about half the seeds (6 of 12
# in 100-111; its own seed 109 happens to give a positive one), and fit_map then
# fails: see test_negative_closed_form_friction_seed.
SERVO_NEGATIVE_B_SEED = 101


def _fit(motor, tmp_path, *, seed, **plan_options):
    session = load_session(simulate_session(plan_for(motor, seed=seed, **plan_options),
                                            tmp_path / motor.name))
    cf = closed_form(session)
    model = build_model(session, cf)
    return session, cf, model, fit_map(model)


def _z_scores(session, model, fit) -> dict:
    return {k: (fit.values[k] - session.truth[k]) / fit.sd[k] for k in model.names}


@pytest.mark.statistical  # the first motor of each structure compiles the fit (15-45 s)
@pytest.mark.parametrize("motor", MOTORS, ids=[m.name for m in MOTORS])
def test_map_within_3_laplace_sd_of_truth(motor, tmp_path):
    session, _, model, fit = _fit(motor, tmp_path, seed=SEEDS[motor.name])
    assert fit.ok, fit.message
    z = _z_scores(session, model, fit)
    report = ", ".join(f"{k} {v:+.2f}" for k, v in z.items())
    assert set(z) == ({"Ra", "La", "K", "B", "J", "Tc"} if motor.Tc > 0
                      else {"Ra", "La", "K", "B", "J"})
    for name, value in z.items():
        assert abs(value) <= 3.0, f"{name}: z = {value:+.2f} (all: {report})"


# Negative control


def _set_step_voltage(session_toml, volts: float) -> None:
    """Rewrite the final voltage of the trace named "step" in session.toml."""
    text = session_toml.read_text(encoding="utf-8")
    blocks = text.split("[[trace]]")
    (k,) = [i for i, b in enumerate(blocks) if 'name = "step"' in b]
    blocks[k], n = re.subn(r"voltage = \[\[0, 0\], \[([^,\]]+), [^\]]+\]\]",
                           rf"voltage = [[0, 0], [\1, {volts:g}]]", blocks[k])
    assert n == 1, blocks[k]
    session_toml.write_text("[[trace]]".join(blocks), encoding="utf-8")


@pytest.mark.compiles
def test_wrong_logged_voltage_shows_in_that_traces_residuals(tmp_path):
    motor = BY_NAME["tool-20W"]  # a 12 V motor; session: step, capture (viscous+current)
    noise = {"speed": SPEED_NOISE * motor.V / motor.K,
             "current": CURRENT_NOISE * motor.V / motor.Ra}
    steady_speed_sd = STEADY_NOISE * motor.V / motor.K
    plan = plan_for(motor, seed=7)
    good = load_session(simulate_session(plan, tmp_path / "good"))
    bad_dir = simulate_session(plan, tmp_path / "bad")
    _set_step_voltage(bad_dir / "session.toml", 10.0)  # simulated at 12 V, logged as 10 V
    bad = load_session(bad_dir)
    assert bad.trace("step").voltage.values[-1] == 10.0
    rms, fits = {}, {}
    for name, session in (("good", good), ("bad", bad)):
        model = build_model(session, closed_form(session))
        fits[name] = fit_map(model)
        assert fits[name].ok, fits[name].message
        rms[name] = trace_rms(model, fits[name].theta)
    # The correct session: every trace's residuals are white noise of the simulated sd.
    # RMS of n = 401 residuals is within ~1/sqrt(2n) = 3.5 % of sd; 20 % is ~6 of those.
    for trace, row in rms["good"].items():
        for channel, value in row.items():
            assert value == pytest.approx(noise[channel], rel=0.2), (trace, channel, value)
    # The mislabelled trace: its current cannot follow 12 V's current with 10 V.
    assert rms["bad"]["step"]["current"] > 5.0 * noise["current"], rms["bad"]
    # Its speed, though, is fitted to the noise level (~1.07x): the parameters bend to
    # 10 V, and the conflict goes to the steady table, whose integrated noise level
    # rises from ~1.4 rad/s (the simulated 0.67 rad/s, pulled up by the prior scale
    # s0 = 1 % of the typical speed) to ~80 rad/s, and to the capture's speed (~4.5x).
    good_sd, bad_sd = (fits[k].noise_sd[ChannelId("steady", "speed")] for k in ("good", "bad"))
    assert good_sd < 3.0 * steady_speed_sd, fits["good"].noise_sd
    assert bad_sd > 20.0 * good_sd, fits["bad"].noise_sd


# A weakness these tests found and that is fixed (a non-physical closed-form seed), and
# one kept as a strict expected failure: when it is fixed the test passes, pytest
# reports it, and the marker should go.


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")
def test_negative_closed_form_friction_seed(tmp_path):
    motor = BY_NAME["servo-200W"]
    session, cf, model, fit = _fit(motor, tmp_path, seed=SERVO_NEGATIVE_B_SEED)
    assert cf.B < 0.0  # the situation under test: equation (19) on noisy data
    assert fit.ok, fit.message
    z = _z_scores(session, model, fit)
    assert all(abs(v) <= 3.0 for v in z.values()), z


@pytest.mark.compiles
@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "known limitation of the Laplace approximation: with only 5 steady readings the "
    "steady-current channel's noise level at the joint mode is ~SS/(n + nu0) while the "
    "parameters absorb several of its n degrees of freedom, so the Laplace sd of K and "
    "B is ~2x too small even with the noise-integration curvature term; the posterior "
    "(which integrates the noise level) is what to trust, and the run's Laplace check "
    "flags parameters whose Laplace and posterior sds differ by more than 20 %"))
def test_laplace_sd_with_a_small_steady_table(tmp_path):
    motor = BY_NAME["toy-5W"]
    z = []
    for seed in range(12):
        session, _, model, fit = _fit(motor, tmp_path / str(seed), seed=seed, n_steady=4)
        assert fit.ok, fit.message
        z.append([v for v in _z_scores(session, model, fit).values()])
    rms = dict(zip(model.names, np.sqrt(np.mean(np.square(z), axis=0)), strict=True))
    print("RMS z with a 4-row steady table:", rms)
    # RMS of 12 N(0, 1) z-scores: chi(12)/sqrt(12), above 1.5 with probability ~3e-4.
    assert max(rms.values()) <= 1.5, rms
