"""The independence proposals refitted on the chain during burn-in: when the Laplace
approximation is too narrow they are reshaped on the ensemble's own draws, which then
mixes far better; when it describes the posterior they are left alone."""

import emcee
import numpy as np

from pmdc_bayes.inference.ensembles import Ensembles
from pmdc_bayes.inference.sampling import LaplaceIndependenceMove
from pmdc_bayes.inference.stopping import stop_message

SD = np.array([5.0, 1.0, 1.0])  # the target: 5 times wider along the first axis


def _target(x):
    return -0.5 * np.sum((np.atleast_2d(x) / SD) ** 2, axis=1)


def test_misfits_sees_a_chain_wider_than_the_proposal_and_refit_reshapes_it():
    rng = np.random.default_rng(0)
    move = LaplaceIndependenceMove(np.zeros(3), np.eye(3))
    wide = rng.standard_normal((4000, 3)) * SD
    alike = rng.standard_normal((4000, 3))
    assert move.misfits(wide, below=0.3, wider=1.5)
    assert not move.misfits(alike, below=0.3, wider=1.5)
    assert move.refit(wide + 2.0)
    np.testing.assert_allclose(move.mean, 2.0, atol=0.2)
    assert not move.misfits(wide, below=0.3, wider=1.5)
    # too few draws to define a covariance: kept as it was
    before = move.mean.copy()
    assert not move.refit(wide[:5]) and np.array_equal(move.mean, before)


def test_low_acceptance_alone_asks_for_a_refit():
    move = LaplaceIndependenceMove(np.zeros(3), np.eye(3))
    move._tried, move._taken = 100, 10
    assert move.acceptance == 0.1
    alike = np.random.default_rng(1).standard_normal((4000, 3))
    assert move.misfits(alike, below=0.3, wider=1.5)
    move.refit(alike)
    assert move.acceptance is None  # counted afresh after a refit


def _run(adapt: bool):
    """Two ensembles on the wide target, proposals from a unit 'Laplace' covariance;
    with ``adapt``, refitted once after 200 steps.  The independence moves' acceptance
    over the last 600 steps."""
    rng = np.random.default_rng(3)
    p0 = rng.standard_normal((16, 3))
    moves = lambda j: [(LaplaceIndependenceMove(np.zeros(3), np.eye(3)), 1.0)]  # noqa: E731
    e = Ensembles(2, 16, 3, _target, p0, _target(p0), moves=moves, seed=4)
    e.run_mcmc(200)
    changed = e.adapt(below=0.3, wider=1.5) if adapt else False
    for ms in e.moves:
        ms[0][0]._tried = ms[0][0]._taken = 0
    e.run_mcmc(600)
    rate = np.mean([ms[0][0].acceptance for ms in e.moves])
    return changed, rate, e


def test_refitting_on_each_ensembles_own_chain_lifts_the_acceptance():
    changed, adapted, e = _run(adapt=True)
    assert changed
    _, fixed, _ = _run(adapt=False)
    assert adapted > 0.6 and fixed < 0.45, (adapted, fixed)
    # each ensemble refitted on its own walkers only: their proposals differ
    a, b = (ms[0][0] for ms in e.moves)
    assert not np.allclose(a.mean, b.mean)


def test_a_proposal_that_fits_is_not_refitted():
    rng = np.random.default_rng(5)
    p0 = rng.standard_normal((16, 3)) * SD
    moves = lambda j: [(LaplaceIndependenceMove(np.zeros(3), np.diag(SD**2)), 0.5),  # noqa: E731
                       (emcee.moves.DEMove(), 0.5)]
    e = Ensembles(2, 16, 3, _target, p0, _target(p0), moves=moves, seed=6)
    e.run_mcmc(200)
    assert not e.adapt(below=0.3, wider=1.5)


def test_the_stop_message_counts_the_steps_after_the_last_refit():
    kw = {"min_tau_multiple": 50.0, "elapsed": 60.0, "max_seconds": 60.0}
    text = stop_message(1200, [3.0, 20.0], ("Ra", "J"), settled=True, adapted=400, **kw)
    # 800 steps since the refit are 40 τ_max: 1000 more than the refit, 1400 in all
    assert "(the limit, 60 s; 1200 steps)" in text
    assert "about 1400 steps, ~70 s here, would be needed" in text
    done = stop_message(1600, [3.0, 20.0], ("Ra", "J"), settled=True, converged=True,
                        adapted=400, min_tau_multiple=50.0)
    assert done == "converged after 1600 steps: 60 × τ_max (τ_max 20.0 steps, J)"
