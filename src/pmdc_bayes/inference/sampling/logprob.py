"""The sampler's log-density: the model's compiled batch log-posterior as emcee's
vectorised ``log_prob_fn`` (padded to a fixed batch, -inf for anything non-finite),
and the walkers' start from the Laplace approximation."""

from __future__ import annotations

import math

import jax
import numpy as np

from ..._x64 import to_device, x64

__all__ = ["batch_log_posterior", "LogProb", "initial_walkers"]


def batch_log_posterior(model):
    """The model's jit-compiled batch log-posterior, compiled once per model (and per
    batch shape)."""
    fn = model.compiled("log_posterior_batch", lambda: jax.jit(
        lambda thetas, data: model.log_posterior_batch(thetas, data=data)))
    return lambda thetas: fn(thetas, model.data)


class LogProb:
    """emcee's vectorised ``log_prob_fn``: NumPy ``(n, P)`` in, ``(n,)`` out, -inf for
    anything non-finite and for a logarithm |θ| ≥ 700 (a parameter beyond e^±700, where
    exp over- or underflows; ``is_log``, one flag per coordinate, marks those that hold
    one: a parameter sampled in value, an initial speed of 1,300 rad/s, may lie there).
    Evaluates in padded batches of a fixed size so the batch log-posterior
    compiles once, whatever size of batch a move proposes."""

    def __init__(self, fn, batch: int, is_log):
        self.fn, self.batch = fn, batch
        self.is_log = np.asarray(is_log, bool)

    @x64  # in every thread: JAX's 64-bit mode is a thread's own setting
    def __call__(self, thetas) -> np.ndarray:
        thetas = np.asarray(thetas, dtype=float)
        n = thetas.shape[0]
        far = (np.abs(thetas) >= 700.0) & self.is_log
        ok = np.all(np.isfinite(thetas), axis=1) & ~np.any(far, axis=1)
        out = np.full(n, -np.inf)
        good = thetas[ok]
        if good.shape[0] == 0:
            return out
        m = math.ceil(good.shape[0] / self.batch) * self.batch
        padded = np.concatenate([good, np.repeat(good[:1], m - good.shape[0], axis=0)])
        vals = np.empty(m)
        for a in range(0, m, self.batch):
            try:
                vals[a:a + self.batch] = np.asarray(self.fn(to_device(padded[a:a + self.batch])))
            except (ArithmeticError, ValueError, RuntimeError):  # a failed solve is -inf
                vals[a:a + self.batch] = -np.inf
        vals = vals[:good.shape[0]]
        out[ok] = np.where(np.isfinite(vals), vals, -np.inf)
        return out


def initial_walkers(fit, log_prob, n_walkers, rng, scale=1.0):
    """Walkers drawn from the Laplace approximation, redrawn where the density is -inf."""
    theta, cov = np.asarray(fit.theta, dtype=float), np.asarray(fit.cov_log) * scale**2
    p0 = rng.multivariate_normal(theta, cov, size=n_walkers, method="eigh")
    lp = log_prob(p0)
    for _ in range(20):
        bad = ~np.isfinite(lp)
        if not bad.any():
            return p0, lp
        p0[bad] = rng.multivariate_normal(theta, cov, size=int(bad.sum()), method="eigh")
        lp[bad] = log_prob(p0[bad])
    raise ValueError(f"{int(bad.sum())} of {n_walkers} initial walkers have a zero posterior "
                     "density around the MAP; check that fit_map converged (fit.message)")
