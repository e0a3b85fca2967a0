"""The rank plots' histograms: walkers pooled into sets, each bin's count over its count
under exchangeable sets."""

import numpy as np

from pmdc_bayes.report.fig_chains import pooled_ranks


def test_exchangeable_walkers_give_flat_rank_histograms():
    x = np.random.default_rng(0).normal(size=(32, 2000))
    h = pooled_ranks(x, 4)
    assert h.shape == (4, 20)
    assert np.allclose(h.mean(axis=1), 1.0)  # each set holds a quarter of the draws
    assert np.abs(h - 1.0).max() < 0.2


def test_a_set_of_walkers_stuck_high_has_its_ranks_piled_at_the_top():
    x = np.random.default_rng(1).normal(size=(32, 2000))
    x[24:] += 1.0  # the last set (walkers 24-31) sits one sd higher
    h = pooled_ranks(x, 4)
    assert h[3, -1] > 2.0 and h[3, 0] < 0.2
    assert h[0, -1] < h[0, 0]  # the other sets lose the top ranks to it
