"""A trace that brakes a turning rotor at 0 V on a rig with a brush drop, drawn by the
independent rig simulator: the drop opposes the braking current, which stops once the
back-emf falls below the drop, and the rotor then coasts with no current; the model
follows that (the current's zero crossing and the open phase after it) and recovers the
drop."""

import numpy as np
import pytest
from conftest import SMALL_MOTOR, fit_and_assess, plan, sweep

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session


def _plan(name: str, duration: float) -> dict:
    return plan(seed=5, motor="braked at 0 V", friction="coulomb",
                truth={**SMALL_MOTOR, "Tc": 1e-3}, bench={"Ra": (0.05, "ohm"), "La": (0.1, "mH")},
                rig={"voltage_drop": 1.5},
                steady=(sweep([4.0, 8.0, 12.0], 0.3, 0.0003, name="steady"),),
                traces=({"name": name, "kind": "step", "duration": duration, "rate": 2000.0,
                         "voltage": [[0.0, 0.0], [0.01, 12.0], [0.15, 0.0]], "speed_noise": 0.3,
                         "current_noise": 0.005},))


@pytest.mark.compiles
@pytest.mark.parametrize(("duration", "brakes"), [(0.4, True), (0.14, False)])
def test_braking_at_zero_volts_against_a_drop_is_fitted(tmp_path, duration, brakes):
    name = "brake" if brakes else "no_brake"
    session = load_session(simulate_session(_plan(name, duration), tmp_path / "s"))
    _, model, fit, verdict = fit_and_assess(session, nuisances=("voltage_drop",))
    assert verdict.verdict == "adequate", verdict.findings
    assert abs(fit.values["Vdrop"] - 1.5) < 3 * fit.sd["Vdrop"], fit.values["Vdrop"]
    if brakes:  # the current stops within the record: the open phase is reached
        tr = session.traces[0]
        ia = model.predict(fit.theta)[0][0]
        late = tr.time > 0.3
        assert np.abs(ia[late]).max() < 1e-9
        assert np.abs(tr.speed[late]).min() > 10.0  # while the rotor still turns
