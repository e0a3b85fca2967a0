"""Coloured noise: a channel's errors as a first-order autoregression, AR(1).

A sensor that filters, differences or averages its readings leaves errors that are
correlated from one sample to the next.  With ``coloured_noise`` under ``[model]``
every analogue channel of the driven traces and coast-downs (a logged speed or
current that is not quantised: a quantised reading's errors are handled by its
quantisation, :func:`.noise.effective_fraction`) has its own lag-1 correlation ρ,
fitted as ``noise_ar_<channel>`` = atanh ρ (prior normal, centre 0, sd
:data:`PHI_PRIOR_SD`: ρ = 0 is white noise, the neutral value).

The likelihood is exact for each run of consecutive readings (a missed reading starts
a new run: the error before the gap is not carried across it).  A channel's residuals
``e_k`` are *whitened* into innovations ``u_k = e_k − ρ·e_{k−1}``, and a run's first
reading into ``√(1−ρ²)·e_k``; the innovations are white with one unknown level,
so the channel's sum of squares, its integrated noise level and every residual check
read them as they read a white channel's residuals.  The Jacobian of the whitening
adds ``½·m·log(1−ρ²)`` for the channel's ``m`` starts: the model carries it as one
more standardised residual ``ρ·√(m·g(ρ))``, ``g(ρ) = −log(1−ρ²)/ρ²``, whose half
square is that term's negative (smooth at ρ = 0, where ``g`` = 1).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..._x64 import to_device
from ...io.channel import ChannelId
from ...io.lattice import analogue_channels

__all__ = ["COLOURED", "PHI_PRIOR_SD", "ar_name", "ar_specs", "coloured_channels", "breaks",
           "previous_index", "whiten", "channel_rho", "mean_se_factor", "noise_rho",
           "start_residuals", "innovation_scale", "coloured_data"]

COLOURED = "coloured_noise"
PHI_PRIOR_SD = 1.5  # sd of atanh ρ: ρ = 0.9 at 1 sd, 0.99 at 1.8 sd
PREFIX = "noise_ar_"


def ar_name(channel: ChannelId) -> str:
    """The parameter of a channel's lag-1 correlation, named after the channel."""
    return PREFIX + "".join(c if c.isalnum() else "_" for c in str(channel)).replace("__", "_")


def coloured_channels(session) -> list[ChannelId]:
    """The channels whose noise the session fits as coloured: the analogue ones of the
    traces ``coloured_noise`` names (``Session.coloured_noise_traces``)."""
    traces = set(session.coloured_noise_traces())
    return [c for c, tr in analogue_channels(session).items() if tr in traces]


def ar_specs(session) -> list:
    """The registry entries of ``coloured_noise`` (none without it)."""
    from .params import ParamSpec, Prior

    return [ParamSpec(ar_name(c), "1", "sensor", Prior("normal", 0.0, PHI_PRIOR_SD, "nuisance"),
                      0.0, transform="identity",
                      description=f"atanh of the lag-1 correlation of the noise of {c}")
            for c in coloured_channels(session)]


def breaks(t) -> np.ndarray:
    """Where a record's chain of readings starts again: its first sample, and each
    reading after a gap longer than 1.5 sample intervals (a missed reading the loader
    left out: the reading before it is not the previous one)."""
    t = np.asarray(t, float)
    out = np.zeros(t.size, bool)
    if t.size:
        out[0] = True
    if t.size > 2:
        dt = np.diff(t)
        out[1:] = dt > 1.5 * np.median(dt)
    return out


def previous_index(observed: np.ndarray, first: np.ndarray, flat_pos: np.ndarray,
                   shape) -> np.ndarray:
    """The flat index, in a padded layout of ``shape``, of each entry's previous
    reading of the same channel (−1 where there is none: a record's first sample, the
    first after a missed reading, padding).  ``observed`` and ``first`` are per sample
    (records concatenated), ``flat_pos`` each sample's flat position in the layout."""
    observed, first = np.asarray(observed, bool), np.asarray(first, bool)
    prev = np.full(int(np.prod(shape)), -1, np.int64)
    chained = observed & ~first
    chained[1:] &= observed[:-1]
    chained[0] = False
    k = np.flatnonzero(chained)
    prev[np.asarray(flat_pos)[k]] = np.asarray(flat_pos)[k - 1]
    return prev.reshape(shape)


def whiten(r, prev, rho):
    """The innovations of residuals ``r`` (any layout) given each entry's previous
    reading's flat index ``prev`` and its channel's ``rho`` (broadcastable to ``r``)."""
    before = r.reshape(-1)[jnp.maximum(prev, 0).reshape(-1)].reshape(r.shape)
    return jnp.where(prev >= 0, r - rho * before, jnp.sqrt(1.0 - rho * rho) * r)


def channel_rho(model, theta) -> dict:
    """Per channel (:class:`~pmdc_bayes.io.channel.ChannelId`) its noise's lag-1
    correlation at ``theta`` (0: white)."""
    rho = np.asarray(model.noise_rho(model.switched(to_device(theta), model.data)))
    return {c.id: float(r) for c, r in zip(model.channels, rho, strict=True)}


def mean_se_factor(rho: float, n: int | None = None) -> float:
    """The standard error of a mean of ``n`` AR(1) readings, over that of as many white
    readings at the innovations' level: with the marginal variance σ²/(1−ρ²), the
    square root of ((1+ρ)/(1−ρ) − 2ρ(1−ρⁿ)/(n(1−ρ)²))/(1−ρ²); for many readings
    (``n`` None), 1/(1−ρ)."""
    if n is None:
        return 1.0 / (1.0 - rho)
    factor = (1 + rho) / (1 - rho) - 2 * rho * (1 - rho**n) / (n * (1 - rho) ** 2)
    return float(np.sqrt(factor / (1.0 - rho * rho)))


def noise_rho(theta, ar):
    """Per channel ρ = tanh of its parameter (0 for a white channel), from the data
    pytree's ``noise_ar`` (:func:`coloured_data`)."""
    idx = ar["param"]
    return jnp.where(idx >= 0, jnp.tanh(jnp.asarray(theta)[jnp.maximum(idx, 0)]), 0.0)


def start_residuals(rho, starts):
    """Per channel the standardised residual whose half square is −½·m·log(1−ρ²)."""
    rr = rho * rho
    safe = jnp.where(rr > 1e-8, rr, 1.0)
    g = jnp.where(rr > 1e-8, -jnp.log1p(-safe) / safe, 1.0 + 0.5 * rr)
    return jnp.sqrt(starts) * rho * jnp.sqrt(g)  # g ≥ 1: a root with a gradient


def innovation_scale(rho) -> float:
    """An innovation's sd over the model-free noise level of AR(1) readings (the second
    differences' sd over √6): √(3(1+ρ)/(3−ρ))."""
    return float(np.sqrt(3.0 * (1.0 + rho) / (3.0 - rho)))


def coloured_data(model) -> dict:
    """The data pytree's ``noise_ar``: per channel the index of its correlation's
    parameter in θ (−1: white) and its number of starts (readings without a previous
    one), which the whitening's Jacobian counts."""
    names = list(model.registry.names)
    param = np.array([names.index(ar_name(c.id)) if ar_name(c.id) in names else -1
                      for c in model.channels], dtype=np.int64)
    starts = np.zeros(len(model.channels))
    for b in model.blocks:
        bd = b.data()
        for (mask, ch), prev in zip(b.layout(bd), b.previous(bd), strict=True):
            if prev is None:
                continue
            mask, ch = np.asarray(mask, bool), np.asarray(ch)
            rows = np.broadcast_to(ch.reshape(ch.shape + (1,) * (mask.ndim - ch.ndim)),
                                   mask.shape)
            first = mask & (np.asarray(prev) < 0)
            np.add.at(starts, rows[first], 1.0)
    return {"param": param, "starts": np.where(param >= 0, starts, 0.0)}
