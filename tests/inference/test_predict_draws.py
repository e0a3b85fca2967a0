"""The predictive draws come from the batched residuals (one compiled program with the
pointwise log-likelihood) and equal the one-θ prediction at each draw."""

import numpy as np

from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session


def test_the_draws_predict_what_one_theta_does(session_dir):
    session = load_session(session_dir)
    model = build_model(session, fit_seed(session))
    rng = np.random.default_rng(0)
    thetas = np.asarray(model.theta_seed()) + 0.05 * rng.standard_normal((3, len(model.names)))
    draws = model.predict_draws(thetas)
    (tr,) = session.traces
    (ia, w, angle), = draws
    assert ia.shape == w.shape == (3, tr.n) and angle is None
    for k, theta in enumerate(thetas):
        ((ia1, w1),) = model.predict(theta)
        np.testing.assert_allclose(w[k], w1, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ia[k], ia1, rtol=1e-12, atol=1e-12)
