"""The sampler's moves: independence proposals from the Laplace approximation, refitted
on the chain during burn-in where that approximation is too narrow, mixed with
differential evolution; the mixture leans on the independence proposals once the chain
shows that they are mostly accepted."""

from __future__ import annotations

import emcee
import numpy as np

__all__ = ["LaplaceIndependenceMove", "LaplaceMixture", "default_moves"]

SHARE = 0.5  # the independence proposals' share of the steps, at first ...
SHARE_TRUSTED = 0.9  # ... and once this many of them ...
TRUSTED_ABOVE = 0.5  # ... are accepted


class LaplaceIndependenceMove(emcee.moves.MHMove):
    """Metropolis–Hastings independence proposals from the Laplace approximation.

    Every walker proposes a fresh point from a multivariate Student-t (ν = 8) centred
    on the MAP with the Laplace covariance (inflated by ``scale``), and accepts it with
    the Hastings ratio ``p(x')·q(x) / (p(x)·q(x'))``.  When the posterior is close to
    the Laplace Gaussian the acceptance is high and successive draws are nearly
    independent; the heavier-than-Gaussian tails keep the ratio bounded where it is not.
    :meth:`refit` recentres and reshapes the proposal on draws of the chain (the
    sampler does so during burn-in only, while the chain is wider than the proposal in
    some direction or few proposals are accepted: :meth:`misfits`).
    """

    def __init__(self, mean, cov, *, nu: float = 8.0, scale: float = 1.2):
        self.nu, self.scale = float(nu), float(scale)
        self._set(mean, cov)
        super().__init__(self._propose)

    def propose(self, model, state):
        state, accepted = super().propose(model, state)
        self._tried += accepted.size
        self._taken += int(np.count_nonzero(accepted))
        return state, accepted

    @property
    def acceptance(self) -> float | None:
        """The share of this move's proposals accepted since it was last (re)fitted;
        None before it has proposed."""
        return self._taken / self._tried if self._tried else None

    def _set(self, mean, cov) -> None:
        cov = np.asarray(cov, dtype=float)
        vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
        vals = np.clip(vals, 1e-300, None)
        self._inv_cov_root = vecs / np.sqrt(vals)  # whitens the covariance itself
        vals = vals * self.scale**2 * (self.nu - 2.0) / self.nu
        self.mean = np.asarray(mean, dtype=float)
        self._tried, self._taken = 0, 0
        self._root = vecs * np.sqrt(vals)
        self._inv_root = vecs / np.sqrt(vals)

    def misfits(self, samples, *, below: float, wider: float) -> bool:
        """Whether the proposal no longer describes the chain's ``samples`` ``(n, P)``:
        its ``acceptance`` since the last fit is below ``below``, or the samples spread
        more than ``wider`` times its sd along some direction (the largest generalised
        eigenvalue of their covariance against the proposal's)."""
        if self.acceptance is not None and self.acceptance < below:
            return True
        samples = np.asarray(samples, dtype=float)
        if samples.ndim != 2 or samples.shape[0] <= 2 * samples.shape[1]:
            return False
        z = (samples - samples.mean(axis=0)) @ self._inv_cov_root
        return bool(np.sqrt(np.linalg.eigvalsh(np.cov(z, rowvar=False)).max()) > wider)

    def adapt(self, samples, *, below: float, wider: float, refit: bool = True) -> bool:
        """:meth:`refit` on ``samples`` where the proposal :meth:`misfits` them (and
        ``refit``); whether it changed."""
        return refit and self.misfits(samples, below=below, wider=wider) \
            and self.refit(samples)

    def refit(self, samples) -> bool:
        """Centre the proposal on the mean of ``samples`` ``(n, P)`` with their
        covariance; kept as it was (False) when they cannot define one."""
        samples = np.asarray(samples, dtype=float)
        if samples.ndim != 2 or samples.shape[0] <= 2 * samples.shape[1]:
            return False
        cov = np.cov(samples, rowvar=False)
        if not np.all(np.isfinite(cov)) or np.linalg.eigvalsh(cov).min() <= 0.0:
            return False
        self._set(samples.mean(axis=0), cov)
        return True

    def _log_q(self, x):
        z = (x - self.mean) @ self._inv_root
        return -0.5 * (self.nu + self.mean.size) * np.log1p(np.sum(z * z, axis=1) / self.nu)

    def _propose(self, x0, random):
        n, d = x0.shape
        z = random.standard_normal((n, d))
        g = random.chisquare(self.nu, size=n) / self.nu
        x1 = self.mean + (z @ self._root.T) / np.sqrt(g)[:, None]
        return x1, self._log_q(x0) - self._log_q(x1)


class LaplaceMixture(emcee.moves.Move):
    """Each step of the ensemble either Laplace independence proposals (with probability
    ``share``) or differential evolution, the choice drawn from the sampler's own
    generator.

    :meth:`adapt` (called by the sampler during burn-in only, the chain before a
    change being discarded) refits the independence proposals where they misfit the
    chain, which sets ``share`` back to :data:`SHARE`; where they fit and more than
    :data:`TRUSTED_ABOVE` of them are accepted, it raises ``share`` to
    :data:`SHARE_TRUSTED`.  An accepted independence proposal is a nearly independent
    draw, so on a near-Gaussian posterior the larger share cuts τ (on the benchmark
    session from about 3.5 steps to 1.7, and the steps to convergence from 400 to
    350, the 50-step pilot included); differential evolution keeps a tenth of the
    steps so that the chain still moves where the proposals reach poorly.
    """

    def __init__(self, independence: LaplaceIndependenceMove, other=None, *,
                 share: float = SHARE):
        self.independence = independence
        self.other = emcee.moves.DEMove() if other is None else other
        self.share = float(share)

    def propose(self, model, state):
        move = self.independence if model.random.uniform() < self.share else self.other
        return move.propose(model, state)

    def adapt(self, samples, *, below: float, wider: float, refit: bool = True) -> bool:
        """Refit the independence proposals on ``samples`` where they misfit them
        (``share`` back to :data:`SHARE`), or raise ``share`` where they are trusted;
        whether the move changed (with ``refit`` False, only the share may)."""
        if self.independence.adapt(samples, below=below, wider=wider, refit=refit):
            self.share = SHARE
            return True
        rate = self.independence.acceptance
        if self.share < SHARE_TRUSTED and rate is not None and rate > TRUSTED_ABOVE \
                and not self.independence.misfits(samples, below=below, wider=wider):
            self.share = SHARE_TRUSTED
            return True
        return False


def default_moves(fit=None):
    """A :class:`LaplaceMixture` (fresh instances): half Laplace-independence
    proposals, half differential evolution, until the chain shows the proposals fit.

    Differential evolution alone gave τ ≈ 18–20 steps on the demo session (stretch:
    ≈ 60); mixing in independence proposals from the Laplace approximation brings τ
    to a few steps when the posterior is near-Gaussian, while DE keeps the chain
    moving where it is not.  Without ``fit``, DE only.
    """
    if fit is None:
        return [(emcee.moves.DEMove(), 1.0)]
    return [(LaplaceMixture(LaplaceIndependenceMove(fit.theta, fit.cov_log)), 1.0)]
