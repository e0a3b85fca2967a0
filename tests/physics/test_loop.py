"""Stability margins of a PI speed loop around the motor, against python-control."""

from __future__ import annotations

import numpy as np
import pytest

from pmdc_bayes._headline import pi_loop_text
from pmdc_bayes.cli import main
from pmdc_bayes.physics.loop import pi_loop, pi_margins

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

control = pytest.importorskip("control")

MOTOR = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4}
SMALL = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5}


def _reference(p, kp, ki, delay):
    g = control.tf([p["K"]], [p["J"] * p["La"], p["J"] * p["Ra"] + p["B"] * p["La"],
                              p["B"] * p["Ra"] + p["K"] ** 2])
    pi = control.tf([kp, ki], [1, 0]) if ki else control.tf([kp], [1])
    loop = pi * g
    if delay:
        loop = loop * control.tf(*control.pade(delay, 12))
    gm, pm, wg, wp = control.margin(loop)
    return 20 * np.log10(gm) if np.isfinite(gm) else np.inf, pm, wp, wg


@pytest.mark.parametrize(("p", "kp", "ki", "delay"), [
    (MOTOR, 0.5, 5.0, 0.0), (MOTOR, 0.5, 5.0, 0.002), (MOTOR, 2.0, 40.0, 0.005),
    (MOTOR, 0.05, 0.3, 0.0), (SMALL, 0.02, 1.0, 0.001), (SMALL, 0.2, 0.0, 0.0005),
])
def test_margins_match_python_control(p, kp, ki, delay):
    ours = pi_margins(*(p[n] for n in ("Ra", "La", "K", "B", "J")), kp, ki, delay)
    gm, pm, wg_pm, wp_gm = _reference(p, kp, ki, delay)
    assert ours["phase_margin_deg"] == pytest.approx(pm, rel=1e-4)
    assert ours["gain_crossover"] == pytest.approx(wg_pm, rel=1e-4)
    if np.isinf(gm):  # no delay: the phase tends to -180° and never reaches it
        assert ours["gain_margin_db"] == np.inf and np.isnan(ours["phase_crossover"])
    else:
        assert ours["gain_margin_db"] == pytest.approx(gm, rel=1e-4)
        assert ours["phase_crossover"] == pytest.approx(wp_gm, rel=1e-4)


def test_the_spread_over_draws_brackets_the_estimate_and_counts_the_risky_draws():
    rng = np.random.default_rng(0)
    draws = [dict(MOTOR, J=MOTOR["J"] * f) for f in np.exp(rng.normal(0, 0.3, 400))]
    rec = pi_loop(2.0, 40.0, 0.005, MOTOR, draws)
    at, over = rec["at_estimate"], rec["over_draws"]
    lo, mid, hi = over["phase_margin_deg"]
    assert lo < at["phase_margin_deg"] < hi and lo < mid < hi
    # a larger inertia lowers the crossover's phase margin here; the share under 45°
    # is the share of draws whose own margin is under 45°
    pms = [pi_margins(*(d[n] for n in ("Ra", "La", "K", "B", "J")), 2.0, 40.0, 0.005)
           ["phase_margin_deg"] for d in draws]
    assert over["share_pm_below_45"] == pytest.approx(np.mean(np.array(pms) < 45))
    assert 0 < over["share_pm_below_45"] < 1
    text = pi_loop_text(rec)
    assert text.startswith("PI loop kp=2, ki=40, delay 5 ms: phase margin ")
    # without a delay the gain margin is infinite, and JSON gets None for it
    rec = pi_loop(0.5, 5.0, 0.0, MOTOR, draws[:5])
    assert rec["at_estimate"]["gain_margin_db"] is None
    assert rec["over_draws"]["gain_margin_db"] == [None, None, None]
    assert "gain margin ∞" in pi_loop_text(rec)
    assert pi_loop_text(pi_loop(0.5, 5.0, 0.0, MOTOR)).endswith(
        "(no posterior draws: no spread)")


@pytest.mark.parametrize("bad", ["0.5", "a,b", "0.5,5,1,2", "-1,5", "0,0", "nan,1"])
def test_a_malformed_pi_is_bad_input(bad, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["fit", "demo", "--pi", bad])
    assert exc.value.code == 2
    assert "--pi" in capsys.readouterr().err
