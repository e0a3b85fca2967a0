"""The independence proposals refitted on the chain during burn-in: when the Laplace
approximation is too narrow they are reshaped on the ensemble's own draws, which then
mixes far better; when it describes the posterior they are left alone, and the mixture
gives them more of the steps."""

import emcee
import numpy as np

from pmdc_bayes.inference.sampling.ensembles import Ensembles
from pmdc_bayes.inference.sampling.moves import SHARE, SHARE_TRUSTED, LaplaceMixture
from pmdc_bayes.inference.sampling.posterior import LaplaceIndependenceMove
from pmdc_bayes.inference.sampling.stopping import stop_message

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


def _mixture_run(cov, *, steps: int, seed: int, refit: bool = True):
    """Two ensembles of a :class:`LaplaceMixture` (proposals centred on 0 with ``cov``)
    on the wide target; adapted once after a 50-step pilot."""
    rng = np.random.default_rng(seed)
    p0 = rng.standard_normal((16, 3)) * SD
    e = Ensembles(2, 16, 3, _target, p0, _target(p0), seed=seed,
                  moves=lambda j: [(LaplaceMixture(LaplaceIndependenceMove(np.zeros(3), cov)),
                                    1.0)])
    e.run_mcmc(50)
    changed = e.adapt(below=0.3, wider=1.5, refit=refit)
    e.run_mcmc(steps)
    return changed, e


def test_the_mixture_trusts_proposals_that_fit_and_still_samples_the_target():
    changed, e = _mixture_run(np.diag(SD**2), steps=1500, seed=7)
    mixes = [ms[0][0] for ms in e.moves]
    assert changed and all(m.share == SHARE_TRUSTED for m in mixes)
    assert not e.adapt(below=0.3, wider=1.5)  # nothing more to change
    draws = e.get_chain(discard=50).reshape(-1, 3)  # the pilot's steps are burn-in
    # 48,000 draws of near-independent points: the moments of N(0, diag(SD²))
    assert np.all(np.abs(draws.mean(axis=0)) < 0.1 * SD), draws.mean(axis=0)
    np.testing.assert_allclose(draws.std(axis=0), SD, rtol=0.05)
    # the trusted share made the chain mix in fewer steps than the even split does
    fixed = Ensembles(2, 16, 3, _target, draws[:16], _target(draws[:16]), seed=7,
                      moves=lambda j: [(LaplaceMixture(LaplaceIndependenceMove(
                          np.zeros(3), np.diag(SD**2))), 1.0)])
    fixed.run_mcmc(1500)
    assert e.get_autocorr_time().max() < 0.8 * fixed.get_autocorr_time().max()


def test_the_mixture_does_not_trust_proposals_narrower_than_the_chain():
    # unit proposals against a target 5 times wider along one axis: at the pilot
    # (refits not allowed) the share stays; at a later check the proposals are refitted
    changed, e = _mixture_run(np.eye(3), steps=150, seed=8, refit=False)
    assert not changed
    assert all(ms[0][0].share == SHARE for ms in e.moves)
    assert e.adapt(below=0.3, wider=1.5)
    for ms in e.moves:
        mix = ms[0][0]
        assert mix.share == SHARE and mix.independence.acceptance is None  # refitted


def test_the_mixtures_share_decides_which_move_steps():
    rng = np.random.default_rng(9)
    p0 = rng.standard_normal((16, 3))
    counts = {}
    for share in (0.0, 1.0, 0.5):
        mix = LaplaceMixture(LaplaceIndependenceMove(np.zeros(3), np.eye(3)), share=share)
        e = Ensembles(1, 16, 3, _target, p0, _target(p0), seed=1,
                      moves=lambda j, mix=mix: [(mix, 1.0)])
        e.run_mcmc(400)
        counts[share] = mix.independence._tried // 16  # steps the independence move took
    assert counts[0.0] == 0 and counts[1.0] == 400
    assert 160 < counts[0.5] < 240
