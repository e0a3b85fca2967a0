"""A candidate model of the search (:mod:`.search`): fitted at its MAP from the usual
starts and from its parent's MAP (in its own compiled programs, or a superset model's
where one covers it and pays, :mod:`.supersets`), scored by its Laplace evidence and
checked for adequacy where the search's choice turns on it; and the typed results the
search hands on."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from .inference.adequacy.verdict import assess
from .inference.fit.joint import fit_map
from .inference.fit.undetermined import PRIOR_DOMINATED
from .inference.model.objective import build_model
from .inference.model.seed import fit_seed
from .io.session import Session
from .selection import laplace_log_evidence
from .terms import label, ordered, with_terms

__all__ = ["Candidate", "Fitted", "Searched", "Stop", "nested_start"]


class Stop(enum.Enum):
    """Why the search stopped (its text, for the record's reason)."""

    FIT_FAILED = "its MAP fit failed, so there is nothing to build on"
    FAULTY_DATA = ("the data hold a bad reading (its verdict's first line), which no "
                   "addition to the model mends")
    ADEQUATE_START = "the data do not reject the session's model"
    ADEQUATE_REACHED = ("the data do not reject it (a plain fit stops at the first model "
                        "the data do not reject; fit --compare tries every addition to it "
                        "as well)")
    NOTHING_BETTER = "the data do not reject it and no single addition is clearly better"
    NO_GAIN = "no addition improves on it"
    FITS = "the bound of {max_fits} fits was reached"
    STEPS = "the bound of {max_fits} steps was reached"


@dataclass(frozen=True)
class Fitted:
    """A candidate fitted at its MAP and checked: the seed, model, MAP fit and verdict a
    run goes on from without fitting them again."""

    session: Session
    seed: object
    model: object
    fit: object
    adequacy: object


@dataclass(frozen=True)
class Searched:
    """The search's record (ready for JSON), the chosen candidate's fit and why the
    search stopped."""

    record: dict
    chosen: Fitted
    stop: Stop


def _neutral(spec) -> float:
    """A parameter's value that leaves the prediction as without it, or nearly (SI): a
    dead time or offset of zero, a gain of one, a current limit far above its prior's
    centre, a lag, load or Coulomb friction far below it, a drop at a quarter of its
    half-normal prior's scale (a start whose gradient in log the fit can still follow)."""
    if spec.transform == "identity":
        return float(spec.prior.centre)
    if spec.unit == "1":
        return 1.0
    width = 2.0 * spec.prior.width_in_log()
    return float(spec.prior.typical * math.exp(width if spec.name == "Imax" else -width))


def nested_start(model, fit) -> np.ndarray:
    """θ of ``model`` (its registry's order) at ``fit``'s MAP, every parameter ``fit`` lacks
    at its neutral value: a start at which the larger model predicts (nearly) what the
    smaller did."""
    values = {s.name: fit.values[s.name] if s.name in fit.values else _neutral(s)
              for s in model.registry.specs}
    return np.asarray(model.theta(values), dtype=float)


class Candidate:
    """One fitted candidate and its row of the search's record."""

    def __init__(self, terms, session, cf, model, parent, move):
        self.terms, self.session, self.cf, self.model = terms, session, cf, model
        self.parent, self.move = parent, move
        self.fit = self._adequacy = None
        self.log_evidence = math.nan
        self.undetermined = ()
        self.why = ""

    @classmethod
    def of(cls, session: Session, terms, parent=None, move: str = "start") -> Candidate:
        """The candidate of ``session`` with the model ``terms`` declares, its seed and
        model built, not yet fitted (:meth:`run`)."""
        s = with_terms(session, terms)
        cf = fit_seed(s)
        return cls(terms, s, cf, build_model(s, cf), parent, move)

    @property
    def adequacy(self):
        """The verdict on the candidate (:func:`~.inference.adequacy.verdict.assess`), made when
        first asked for: the search asks only of the candidates its choice turns on."""
        if self._adequacy is None:
            self._adequacy = assess(self.model, self.fit, self.cf)
        return self._adequacy

    @property
    def checked(self) -> bool:
        """Whether the verdict is made (a candidate's programs are not needed after)."""
        return self._adequacy is not None

    @property
    def ok(self) -> bool:
        return self.adequacy.ok and self.fit.ok \
            and math.isfinite(self.log_evidence)

    def run(self, seed: int, superset=None) -> None:
        """Fit, check and score the candidate; in ``superset``'s compiled programs (a
        :class:`~.inference.fit.superset.Superset` that covers it) when given."""
        starts = [] if self.parent is None else [nested_start(self.model, self.parent.fit)]
        if superset is None:
            self.fit = fit_map(self.model, seed=seed, alternatives=starts)
        else:
            self.fit = superset.fit(self.model, seed=seed, alternatives=starts)
        self.log_evidence = laplace_log_evidence(self.model, self.fit)
        own = set(self.parent.model.names) if self.parent is not None else set(self.model.names)
        ratio = np.sqrt(np.clip(np.diag(self.fit.cov_log), 0, None)) / self.model.prior_sd
        self.undetermined = tuple(n for n, r in zip(self.model.names, ratio, strict=True)
                                  if n not in own and r > PRIOR_DOMINATED)

    def row(self) -> dict:
        """The candidate's row of the record; its verdict ``"not checked"`` where the
        search's choice did not turn on it (its evidence too low to be taken)."""
        fit = self.fit
        parent = self.parent
        verdict = self._adequacy
        return {"name": label(self.terms), "terms": ordered(self.terms),
                "n_params": len(self.model.names), "move": self.move,
                "parent": None if parent is None else label(parent.terms),
                "verdict": "not checked" if verdict is None else str(verdict.verdict),
                "converged": fit.ok,
                "log_posterior": float(fit.log_posterior), "log_evidence": self.log_evidence,
                "delta_log_evidence": None if parent is None
                else self.log_evidence - parent.log_evidence,
                "undetermined": list(self.undetermined),
                "failures": [] if verdict is None else [f"{f.where}: {f.check}"
                                                         for f in verdict.failures()],
                "values": {n: [fit.values[n], fit.sd[n]] for n in self.model.names},
                "loo": None, "decision": "dropped", "why": ""}
