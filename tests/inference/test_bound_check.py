"""A motor parameter pressed against zero (its physical bound), far below its prior's
centre with only the prior holding it, fails the adequacy checks; one the data
determine there, or one near its prior's centre, does not."""

from types import SimpleNamespace

import numpy as np

from pmdc_bayes.inference.adequacy.model_checks import BOUND_Z, bound_checks
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session


def _fit(model, shift_b: float, sd_share: float):
    centre, scale = model.registry.prior_arrays()
    k = model.names.index("B")
    theta = np.array(model.theta_seed(), dtype=float)
    theta[k] = centre[k] + shift_b * scale[k]
    cov = np.diag(np.asarray(model.prior_sd) ** 2) * 1e-6
    cov[k, k] = (sd_share * model.prior_sd[k]) ** 2
    return SimpleNamespace(theta=theta, cov_log=cov)


def test_a_friction_pressed_against_zero_fails_and_a_measured_small_one_does_not(session_dir):
    session = load_session(session_dir)
    model = build_model(session, fit_seed(session))
    (f,) = bound_checks(model, _fit(model, -(BOUND_Z + 0.5), 1.0))
    assert f.where == "B" and f.severity == "fail" and "pressed against zero" in f.message
    assert "--allow-inadequate" in f.suggestion
    assert bound_checks(model, _fit(model, -(BOUND_Z + 0.5), 0.1)) == []  # the data hold it
    assert bound_checks(model, _fit(model, -0.5, 1.0)) == []  # near its prior's centre
    assert bound_checks(model, _fit(model, +(BOUND_Z + 0.5), 1.0)) == []  # far above: not zero
