"""Simulations of the traces under each parameter set, and the posterior predictive.

For every trace: the closed-form model (viscous, as the paper's method assumes), the
MAP, and the posterior predictive, i.e. the model simulated at posterior draws plus
Gaussian measurement noise at each channel's fitted level.  The 94 % band of the
predictive is reported together with the narrower band of the parameter uncertainty
alone (draws without noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..inference.objective import noise_scale
from ..io.session import Trace

__all__ = ["TracePrediction", "predict_traces", "BAND", "METHODS"]

BAND = (0.03, 0.97)  # quantiles of the 94 % band
METHODS = {"closed_form": "closed form", "map": "MAP", "mean": "posterior predictive"}


@dataclass(frozen=True)
class TracePrediction:
    """One trace's measurements and predictions (SI: A, rad/s).

    ``sims[method][channel]`` with method in ``closed_form``, ``map`` and, with a
    posterior, ``mean`` (the posterior predictive mean); channel ``speed`` or
    ``current`` (the latter only when the trace logs it).  ``band`` and
    ``param_band`` map a channel to ``(lower, upper)`` 94 % limits of the posterior
    predictive and of the parameter uncertainty alone (None without a posterior).
    ``noise`` is the measurement noise sd per channel used for the predictive;
    ``rms`` the RMS error per method and channel; ``coverage`` the fraction of
    measured samples inside the predictive band.
    """

    trace: Trace
    held_out: bool
    sims: dict
    band: dict | None
    param_band: dict | None
    noise: dict
    rms: dict
    coverage: dict | None

    def measured(self, channel: str) -> np.ndarray:
        return self.trace.speed if channel == "speed" else self.trace.current

    @property
    def channels(self) -> tuple:
        return ("speed", "current") if self.trace.current is not None else ("speed",)


def _theta(model, values: dict):
    return model.theta(values)


def _rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def predict_traces(model, values: dict, draws, noise_sd: dict, *, seed: int = 0,
                   held_out: bool = False) -> list[TracePrediction]:
    """Predictions of every trace of ``model``'s session.

    Parameters
    ----------
    model : a :class:`pmdc_bayes.inference.objective.SessionModel`.
    values : ``{"closed_form": {...}, "map": {...}}`` SI parameter values by name.
    draws : ``(N, P)`` SI posterior draws in ``model.names`` order, or None.
    noise_sd : fitted noise sd per channel name (``"<trace>: speed"``); a trace
        without one (held out of the fit) gets the model-free estimate from its data.
    seed : seeds the simulated measurement noise of the predictive.
    """
    if model.exp is None:
        return []
    runs = {"closed_form": model.predict(_theta(model, values["closed_form"]), coulomb=False),
            "map": model.predict(_theta(model, values["map"]))}
    per_draw = None
    if draws is not None:
        sims = [model.predict(model.theta(dict(zip(model.names, d)))) for d in draws]
        per_draw = [(np.stack([s[k][0] for s in sims]), np.stack([s[k][1] for s in sims]))
                    for k in range(len(model.session.traces))]
    rng = np.random.default_rng(seed)
    out = []
    for k, tr in enumerate(model.session.traces):
        channels = ("speed", "current") if tr.current is not None else ("speed",)
        noise = {c: float(noise_sd.get(f"{tr.name}: {c}")
                          or noise_scale(tr.speed if c == "speed" else tr.current))
                 for c in channels}
        sims = {m: {"current": r[k][0], "speed": r[k][1]} for m, r in runs.items()}
        band = param_band = coverage = None
        if per_draw is not None:
            ia_d, w_d = per_draw[k]
            draws_c = {"current": ia_d, "speed": w_d}
            band, param_band, coverage = {}, {}, {}
            sims["mean"] = {}
            for c in channels:
                x = draws_c[c]
                sims["mean"][c] = x.mean(axis=0)
                param_band[c] = tuple(np.quantile(x, BAND, axis=0))
                noisy = x + rng.normal(0.0, noise[c], size=x.shape)
                band[c] = tuple(np.quantile(noisy, BAND, axis=0))
                y = tr.speed if c == "speed" else tr.current
                coverage[c] = float(np.mean((y >= band[c][0]) & (y <= band[c][1])))
        rms = {m: {c: _rms((tr.speed if c == "speed" else tr.current) - s[c])
                   for c in channels} for m, s in sims.items()}
        out.append(TracePrediction(tr, held_out, sims, band, param_band, noise, rms, coverage))
    return out
