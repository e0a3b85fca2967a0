"""Simulations of the traces under each parameter set, and the posterior predictive.

For every trace: the closed-form model (viscous, as the paper's method assumes), the
MAP, and the posterior predictive, i.e. the model simulated at posterior draws plus
Gaussian measurement noise at each channel's fitted level.  The 94 % band of the
predictive is reported together with the narrower band of the parameter uncertainty
alone (draws without noise).
"""

from __future__ import annotations

import numpy as np

from ..inference.model.objective import noise_scale
from ..io.channel import ChannelId
from ._view import BAND, METHODS, TracePrediction, _measured, trace_channels

__all__ = ["TracePrediction", "predict_traces", "trace_channels", "BAND", "METHODS"]

def _theta(model, values: dict):
    return model.theta(values)


def _finite(x) -> np.ndarray:
    x = np.asarray(x)
    return x[np.isfinite(x)]


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def predict_traces(model, values: dict, draws, noise_sd: dict, *, seed: int = 0,
                   held_out: bool = False) -> list[TracePrediction]:
    """Predictions of every trace of ``model``'s session.

    Parameters
    ----------
    model : a :class:`pmdc_bayes.inference.model.objective.SessionModel`.
    values : ``{"closed_form": {...}, "map": {...}}`` SI parameter values by name.
    draws : ``(N, P)`` SI posterior draws in ``model.names`` order, or None.
    noise_sd : fitted noise sd per channel, by its text (``"<trace>: speed"``); a trace
        without one (held out of the fit) gets the model-free estimate from its data.
    seed : seeds the simulated measurement noise of the predictive.
    """
    if model.exp is None:
        return []
    def run(theta):
        pairs = model.predict(theta)
        return [(ia, w, a) for (ia, w), a in zip(pairs, model.predict_angles(theta),
                                                  strict=True)]

    runs = {"closed_form": run(_theta(model, values["closed_form"])),
            "map": run(_theta(model, values["map"]))}
    per_draw = None
    if draws is not None:
        thetas = np.stack([np.asarray(model.theta(dict(zip(model.names, d, strict=True))))
                           for d in draws])
        per_draw = model.predict_draws(thetas)
    rng = np.random.default_rng(seed)
    out = []
    for k, tr in enumerate(model.session.traces):
        channels = trace_channels(tr)
        noise = {c: float(noise_sd.get(str(ChannelId(tr.name, c)))
                          or noise_scale(_finite(_measured(tr, c))))
                 for c in channels}
        sims = {m: {"current": r[k][0], "speed": r[k][1], "position": r[k][2]}
                for m, r in runs.items()}
        band = param_band = coverage = None
        if per_draw is not None:
            draws_c = dict(zip(("current", "speed", "position"), per_draw[k], strict=True))
            band, param_band, coverage = {}, {}, {}
            sims["mean"] = {}
            for c in channels:
                x = draws_c[c]
                sims["mean"][c] = x.mean(axis=0)
                param_band[c] = tuple(np.quantile(x, BAND, axis=0))
                noisy = x + rng.normal(0.0, noise[c], size=x.shape)
                band[c] = tuple(np.quantile(noisy, BAND, axis=0))
                y = _measured(tr, c)
                ok = np.isfinite(y)
                coverage[c] = float(np.mean((y[ok] >= band[c][0][ok])
                                            & (y[ok] <= band[c][1][ok])))
        rms = {m: {c: _rms(_finite(_measured(tr, c) - s[c])) for c in channels}
               for m, s in sims.items()}
        out.append(TracePrediction(tr, held_out, sims, band, param_band, noise, rms, coverage))
    return out
