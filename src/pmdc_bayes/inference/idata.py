"""The ArviZ record of a posterior sample, with the pointwise log-likelihood for LOO."""

from __future__ import annotations

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from .diagnostics import az

__all__ = ["to_inference_data", "LL_DRAWS"]

LL_DRAWS = 400  # at most this many draws carry a pointwise log-likelihood (for LOO)
_LL_BATCH = 50


def _pointwise_fn(model):
    """:meth:`SessionModel.padded_log_density` over a batch of θ, compiled once per
    session structure."""
    fn = model.compiled("pointwise", lambda: jax.jit(
        lambda thetas, data: jax.lax.map(lambda t: model.padded_log_density(t, data=data),
                                         thetas, batch_size=4)))
    return lambda thetas: fn(thetas, model.data)


def _padded_pointwise(model, theta):
    """Per channel the log-density of every padded sample of its output, and the mask
    that selects the channel's observations (checked in the tests against
    :meth:`SessionModel.pointwise_log_likelihood`)."""
    outs = model.padded_log_density(theta)
    dens, masks = [], []
    for k, idx in model.observation_selection():
        flat = jnp.asarray(outs[k]).reshape(-1)
        mask = np.zeros(flat.shape[0], dtype=bool)
        mask[idx] = True
        dens.append(flat)
        masks.append(mask)
    return dens, masks


def _identifier(name: str, taken: set) -> str:
    ident = re.sub(r"\W+", "_", name).strip("_") or "channel"
    if ident[0].isdigit():
        ident = "c_" + ident
    base, k = ident, 2
    while ident in taken:
        ident, k = f"{base}_{k}", k + 1
    taken.add(ident)
    return ident


def _pointwise(model, chain_log: np.ndarray, thin: int) -> np.ndarray:
    """Pointwise log-likelihood ``(chains, kept, n_obs)`` at every ``thin``-th draw."""
    fn = _pointwise_fn(model)
    sel = model.observation_selection()
    sub = chain_log[:, ::thin]
    flat = sub.reshape(-1, sub.shape[-1])
    m = math.ceil(flat.shape[0] / _LL_BATCH) * _LL_BATCH
    padded = np.concatenate([flat, np.repeat(flat[:1], m - flat.shape[0], axis=0)])
    parts = []
    for a in range(0, m, _LL_BATCH):
        outs = [np.asarray(o) for o in fn(jnp.asarray(padded[a:a + _LL_BATCH]))]
        outs = [o.reshape(_LL_BATCH, int(np.prod(o.shape[1:]))) for o in outs]
        parts.append(np.concatenate([outs[k][:, idx] for k, idx in sel], axis=1))
    ll = np.concatenate(parts)[:flat.shape[0]]
    return ll.reshape(*sub.shape[:2], -1)


def to_inference_data(model, chain_log: np.ndarray, log_prob: np.ndarray,
                      acceptance: np.ndarray, *, ll_draws: int = LL_DRAWS) -> az.InferenceData:
    """ArviZ record of a sample: ``posterior`` (SI value per parameter, walkers as
    chains), ``sample_stats`` (``lp``; per-chain ``acceptance``), ``observed_data`` (one
    variable per channel, names made identifiers) and ``log_likelihood``.

    ``log_likelihood`` holds one variable ``y`` over all observations (dimension
    ``observation``, with a ``channel`` coordinate naming each one's channel), so
    ``az.loo(idata)`` works directly.  It is evaluated at every ``thin``-th draw
    (``attrs["thin"]``) so that at most ``ll_draws`` draws carry it; its ``draw``
    coordinate gives the draws used.
    """
    chains, draws, _ = chain_log.shape
    taken: set = set()
    obs_names = [_identifier(c.name, taken) for c in model.channels]
    observed = {nm: o for nm, o in zip(obs_names, model.observed_values()) if o.size}
    values = model.registry.to_values(chain_log)
    idata = az.from_dict(
        posterior={n: values[..., k] for k, n in enumerate(model.names)},
        sample_stats={"lp": log_prob},
        observed_data=observed,
        dims={nm: [f"{nm}_dim"] for nm in observed},
        attrs={"inference_library": "emcee"},
    )
    idata.sample_stats["acceptance"] = xr.DataArray(np.asarray(acceptance), dims=["chain"],
                                                    coords={"chain": np.arange(chains)})
    thin = max(1, math.ceil(chains * draws / max(ll_draws, chains)))
    ll = _pointwise(model, chain_log, thin)
    labels = np.asarray([nm for nm, c in zip(obs_names, model.channels) for _ in range(c.n)])
    ds = xr.Dataset(
        # float32: LOO needs ~3 significant digits of each term, and the group is by far
        # the largest in posterior.nc.
        {"y": (("chain", "draw", "observation"), ll.astype(np.float32))},
        coords={"chain": np.arange(chains), "draw": np.arange(0, draws, thin),
                "observation": np.arange(ll.shape[-1]), "channel": ("observation", labels)},
        attrs={"thin": thin},
    )
    idata.add_groups(log_likelihood=ds)
    return idata
