"""The regime-switching solution follows at most PHASES regime changes per input segment;
a segment that changes more often (an underdamped armature ringing through zero under
a voltage drop) is flagged, the flag is what makes the prediction inexact (the same
segment cut in pieces, each within the cap, is predicted otherwise), and the adequacy
checks fail it with what to do."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.adequacy.model_checks import solver_checks
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.physics.experiment import stack_experiments
from pmdc_bayes.physics.limited import PHASES
from pmdc_bayes.physics.solution import Params, simulate_padded
from pmdc_bayes.simulate.session import simulate_session

T = np.arange(0.0, 3.0, 1e-3)
VT, VV = [0.0, 0.1, 2.0], [0.0, 12.0, 0.0]


@x64
def _run(la, cuts=None):
    exp = stack_experiments([(T, VT, VV, None, None, "rest", cuts)])
    p = Params(Ra=2.0, La=la, K=0.05, B=2e-5, J=2e-5, Tc=1e-3)
    ia, w, flags = simulate_padded(p, exp, coulomb=True, drop=0.8, overflow=True)
    return np.asarray(exp.unpad(ia)), np.asarray(exp.unpad(w)), np.asarray(flags)


def test_a_segment_ringing_past_the_cap_is_flagged_and_is_where_the_solution_errs():
    ia, w, flags = _run(2e-3)
    assert not flags.any()
    ia, w, flags = _run(0.5)  # the armature rings at about 2.5 Hz, braking at 0 V
    assert flags.tolist() == [False, False, True]
    # each zero crossing of the current is two changes (to no current, then back)
    crossings = np.flatnonzero(np.diff(np.sign(ia[T >= 2.0])) != 0)
    assert 2 * crossings.size >= PHASES
    # the braking segment cut in pieces at the same 0 V: each within the cap
    ia_cut, w_cut, flags_cut = _run(0.5, cuts=np.arange(2.1, 3.0, 0.1))
    assert flags_cut.size == 12 and not flags_cut.any()
    before = T < 2.0
    np.testing.assert_allclose(w_cut[before], w[before], rtol=1e-9, atol=1e-9)
    assert np.abs(w_cut - w).max() > 0.5  # rad/s: after the cap the flagged run is wrong


@pytest.mark.compiles
def test_the_adequacy_checks_fail_a_trace_beyond_the_cap(tmp_path):
    truth = {"Ra": 2.0, "La": 0.5, "K": 0.05, "B": 2e-5, "J": 2e-5, "Tc": 1e-3}
    plan = {"seed": 1, "motor": {"name": "ringing", "friction": "coulomb"}, "truth": truth,
            "bench": {"Ra": {"sd": 0.05, "unit": "ohm"}}, "rig": {"voltage_drop": 0.8},
            "trace": [{"name": "brake", "kind": "step", "duration": 3.0, "rate": 1000.0,
                       "voltage": [[0.0, 0.0], [0.1, 12.0], [2.0, 0.0]],
                       "speed_noise": 0.05, "current_noise": 0.002},
                      {"name": "plain", "kind": "step", "duration": 1.0, "rate": 1000.0,
                       "voltage": [[0.0, 0.0], [0.1, 6.0]],
                       "speed_noise": 0.05, "current_noise": 0.002}]}
    root = simulate_session(plan, tmp_path / "s")
    session = dataclasses.replace(load_session(root), nuisances=("voltage_drop",))
    model = build_model(session, fit_seed(session))
    theta = model.theta({**truth, "Vdrop": 0.8})
    starts = model.beyond_phases(theta)
    assert [s.size for s in starts] == [1, 0] and starts[0][0] == pytest.approx(2.0)
    (finding,) = solver_checks(model, SimpleNamespace(theta=theta))
    assert finding.severity == "fail" and finding.where == "brake"
    assert f"more than {PHASES} times" in finding.message and "t = 2 s" in finding.message
    assert "log the voltage as a column" in finding.suggestion
