"""The correlation built from unconstrained numbers is a correlation, and its prior is
the LKJ density (checked against that density's known marginal)."""

from __future__ import annotations

import numpy as np

from pmdc_bayes.inference.model.correlation import (
    cholesky_corr,
    correlations,
    lkj_log_prior,
    n_pairs,
)


def test_any_numbers_give_a_positive_definite_matrix_with_a_unit_diagonal():
    rng = np.random.default_rng(0)
    for p in (2, 3, 5):
        y = 1.5 * rng.standard_normal((50, n_pairs(p)))
        r = correlations(cholesky_corr(y, p))
        assert np.allclose(np.diagonal(r, axis1=1, axis2=2), 1.0)
        assert np.all(np.linalg.eigvalsh(r) > 0)
        assert np.allclose(r, np.swapaxes(r, 1, 2))
        # far out tanh rounds to ±1: the factor keeps a positive diagonal (invertible)
        far = cholesky_corr(np.full((1, n_pairs(p)), 40.0), p)
        assert np.all(np.diagonal(far, axis1=1, axis2=2) > 0)


def test_two_parameters_correlate_as_the_tanh_of_their_number():
    y = np.array([[-1.2], [0.0], [0.7]])
    r = correlations(cholesky_corr(y, 2))
    assert np.allclose(r[:, 1, 0], np.tanh(y[:, 0]))


def test_the_prior_is_lkj_each_correlation_with_its_beta_marginal():
    # Under LKJ(η) every off-diagonal r of a p × p correlation has (r + 1)/2 ~
    # Beta(η − 1 + p/2, η − 1 + p/2): variance 1/(2η + p − 1).  Importance sampling
    # from a wide Gaussian in y, weighted by the prior, must give that variance for
    # every pair (a wrong shape per level gives pairs different variances).
    rng = np.random.default_rng(1)
    for p, eta in ((3, 1.0), (4, 2.0)):
        y = 1.5 * rng.standard_normal((400_000, n_pairs(p)))
        log_w = lkj_log_prior(y, p, eta) + 0.5 * np.sum((y / 1.5) ** 2, axis=1)
        w = np.exp(log_w - log_w.max())
        w /= w.sum()
        r = correlations(cholesky_corr(y, p))
        expected = 1.0 / (2 * eta + p - 1)
        for i in range(p):
            for j in range(i):
                mean = np.sum(w * r[:, i, j])
                var = np.sum(w * r[:, i, j] ** 2) - mean**2
                assert abs(mean) < 0.01
                assert abs(var - expected) < 0.03 * expected, (p, i, j, var, expected)


def test_one_parameter_has_no_correlation_and_no_prior_term():
    assert n_pairs(1) == 0
    assert np.allclose(cholesky_corr(np.zeros((3, 0)), 1), 1.0)
    assert np.allclose(lkj_log_prior(np.zeros((3, 0)), 1), 0.0)
