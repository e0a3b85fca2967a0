"""The sampler's fast path assumes the motor's two modes are real and apart; a known
viscous drag moves them, so the gate reads each segment's drag from the session's
data, not from the session that compiled the program: two sessions of one structure,
one whose drag makes the modes complex, each get their own exact log-posterior."""

import dataclasses

import jax
import numpy as np

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.inference.sampling.posterior import _log_posterior_batch
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Drag
from pmdc_bayes.physics.propagator import real_modes


@x64
def test_a_drag_that_makes_the_modes_complex_is_not_taken_on_the_fast_path(session_dir):
    base = load_session(session_dir)
    model = build_model(base, fit_seed(base))
    theta = np.asarray(model.theta_seed())
    p = model.params(theta)
    # the viscous drag that puts B/J at Ra/La: the modes' discriminant turns negative
    b = float(p.Ra / p.La * p.J - p.B)
    assert not bool(real_modes(p._replace(B=p.B + b))) and bool(real_modes(p))
    models = []
    for drag in (1e-3 * b, b):  # the same structure, a mild drag first
        s = dataclasses.replace(base, traces=tuple(dataclasses.replace(tr, drag=Drag(
            viscous=drag)) for tr in base.traces))
        models.append(build_model(s, fit_seed(base)))
    thetas = np.tile(theta, (8, 1))
    for m in models:
        batch = np.asarray(_log_posterior_batch(m)(thetas))
        slow = np.asarray(jax.vmap(lambda t, m=m: m.log_posterior(t, fast=False))(thetas))
        np.testing.assert_allclose(batch, slow, rtol=1e-10)
