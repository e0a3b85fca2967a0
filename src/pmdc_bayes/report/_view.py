"""What the figures see of a run: plain, picklable records (NumPy arrays, dicts, the
session), so that a figure can be built and drawn in a worker process that imports
neither JAX nor ArviZ (:mod:`._render`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..io.session import Trace

__all__ = ["FigureView", "TracePrediction", "trace_channels", "BAND", "METHODS"]

BAND = (0.03, 0.97)  # quantiles of the 94 % band
METHODS = {"closed_form": "closed form", "map": "MAP", "mean": "posterior predictive"}


@dataclass(frozen=True)
class TracePrediction:
    """One trace's measurements and predictions (SI: A, rad/s, rad).

    ``sims[method][channel]`` with method in ``closed_form``, ``map`` and, with a
    posterior, ``mean`` (the posterior predictive mean); channel ``speed``,
    ``current`` or ``position`` (those the trace logs, :func:`trace_channels`).  ``band`` and
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
        return _measured(self.trace, channel)

    @property
    def channels(self) -> tuple:
        return trace_channels(self.trace)


def trace_channels(tr: Trace) -> tuple:
    """The channels a trace logged: ``speed`` (unless estimated from an angle),
    ``current``, ``position``."""
    return tuple(c for c, y in (("speed", tr.speed if tr.speed_logged else None),
                                ("current", tr.current), ("position", tr.position))
                 if y is not None)


def _measured(tr: Trace, channel: str) -> np.ndarray:
    return {"speed": tr.speed, "current": tr.current, "position": tr.position}[channel]


@dataclass(frozen=True)
class FigureView:
    """A finished run as the figures see it.

    Attributes
    ----------
    summary : ``summary.json`` as a dict.
    names : parameter names in θ order.
    values : ``{"closed_form" | "map" | "mean": {name: SI value}}`` (``mean`` only with
        a posterior); the closed form has ``Tc = 0``.
    truth : true values of a simulated session, or None.
    draws : all posterior draws ``(N, P)`` in SI, or None without a posterior.
    chains : per parameter its ``(walkers, steps)`` draws (SI), or None.
    coulomb : whether the fitted model has Coulomb friction.
    log_names : the parameters fitted on a log scale (the positive ones).
    cf_applicable : whether the paper's closed-form method ran on the session.
    """

    summary: dict
    names: tuple
    values: dict
    truth: dict | None
    draws: np.ndarray | None
    chains: dict | None
    coulomb: bool
    log_names: tuple
    cf_applicable: bool

    @property
    def has_posterior(self) -> bool:
        return self.draws is not None

    @property
    def best(self) -> dict:
        """The reference parameter set: the posterior mean, else the MAP."""
        return self.values.get("mean") or self.values["map"]

    @property
    def cf_label(self) -> str:
        """What the closed-form curves and points are: the paper's method, or the
        data's seed when the method cannot run on the session."""
        return "closed form" if self.cf_applicable else "seed (closed form n/a)"

    @property
    def best_label(self) -> str:
        return "posterior mean" if self.has_posterior else "MAP"

    def unit(self, name: str) -> str:
        """A parameter's SI unit as written in ``summary.json`` (from the registry)."""
        return self.summary["parameters"][name]["unit"]

    def sd(self, name: str) -> float:
        """Posterior sd of a parameter (SI), else its Laplace sd at the MAP."""
        row = self.summary["parameters"][name]
        return float(row["sd"] if "sd" in row else row["map_sd"])

    def covariance(self) -> np.ndarray:
        """Parameter covariance (SI): of the posterior draws, else Laplace (MAP sd and
        the fit's correlation; note the fit works in log space, so this is linearised)."""
        if self.draws is not None:
            return np.cov(self.draws, rowvar=False)
        corr = np.asarray(self.summary["fit"]["correlation"], dtype=float)
        sd = np.array([self.summary["parameters"][n]["map_sd"] for n in self.names])
        return corr * np.outer(sd, sd)

    def view(self, *, draws: bool = True, chains: bool = True) -> FigureView:
        """This record as a plain :class:`FigureView` (what a worker process receives),
        without the posterior draws or the chains when the figure does not read them
        (they are pickled for each figure)."""
        v = {f.name: getattr(self, f.name) for f in fields(FigureView)}
        v["draws"] = v["draws"] if draws else None
        v["chains"] = v["chains"] if chains else None
        return FigureView(**v)
