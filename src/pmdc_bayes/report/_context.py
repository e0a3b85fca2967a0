"""Everything a report needs from a finished run, loaded once.

The report is built from a :class:`~pmdc_bayes.inference.result.RunResult`: the one a
run just produced, or one read back from a run directory (``summary.json``,
``posterior.nc`` and the session at the path the summary records).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._x64 import x64
from ..inference.objective import SessionModel, build_model
from ..inference.result import RunResult, read_run
from ..io.session import Session
from ..paper.closed_form import ClosedForm
from .predictive import TracePrediction, predict_traces

__all__ = ["ReportContext", "load_context", "context_from_result", "N_PREDICTIVE_DRAWS"]

N_PREDICTIVE_DRAWS = 100  # posterior draws simulated for the predictive bands


@dataclass(frozen=True)
class ReportContext:
    """A finished run, ready to report.

    Attributes
    ----------
    run_dir : the run directory.
    summary : ``summary.json`` as a dict.
    session_full : the session with every trace (hold-out traces included).
    session : the session the fit saw (hold-out traces removed).
    cf : the closed form of ``session``.
    model : the objective of ``session`` (its friction model is the run's).
    names : parameter names in θ order.
    values : ``{"closed_form" | "map" | "mean": {name: SI value}}`` (``mean`` only with
        a posterior); the closed form has ``Tc = 0``.
    truth : true values of a simulated session, or None.
    draws : all posterior draws ``(N, P)`` in SI, or None without a posterior.
    idata : the ArviZ record, or None.
    predictions : per fitted trace, :class:`TracePrediction`.
    holdout : per held-out trace, :class:`TracePrediction`.
    """

    run_dir: Path
    summary: dict
    session_full: Session
    session: Session
    cf: ClosedForm
    model: SessionModel
    names: tuple
    values: dict
    truth: dict | None
    draws: np.ndarray | None
    idata: object
    predictions: list[TracePrediction]
    holdout: list[TracePrediction]

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
        return "closed form" if self.cf.applicable else "seed (closed form n/a)"

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


@x64
def context_from_result(result: RunResult, run_dir) -> ReportContext:
    """The report's view of a run result, with the simulations the report shows;
    ``run_dir`` is where the run lives (named in the report)."""
    summary, session, model, cf = result.summary, result.session, result.model, result.closed_form
    names = result.names
    values = result.values()
    draws = result.draws
    truth = summary.get("truth") or session.truth
    if truth:
        truth = {n: truth.get(n) for n in names}
    sub = None
    if draws is not None:
        idx = np.linspace(0, draws.shape[0] - 1, min(N_PREDICTIVE_DRAWS, draws.shape[0]))
        sub = draws[idx.astype(int)]
    noise = summary["fit"].get("noise_sd", {})
    seed = int(summary.get("seed", 0))
    preds = predict_traces(model, values, sub, noise, seed=seed)
    holdout = []
    held = list(summary["session"].get("holdout") or [])
    if held:
        full = result.session_full
        others = [t.name for t in full.traces if t.name not in held]
        ho_model = build_model(full.without_traces(others), cf, coulomb=model.coulomb)
        holdout = predict_traces(ho_model, values, sub, noise, seed=seed + 1, held_out=True)
    return ReportContext(Path(run_dir), summary, result.session_full, session, cf, model, names,
                         values, truth, draws, result.idata, preds, holdout)


def load_context(run_dir) -> ReportContext:
    """Read a run directory and compute the simulations the report shows."""
    return context_from_result(read_run(run_dir), run_dir)
