"""The distinct optima a fit's starts reached: finals that neither lie close together
(in θ, or within a few Laplace standard deviations) nor share one ridge are separated
by a valley of the log-posterior."""

from __future__ import annotations

import numpy as np

__all__ = ["distinct_optima", "precision", "SAME_DISTANCE", "DIP"]

SAME_DISTANCE = 1.0  # Laplace sds (Mahalanobis) within which two finals are one optimum
DIP = 1.0  # log-posterior units: a smaller dip between two finals is no valley


def distinct_optima(thetas, logp, ok, cov, evaluate) -> tuple[list[int], list[int]]:
    """The distinct optima the starts reached: their indices (best first), and for each
    start the index of the optimum it reached (-1 for one that did not converge).

    Two finals are one optimum when they lie within 1e-3 in θ with log-posteriors within
    1e-6 (relative), within :data:`SAME_DISTANCE` Laplace standard deviations of each
    other (Mahalanobis distance under the MAP's covariance ``cov``), or on one ridge: the
    log-posterior (``evaluate(θ).lp``) nowhere on the segment between them dips more
    than :data:`DIP` below the lower of the two.  A distinct optimum is one a valley
    separates from the MAP's.
    """
    order = [int(i) for i in np.argsort(-logp) if np.isfinite(logp[i]) and ok[i]]
    prec = precision(cov)

    def same(i, j):
        d = thetas[i] - thetas[j]
        gap, dlp = np.max(np.abs(d)), abs(logp[i] - logp[j])
        if gap < 1e-3 and dlp < 1e-6 * max(1.0, abs(logp[j])):
            return True
        if float(d @ prec @ d) < SAME_DISTANCE**2:
            return True
        floor = min(logp[i], logp[j]) - DIP
        return all(evaluate(thetas[j] + f * d).lp >= floor for f in (0.25, 0.5, 0.75))

    modes: list[int] = []
    label = [-1] * len(logp)
    for i in order:
        label[i] = next((j for j in modes if same(i, j)), i)
        if label[i] == i:
            modes.append(i)
    return modes, label


def precision(cov) -> np.ndarray:
    """The inverse of a covariance by its eigenvalues (zeros where it is not finite)."""
    if not np.all(np.isfinite(cov)):
        return np.zeros_like(cov)
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    return (vecs / np.clip(vals, 1e-300, None)) @ vecs.T
