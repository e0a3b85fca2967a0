"""Everything a report needs from a finished run, loaded once.

The report is built from a :class:`~pmdc_bayes.run.RunResult`: the one a
run just produced, or one read back from a run directory (``summary.json``,
``posterior.nc`` and the session at the path the summary records).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._x64 import x64
from ..inference.model.objective import SessionModel, build_model
from ..io.session import Session
from ..paper.closed_form import ClosedForm
from ._view import FigureView, TracePrediction
from .predictive import predict_traces

if TYPE_CHECKING:
    from ..run import RunResult

__all__ = ["ReportContext", "context_from_result", "N_PREDICTIVE_DRAWS"]

N_PREDICTIVE_DRAWS = 100  # posterior draws simulated for the predictive bands


@dataclass(frozen=True)
class ReportContext(FigureView):
    """A finished run, ready to report: the :class:`FigureView` and the rest.

    Attributes
    ----------
    run_dir : the run directory.
    session : the session the fit saw (hold-out traces removed).
    session_full : the session with every trace (hold-out traces included).
    cf : the closed form of ``session``.
    model : the objective of ``session`` (its friction model is the run's).
    idata : the ArviZ record, or None.
    predictions : per fitted trace, :class:`TracePrediction`.
    holdout : per held-out trace, :class:`TracePrediction`.
    """

    run_dir: Path
    session: Session
    session_full: Session
    cf: ClosedForm
    model: SessionModel
    idata: object
    predictions: list[TracePrediction]
    holdout: list[TracePrediction]


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
    chains = None
    if result.idata is not None and draws is not None:
        chains = {n: np.asarray(result.idata.posterior[n].values) for n in names}
    return ReportContext(
        summary=summary, session=session, names=names, values=values, truth=truth,
        draws=draws, chains=chains, coulomb=bool(model.coulomb),
        log_names=tuple(n for n in names if model.registry[n].transform == "log"),
        cf_applicable=bool(cf.applicable), run_dir=Path(run_dir),
        session_full=result.session_full, cf=cf, model=model, idata=result.idata,
        predictions=preds, holdout=holdout)
