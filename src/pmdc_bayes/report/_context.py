"""Everything a report needs from a finished run, loaded once.

A run directory holds ``summary.json`` and, when the sampler ran, ``posterior.nc``;
the session is re-read from the path the summary records, so simulations for the
figures use exactly the data of the fit.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import jax
import numpy as np

from .._errors import UsageError
from ..paper.closed_form import ClosedForm, closed_form
from ..io.loader import load_session
from ..inference.objective import SessionModel, build_model
from ..io.session import Session
from .predictive import TracePrediction, predict_traces
from .._x64 import x64

__all__ = ["ReportContext", "load_context", "N_PREDICTIVE_DRAWS"]

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
    def best_label(self) -> str:
        return "posterior mean" if self.has_posterior else "MAP"

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


def _read_summary(run_dir: Path) -> dict:
    path = run_dir / "summary.json"
    if not path.is_file():
        raise UsageError(f"{run_dir}: no summary.json here; give the directory a "
                         "'pmdc-bayes fit' run wrote")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise UsageError(f"{path}: not valid JSON ({exc}); rerun 'pmdc-bayes fit'") from None


def _read_posterior(run_dir: Path, names) -> tuple:
    path = run_dir / "posterior.nc"
    if not path.is_file():
        return None, None
    from ..inference.diagnostics import az

    idata = az.from_netcdf(path)
    post = idata.posterior
    draws = np.stack([np.asarray(post[n].values, dtype=float).reshape(-1) for n in names],
                     axis=1)
    return draws, idata


@x64
def load_context(run_dir) -> ReportContext:
    """Read a run directory and compute the simulations the report shows."""
    run_dir = Path(run_dir)
    summary = _read_summary(run_dir)
    info = summary["session"]
    session_full = load_session(info["path"])
    held = list(info.get("holdout") or [])
    session = session_full.without_traces(held) if held else session_full
    cf = closed_form(session)
    coulomb = info.get("friction") == "coulomb"
    model = build_model(session, cf, coulomb=coulomb)
    names = tuple(model.names)
    params = summary["parameters"]
    values = {"closed_form": dict(cf.params(), Tc=0.0),
              "map": {n: float(params[n]["map"]) for n in names}}
    draws, idata = _read_posterior(run_dir, names)
    if draws is not None:
        values["mean"] = {n: float(np.mean(draws[:, k])) for k, n in enumerate(names)}
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
    if held:
        others = [t.name for t in session_full.traces if t.name not in held]
        ho_model = build_model(session_full.without_traces(others), cf, coulomb=coulomb)
        holdout = predict_traces(ho_model, values, sub, noise, seed=seed + 1, held_out=True)
    return ReportContext(run_dir, summary, session_full, session, cf, model, names, values,
                         truth, draws, idata, preds, holdout)
