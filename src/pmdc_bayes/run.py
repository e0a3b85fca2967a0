"""The record of a run, handed from stage to stage and written as a run directory.

:class:`RunResult` carries what each stage produced: the session, the closed form,
the model (with its parameter registry), the MAP fit, the posterior draws and their
ArviZ record, and ``summary`` (its serialisation, written as ``summary.json``);
:func:`write_run` writes it, whole or not at all, and :mod:`.readback` reads it back.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._errors import UsageError
from .inference.adequacy.findings import Verdict
from .inference.fit.joint import FitResult
from .inference.model.objective import SessionModel
from .io.output import dumps
from .io.session import Session
from .paper.closed_form import ClosedForm
from .rundir import copy_session, write_atomically, write_model

__all__ = ["RunResult", "write_run"]


@dataclass(frozen=True, repr=False)
class RunResult:
    """A finished run.

    Attributes
    ----------
    summary : the JSON-ready record of the run (``summary.json``), never changed once
        the result is built: :meth:`recorded` gives a result with more in it.
    session : the session the fit saw (hold-out traces removed).
    session_full : the session with every trace.
    closed_form : the paper's closed form of ``session``, or None where it cannot run.
    model : the objective (its ``registry`` lists the parameters).
    fit : the MAP fit, or None for a run read back from disk (``summary`` has it).
    draws : posterior draws ``(N, P)`` in SI in the registry's order, or None.
    idata : the ArviZ record of the posterior, or None.
    adequacy : the adequacy checks at the MAP (:class:`~.adequacy.Adequacy`), or None for
        a run read back from disk (``summary["adequacy"]`` has them).
    """

    summary: dict
    session: Session
    session_full: Session
    closed_form: ClosedForm | None
    model: SessionModel
    fit: FitResult | None = None
    draws: np.ndarray | None = None
    idata: object = None
    adequacy: object = None

    @property
    def names(self) -> tuple:
        return tuple(self.model.names)

    def recorded(self, **entries) -> RunResult:
        """The same run with ``entries`` as top-level entries of its summary (a new
        summary: a result's record is never changed once it is built)."""
        return dataclasses.replace(self, summary={**self.summary, **entries})

    def session_recorded(self, **entries) -> RunResult:
        """The same run with ``entries`` added to its summary's ``session`` record."""
        return self.recorded(session={**self.summary["session"], **entries})

    @property
    def adequate(self) -> bool:
        """Whether the data do not reject the fitted model (True for old runs)."""
        return Verdict.of(self.summary) is Verdict.ADEQUATE

    @property
    def has_posterior(self) -> bool:
        return self.draws is not None

    def __repr__(self) -> str:
        from ._headline import headline_text

        return headline_text(self.summary)

    def _repr_html_(self) -> str:
        from ._headline import headline_html

        return headline_html(self.summary)

    def write(self, out, *, force: bool = False) -> Path:
        """Write the run directory ``out`` (summary, posterior, report, a copy of the
        session's files), whole or not at all; ``force`` replaces an earlier run only."""
        if self.summary["session"].get("changed_in_memory"):
            raise UsageError(f"{out}: not written: the session was changed in memory, so "
                             f"its files under {self.session_full.root} are not what was "
                             "fitted and the run could not be read back; write the session's "
                             "files (docs/session-format.md) and fit those")
        write_run(self, Path(out), force=force)
        return Path(out)

    def to_control(self, draws: int | None = None, *, seed: int = 0):
        """The motor as a python-control ``StateSpace`` (state ``[ω, ia]``, inputs
        ``[TL, Va]``, output ``ω``, equations (11)–(14)) at the posterior mean (the MAP
        without a posterior); with ``draws=N``, a list of ``N`` systems, one per
        posterior draw picked at random, for bands of step and frequency responses.
        Coulomb friction, a constant load opposing the motion, is not part of them."""
        try:
            import control
        except ImportError as exc:
            raise ImportError("python-control is not installed; pip install "
                              "'pmdc-bayes[control]'") from exc
        from .physics.motor import state_space

        def system(v):
            A, Bu, C, D = state_space(*(float(v[n]) for n in ("Ra", "La", "K", "B", "J")))
            return control.ss(np.asarray(A), np.asarray(Bu), C, D, inputs=["TL", "Va"],
                              outputs=["omega"], states=["omega", "ia"])

        values = self.values()
        if draws is None:
            return system(values.get("mean", values["map"]))
        if self.draws is None:
            raise UsageError("no posterior to draw systems from: fit with mcmc=True, or "
                             "call to_control() for the MAP's system")
        rows = np.random.default_rng(seed).choice(len(self.draws), size=int(draws),
                                                  replace=int(draws) > len(self.draws))
        return [system(dict(zip(self.names, self.draws[k], strict=True))) for k in rows]

    def pi_loop(self, kp: float, ki: float, delay: float = 0.0, *, draws: int = 1000,
                seed: int = 0) -> dict:
        """Stability margins of a PI speed loop ``Va = kp·e + ki·∫e`` (e the speed
        error, rad/s; an optional loop delay in s) around the motor, at the posterior
        mean (the MAP without a posterior) and over up to ``draws`` posterior draws:
        :func:`~pmdc_bayes.physics.loop.pi_loop`."""
        from .physics.loop import pi_loop

        values = self.values()
        rows = []
        if self.draws is not None:
            pick = np.random.default_rng(seed).choice(
                len(self.draws), size=min(draws, len(self.draws)), replace=False)
            rows = [dict(zip(self.names, self.draws[k], strict=True)) for k in pick]
        return pi_loop(kp, ki, delay, values.get("mean", values["map"]), rows)

    def values(self) -> dict:
        """``{"closed_form" | "map" | "mean": {name: SI value}}`` (``closed_form`` only when
        the method ran, with ``Tc = 0``; ``mean`` only with a posterior)."""
        params = self.summary["parameters"]
        out = {"map": {n: float(params[n]["map"]) for n in self.names}}
        if self.closed_form is not None:
            out["closed_form"] = dict(self.closed_form.params(), Tc=0.0)
        if self.draws is not None:
            out["mean"] = {n: float(np.mean(self.draws[:, k])) for k, n in enumerate(self.names)}
        return out


def write_run(result: RunResult, out: Path, *, force: bool = False) -> RunResult:
    """Write a run directory (summary, posterior, report) atomically: everything is
    built in a temporary sibling and renamed into place only when complete.  Returns
    the run as written: its summary with the session's files copied into it and the
    report's time."""
    from .report import report_stage

    written = []

    def fill(tmp: Path):
        files = {"files": copy_session(result.session_full, tmp)}
        chosen = result.summary.get("model_selection")
        if chosen:
            files["copy_rewritten"] = write_model(result.session_full, tmp, chosen["model"],
                                                  chosen["friction"])
        run = result.session_recorded(**files)
        (tmp / "summary.json").write_text(dumps(run.summary))
        if run.idata is not None:
            # uncompressed: 0.4 s instead of 2.4 s for a demo-sized run, 30 % larger
            run.idata.to_netcdf(tmp / "posterior.nc", compress=False)
        written.append(report_stage(run, out, tmp))

    write_atomically(Path(out), fill, force=force)
    return written[-1]
