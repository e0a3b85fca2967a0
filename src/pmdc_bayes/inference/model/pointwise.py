"""Each observation's own log-density under the fitted noise levels: what LOO and the
ArviZ record's pointwise log-likelihood read (a mixin of
:class:`~.objective.SessionModel`)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .channels import entry_weights
from .noise import NU0

__all__ = ["Pointwise"]


class Pointwise:
    """The observations one by one: their log-densities, residuals and where each
    channel's lie in the blocks' layouts."""

    def padded_log_density(self, theta, *, data=None) -> list:
        """Gaussian log-density of every observation, in each block's layout, at its
        channel's noise level ``σ_c² = (ν0·s0_c² + SS_c)/(n_c + ν0)`` (for LOO);
        :meth:`observation_selection` picks each channel's observations out of it."""
        return [-0.5 * (jnp.log(2 * jnp.pi * v) + r * r / v)
                for r, v in self.padded_residuals(theta, data=data)]

    def padded_residuals(self, theta, *, data=None, whitened: bool = True) -> list:
        """Per output of :meth:`padded_log_density`, ``(residual, σ_c²)``, the second
        broadcastable to the first: the model's prediction is the observation minus the
        residual.  A channel whose noise is coloured gives its innovations and their
        level: the observation minus the innovation is then the prediction of the
        reading given the one before it (:mod:`.coloured`), and a run's first reading
        its own residual at the stationary level ``σ_c²/(1−ρ²)``, so that the densities
        add up to the likelihood the fit uses; not ``whitened``, its residuals
        themselves."""
        d = self._d(data)
        parts = self._parts(theta, d)
        var = (NU0 * d["s0"] ** 2 + self._sums(parts)) / (d["n_obs"] + NU0)
        starts = [None] * len(parts)
        if self.coloured and whitened:
            rho = self.noise_rho(self.switched(theta, d), d)
            starts = [p for b in self.blocks for p in b.previous(d[b.key])]
        elif self.coloured:
            parts = self._parts(theta, d, whitened=False)
        out = []
        for (r, _, ch), prev in zip(parts, starts, strict=True):
            if r.shape[0] == 0:
                # lax.map cannot batch an empty output: an empty array gets a dummy
                # entry that its (empty) selection never reads.
                r = jnp.zeros((1,) + r.shape[1:])
                out.append((r, jnp.ones_like(r)))
                continue
            v = entry_weights(var, ch, r)
            if prev is not None:  # a run's first reading: its residual, stationary level
                share = jnp.where(prev < 0, 1.0 - entry_weights(rho, ch, r) ** 2, 1.0)
                r, v = r / jnp.sqrt(share), v / share
            out.append((r, v))
        return out

    def _numpy_data(self, block):
        return jax.tree_util.tree_map(np.asarray, self.data[block.key])

    def observed_values(self) -> list[np.ndarray]:
        """Per channel, in channel order, its observations in the order of
        :meth:`observation_selection` (and of the pointwise log-likelihood)."""
        arrays = [np.asarray(o) for b in self.blocks for o in b.observed(self._numpy_data(b))]
        return [arrays[k].reshape(-1)[idx] for k, idx in self.observation_selection()]

    def observation_selection(self) -> list:
        """Per channel, in channel order: (which output of :meth:`padded_log_density`,
        flat indices of its observations)."""
        layout = [(np.asarray(m), np.asarray(ch)) for b in self.blocks
                  for m, ch in b.layout(self._numpy_data(b))]
        sel = []
        for c in range(len(self.channels)):
            for k, (m, ch) in enumerate(layout):
                own = (ch == c).reshape(ch.shape + (1,) * (m.ndim - ch.ndim))
                idx = np.nonzero((m & own).reshape(-1))[0]
                if idx.size:
                    sel.append((k, idx))
                    break
            else:
                sel.append((0, np.zeros(0, int)))
        return sel

    def pointwise_log_likelihood(self, theta, *, data=None) -> list:
        """Per channel, the log-density of each of its observations (see
        :meth:`padded_log_density`)."""
        outs = self.padded_log_density(theta, data=data)
        return [jnp.asarray(outs[k]).reshape(-1)[idx] for k, idx in self.observation_selection()]
