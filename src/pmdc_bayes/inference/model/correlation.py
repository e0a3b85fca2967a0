"""A correlation matrix from unconstrained numbers, with the LKJ prior on it.

The ``P(P−1)/2`` numbers ``y`` are the canonical partial correlations ``z = tanh(y)``
of a C-vine (Lewandowski, Kurowicka & Joe 2009), row by row below the diagonal; the
Cholesky factor of the correlation is built from them as Stan builds its
``cholesky_factor_corr``.  Under the LKJ(η) density on the correlation
(``∝ det(R)^(η−1)``) the partial correlations are independent, the one at level ``k``
(conditioned on ``k − 1`` others) ``Beta(β_k, β_k)`` on ``(−1, 1)`` with
``β_k = η + (P − 1 − k)/2``; in ``y`` each has log-density ``β_k·log(1 − z²)`` up to a
constant (its Jacobian included).  Everything is vectorised over a leading axis.
"""

from __future__ import annotations

import numpy as np

__all__ = ["n_pairs", "cholesky_corr", "lkj_log_prior", "correlations", "ETA"]

ETA = 2.0  # LKJ shape: mild shrinkage toward no correlation
_FLOOR = 1e-200


def n_pairs(p: int) -> int:
    """How many correlations a ``p × p`` matrix has."""
    return p * (p - 1) // 2


def _rows(p: int):
    """``(i, j)`` of each partial correlation, in the order ``y`` holds them."""
    return [(i, j) for i in range(1, p) for j in range(i)]


def cholesky_corr(y, p: int) -> np.ndarray:
    """``(W, p, p)``: the lower Cholesky factors of the correlations whose partial
    correlations are ``tanh(y)`` (``y`` of shape ``(W, n_pairs(p))``)."""
    y = np.atleast_2d(np.asarray(y, dtype=float))
    z = np.tanh(y)
    w = y.shape[0]
    chol = np.zeros((w, p, p))
    chol[:, 0, 0] = 1.0
    k = 0
    for i in range(1, p):
        left = np.ones(w)  # 1 − the squares of the row so far
        for j in range(i):
            chol[:, i, j] = z[:, k] * np.sqrt(left)
            left = left - chol[:, i, j] ** 2
            k += 1
        chol[:, i, i] = np.sqrt(np.maximum(left, _FLOOR))  # tanh rounds to ±1 far out
    return chol


def lkj_log_prior(y, p: int, eta: float = ETA) -> np.ndarray:
    """``(W,)``: the LKJ(η) log-density of the correlations ``y`` stand for, in ``y``
    (up to a constant)."""
    y = np.atleast_2d(np.asarray(y, dtype=float))
    if y.shape[1] == 0:
        return np.zeros(y.shape[0])
    beta = np.array([eta + (p - 2 - j) / 2.0 for _, j in _rows(p)])
    # log(1 − tanh²y) = −2·log(cosh y), written to stay finite for large |y|
    log_one_minus_z2 = 2.0 * (np.log(2.0) - np.abs(y) - np.log1p(np.exp(-2.0 * np.abs(y))))
    return np.sum(beta * log_one_minus_z2, axis=1)


def correlations(chol) -> np.ndarray:
    """``(W, p, p)``: the correlation matrices of Cholesky factors ``chol``."""
    chol = np.asarray(chol)
    return chol @ np.swapaxes(chol, -1, -2)
