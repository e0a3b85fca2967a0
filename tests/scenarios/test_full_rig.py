"""Every non-ideality of a real rig at once, drawn by the independent rig simulator: a
dead time, a brush drop (with a rotor braked at 0 V that coasts on with no current), a
current-limited driver, lags in both sensors, Coulomb friction, and a voltage logged
at every sample; the model that declares them all is adequate and recovers every
parameter."""

import dataclasses
import json

import numpy as np
import pytest

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5, "Tc": 1e-3}
RIG = {"dead_time": 0.0023, "voltage_drop": 1.2, "current_limit": 2.5, "speed_lag": 0.004,
       "current_lag": 0.0003}
NUISANCES = ("dead_time", "voltage_drop", "current_limit", "speed_lag", "current_lag")


def _plan():
    t = np.arange(0.0, 0.3, 1.0 / 2000)
    jitter = np.where(t < 0.02, 0.0, 7.0 + np.random.default_rng(1).normal(0.0, 0.2, t.size))
    noise = {"speed_noise": 0.2, "current_noise": 0.005}
    return {"seed": 7, "motor": {"name": "every non-ideality", "friction": "coulomb"},
            "truth": dict(TRUTH), "bench": {"Ra": {"sd": 0.06, "unit": "ohm"}}, "rig": RIG,
            "steady_table": [{"name": "steady", "voltages": [4.0, 8.0, 12.0],
                              "speed_sd": 0.3, "current_sd": 0.0003}],
            "trace": [{"name": "brake", "kind": "step", "duration": 0.4, "rate": 2000.0,
                       "voltage": [[0.0, 0.0], [0.01, 12.0], [0.2, 0.0]], **noise},
                      {"name": "jitter", "kind": "step", "duration": 0.3, "rate": 2000.0,
                       "voltage": [[float(a), float(b)] for a, b in zip(t, jitter,
                                                                       strict=True)],
                       **noise}]}


@pytest.mark.compiles
def test_a_rig_with_every_non_ideality_is_fitted_and_recovered(tmp_path):
    from pmdc_bayes.pipeline import FitOptions, fit_session

    root = simulate_session(_plan(), tmp_path / "s")
    truth = json.loads((root / "truth.json").read_text())
    session = dataclasses.replace(load_session(root), nuisances=NUISANCES)
    res = fit_session(session, FitOptions(mcmc=False))
    assert res.adequacy.verdict == "adequate", [f.message for f in res.adequacy.findings]
    fit = res.fit
    assert set(fit.values) >= {"Vdrop", "Imax", "speed_lag", "current_lag",
                               "dead_time_brake", "dead_time_jitter"}
    for name, value in fit.values.items():
        assert abs(value - truth[name]) < 3 * fit.sd[name], (name, value, truth[name])
