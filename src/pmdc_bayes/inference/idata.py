"""The ArviZ record of a posterior sample, with the pointwise log-likelihood for LOO."""

from __future__ import annotations

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from .diagnostics import az
from .objective import NU0

__all__ = ["to_inference_data", "LL_DRAWS"]

LL_DRAWS = 400  # at most this many draws carry a pointwise log-likelihood (for LOO)
_LL_BATCH = 50


def _pointwise_fn(model):
    """Compiled (once per session structure) Gaussian log-density of every padded
    sample, at the noise level σ_c² = (ν0·s0_c² + SS_c)/(n_c + ν0) of its channel."""

    def one(theta, data):
        ss = model.sums_of_squares(theta, data=data)
        var = (NU0 * data["s0"] ** 2 + ss) / (data["n_obs"] + NU0)

        def dens(r, v):
            return -0.5 * (jnp.log(2 * jnp.pi * v) + r * r / v)

        out = []
        if model.exp is not None:
            rw, ri = model.trace_residuals(theta, data=data)
            out += [dens(rw, var[data["speed_ch"]][:, None]),
                    dens(ri, var[data["current_ch"]][:, None])]
        n_ch = len(model.channels)
        for k, (r, _) in enumerate(model._steady_and_tau_residuals(model.params(theta),
                                                                   data=data)):
            # lax.map cannot batch an empty output: an empty channel gets a dummy entry
            # that its (empty) selection never reads.
            out.append(dens(r if r.shape[0] else jnp.zeros(1), var[n_ch - 3 + k]))
        return out

    fn = model.compiled("pointwise", lambda: jax.jit(
        lambda thetas, data: jax.lax.map(lambda t: one(t, data), thetas, batch_size=4)))
    return lambda thetas: fn(thetas, model.data)


def _selection(model):
    """Per channel, (which output of :func:`_pointwise_fn`, flat indices of its
    observations), in channel order."""
    n_ch = len(model.channels)
    sel = []
    if model.exp is not None:
        mask = np.asarray(model.exp.mask)
        for c in range(n_ch - 3):
            m_w = (mask & (model._speed_ch == c)[:, None]).reshape(-1)
            m_i = (model._current_mask & (model._current_ch == c)[:, None]).reshape(-1)
            sel.append((0, np.nonzero(m_w)[0]) if m_w.any() else (1, np.nonzero(m_i)[0]))
    base = 2 if model.exp is not None else 0
    st = model._steady
    sel.append((base, np.nonzero(st["w_mask"])[0]))
    sel.append((base + 1, np.nonzero(st["i_mask"])[0]))
    sel.append((base + 2, np.arange(len(model.session.step_readings))))
    return sel


def _padded_pointwise(model, theta):
    """Per channel the log-density of every (padded) sample and the masks (independent
    of θ) that select the observations (kept for the tests, which check it against
    :meth:`SessionModel.pointwise_log_likelihood`)."""
    ss = model.sums_of_squares(theta)
    var = (NU0 * jnp.asarray(model.s0) ** 2 + ss) / (jnp.asarray(model.n_obs) + NU0)
    dens, masks = [], []
    for c, (r, m) in enumerate(model.channel_residuals(theta)):
        r = jnp.asarray(r).reshape(-1)
        dens.append(-0.5 * (jnp.log(2 * jnp.pi * var[c]) + r * r / var[c]))
        masks.append(jnp.asarray(m, dtype=bool).reshape(-1))
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


def _observed(model) -> list[np.ndarray]:
    """Observed values per channel, in the model's channel order (the order the
    objective builds them in: traces, steady speeds, steady currents, τ readings)."""
    s = model.session
    out = []
    for tr in s.traces:
        out.append(np.asarray(tr.speed, dtype=float))
        if tr.current is not None:
            out.append(np.asarray(tr.current, dtype=float))
    w, i = [], []
    for op in s.operating_points:
        w.append(op.speed)
        if op.current is not None:
            i.append(op.current)
    for tab in s.steady_tables:
        w.extend(np.asarray(tab.speed, dtype=float))
        if tab.current is not None:
            i.extend(np.asarray(tab.current, dtype=float))
    w.extend(r.final_speed for r in s.step_readings)
    out += [np.asarray(w, dtype=float), np.asarray(i, dtype=float),
            np.asarray([r.tau for r in s.step_readings], dtype=float)]
    sizes = [c.n for c in model.channels]
    if [o.size for o in out] != sizes:
        raise ValueError(f"observed values per channel have sizes {[o.size for o in out]}, "
                         f"but the model's channels have {sizes}: the channel order of "
                         "SessionModel changed; update sampling._observed")
    return out


def _pointwise(model, chain_log: np.ndarray, thin: int) -> np.ndarray:
    """Pointwise log-likelihood ``(chains, kept, n_obs)`` at every ``thin``-th draw."""
    fn = _pointwise_fn(model)
    sel = _selection(model)
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
    observed = {nm: o for nm, o in zip(obs_names, _observed(model)) if o.size}
    values = np.exp(chain_log)
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
