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
    separates from the MAP's.  A start that stalled (at a kink its steps cannot leave)
    reached an optimum where it lies that close to it (:func:`_close`); it makes none.
    """
    order = [int(i) for i in np.argsort(-logp) if np.isfinite(logp[i]) and ok[i]]
    prec = precision(cov)

    def same(i, j):
        d = thetas[i] - thetas[j]
        if _close(d, logp[i], logp[j], prec) or float(d @ prec @ d) < SAME_DISTANCE**2:
            return True
        floor = min(logp[i], logp[j]) - DIP
        return all(evaluate(thetas[j] + f * d).lp >= floor for f in (0.25, 0.5, 0.75))

    modes: list[int] = []
    label = [-1] * len(logp)
    for i in order:
        label[i] = next((j for j in modes if same(i, j)), i)
        if label[i] == i:
            modes.append(i)
    for i in range(len(logp)):  # a start stalled at an optimum (a kink) reached it
        if label[i] < 0 and np.isfinite(logp[i]):
            label[i] = next((j for j in modes if _close(thetas[i] - thetas[j], logp[i],
                                                        logp[j], prec)), -1)
    return modes, label


def _close(d, lp_i, lp_j, prec) -> bool:
    """Whether two finals whose difference is ``d`` are one point: within 1e-3 in θ with
    log-posteriors within 1e-6 (relative), or within :data:`SAME_DISTANCE` Laplace
    standard deviations with log-posteriors within :data:`DIP`."""
    gap, dlp = np.max(np.abs(d)), abs(lp_i - lp_j)
    if gap < 1e-3 and dlp < 1e-6 * max(1.0, abs(lp_j)):
        return True
    return float(d @ prec @ d) < SAME_DISTANCE**2 and dlp < DIP


def precision(cov) -> np.ndarray:
    """The inverse of a covariance by its eigenvalues (zeros where it is not finite)."""
    if not np.all(np.isfinite(cov)):
        return np.zeros_like(cov)
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    return (vecs / np.clip(vals, 1e-300, None)) @ vecs.T
