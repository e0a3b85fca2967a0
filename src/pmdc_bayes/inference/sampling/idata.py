"""The ArviZ record of a posterior sample, with the pointwise log-likelihood for LOO."""

from __future__ import annotations

import math
import re

import jax.numpy as jnp
import numpy as np
import xarray as xr

from ..._x64 import to_device
from ..model.predictions import RESIDUAL_BATCH
from .arviz_import import az

__all__ = ["to_inference_data", "lumped", "LL_DRAWS"]

LL_DRAWS = 400  # at most this many draws carry a pointwise log-likelihood (for LOO)
_LL_BATCH = RESIDUAL_BATCH


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


def _pointwise(model, chain_log: np.ndarray, thin: int, rng) -> tuple:
    """At every ``thin``-th draw, per observation (in channel order): the log-likelihood
    (float64: on a precise posterior an observation's log-density differs between
    draws by less than float32 resolves, and those differences are what PSIS-LOO
    reads) and a replicate of the observation (the model's prediction plus Gaussian
    noise at its channel's level, float32; where the noise is coloured, the density and
    the replicate of each reading given the one before it, :mod:`.coloured`), each
    ``(chains, kept, n_obs)``, filled batch by batch (the next batch computed while this
    one is unpacked)."""
    fn = model.residuals_of_batch
    observed = np.concatenate(model.observed_values()).astype(np.float32)
    selection = model.observation_selection()
    ends = np.cumsum([idx.size for _, idx in selection])
    sub = chain_log[:, ::thin]
    flat = sub.reshape(-1, sub.shape[-1])
    n = flat.shape[0]
    m = math.ceil(n / _LL_BATCH) * _LL_BATCH
    padded = np.concatenate([flat, np.repeat(flat[:1], m - n, axis=0)])
    ll = np.empty((n, observed.size))
    replicate = np.empty((n, observed.size), np.float32)
    ahead = fn(to_device(padded[:_LL_BATCH]))
    for a in range(0, m, _LL_BATCH):
        outs = ahead
        if a + _LL_BATCH < m:  # dispatched now, computed while this batch is unpacked
            ahead = fn(to_device(padded[a + _LL_BATCH:a + 2 * _LL_BATCH]))
        keep = min(_LL_BATCH, n - a)
        for (k, idx), end in zip(selection, ends, strict=True):
            # the channel's residuals, and σ² (one value per row of the output, so its
            # logarithm and root are taken there), picked per observation
            r = np.asarray(outs[k][0]).reshape(_LL_BATCH, -1)[:keep]
            var = np.asarray(outs[k][1]).reshape(_LL_BATCH, -1)[:keep]
            rows = idx // (r.shape[1] // var.shape[1])
            r = np.take(r, idx, axis=1)
            out = ll[a:a + keep, end - idx.size:end]  # in place: these arrays are large
            np.multiply(r, r, out=out)
            out *= np.take(0.5 / var, rows, axis=1)
            np.subtract(np.take(-0.5 * np.log(2 * np.pi * var), rows, axis=1), out, out=out)
            out = replicate[a:a + keep, end - idx.size:end]
            out[...] = rng.standard_normal(out.shape, dtype=np.float32)
            out *= np.take(np.sqrt(var).astype(np.float32), rows, axis=1)
            out += observed[end - idx.size:end]
            out -= r
    return ll.reshape(*sub.shape[:2], -1), replicate.reshape(*sub.shape[:2], -1)


def _coords(model, names) -> dict:
    """Per channel variable, the coordinate of its observations: the sample time (s)
    for a trace's channel, the observation's index otherwise."""
    t = None
    if model.exp is not None:
        d = model.data["traces"]
        t = np.asarray(model.exp.pad(np.asarray(d["t"]))).reshape(-1)
    coords, dims = {}, {}
    traces = {tr.name for tr in model.session.traces}
    for nm, ch, (k, idx) in zip(names, model.channels, model.observation_selection(),
                                strict=True):
        dim = f"{nm}_time" if t is not None and k < 3 and ch.id.trace in traces \
            and ch.id.signal in ("speed", "current", "position") else f"{nm}_dim"
        dims[nm] = [dim]
        coords[dim] = t[idx] if dim.endswith("_time") else np.arange(idx.size)
    return coords, dims


def to_inference_data(model, chain_log: np.ndarray, log_prob: np.ndarray,
                      acceptance: np.ndarray, *, ll_draws: int = LL_DRAWS,
                      seed: int = 0) -> az.InferenceData:
    """ArviZ record of a sample, one variable per channel (names made identifiers:
    ``step_speed``, ``steady_current``...), with its unit in ``attrs["units"]``:

    * ``posterior``: the SI value of each parameter, walkers as chains;
    * ``sample_stats``: ``lp``, and per chain ``acceptance``;
    * ``observed_data``: each channel's observations, on the sample times (s) for a
      trace's channel (dimension ``<channel>_time``), by index otherwise;
    * ``log_likelihood``: each observation's log-density at its channel's noise level,
      so ``az.loo(idata, var_name="step_speed")`` scores a channel
      (:func:`lumped` joins them for the whole session's LOO);
    * ``posterior_predictive``: a replicate of each observation (the model plus noise at
      its channel's level), for ``az.plot_ppc`` and ``az.plot_loo_pit``.

    The last two are evaluated at every ``thin``-th draw (``attrs["thin"]``) so that at
    most ``ll_draws`` draws carry them; their ``draw`` coordinate gives the draws used.
    """
    chains, draws, _ = chain_log.shape
    taken: set = set()
    names = [_identifier(c.name, taken) for c in model.channels]
    units = {nm: c.unit for nm, c in zip(names, model.channels, strict=True)}
    coords, dims = _coords(model, names)
    observed = {nm: o for nm, o in zip(names, model.observed_values(), strict=True) if o.size}
    values = model.registry.to_values(chain_log)
    thin = max(1, math.ceil(chains * draws / max(ll_draws, chains)))
    # the replicates' noise: a stream of its own, apart from the sampler's
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
    ll, replicate = _pointwise(model, chain_log, thin, rng)
    split = np.cumsum([idx.size for _, idx in model.observation_selection()])[:-1]
    kept = {"chain": np.arange(chains), "draw": np.arange(0, draws, thin)}

    def per_channel(x):
        return {nm: xr.DataArray(part, dims=["chain", "draw", *dims[nm]],
                                 coords={**kept, dims[nm][0]: coords[dims[nm][0]]},
                                 attrs={"units": units[nm]})
                for nm, part in zip(names, np.split(x, split, axis=-1), strict=True)
                if nm in observed}

    idata = az.from_dict(
        posterior={n: values[..., k] for k, n in enumerate(model.names)},
        sample_stats={"lp": log_prob},
        observed_data=observed,
        coords={dims[nm][0]: coords[dims[nm][0]] for nm in observed},
        dims={nm: dims[nm] for nm in observed},
        attrs={"inference_library": "emcee"},
    )
    for n in model.names:
        idata.posterior[n].attrs["units"] = model.registry[n].unit
    for nm in observed:
        idata.observed_data[nm].attrs["units"] = units[nm]
    idata.sample_stats["acceptance"] = xr.DataArray(np.asarray(acceptance), dims=["chain"],
                                                    coords={"chain": np.arange(chains)})
    idata.add_groups(log_likelihood=xr.Dataset(per_channel(ll), attrs={"thin": thin}),
                     posterior_predictive=xr.Dataset(per_channel(replicate),
                                                     attrs={"thin": thin}))
    return idata


def lumped(idata) -> az.InferenceData:
    """The posterior and one log-likelihood variable ``y`` over every observation of
    every channel, for the whole session's ``az.loo``."""
    ll = idata.log_likelihood
    parts = [ll[v].values.reshape(ll.sizes["chain"], ll.sizes["draw"], -1)
             for v in ll.data_vars]
    y = xr.DataArray(np.concatenate(parts, axis=-1), dims=["chain", "draw", "observation"],
                     coords={"chain": ll.chain, "draw": ll.draw})
    return az.InferenceData(posterior=idata.posterior,
                            log_likelihood=xr.Dataset({"y": y}, attrs=dict(ll.attrs)))
