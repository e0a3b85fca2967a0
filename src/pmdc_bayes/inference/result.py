"""The result of a run, handed from stage to stage, and read back from a run directory.

:class:`RunResult` carries what each stage produced: the session, the closed form,
the model (with its parameter registry), the MAP fit, the posterior draws and their
ArviZ record, and ``summary`` (its serialisation, written as ``summary.json``).  The
report is built from a :class:`RunResult`, either the one a run just produced or one
read back from disk by :func:`read_run`.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import UsageError
from .._x64 import x64
from ..io.loader import load_session
from ..io.session import DEAD_TIMES, LOAD_KINDS, NUISANCES, Session
from ..paper.closed_form import ClosedForm
from ..rundir import SESSION_COPY, changed_files
from .fit import FitResult
from .objective import SessionModel, build_model
from .seed import fit_seed

__all__ = ["RunResult", "read_run", "read_summary"]


@dataclass(frozen=True, repr=False)
class RunResult:
    """A finished run.

    Attributes
    ----------
    summary : the JSON-ready record of the run (``summary.json``).
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

    @property
    def adequate(self) -> bool:
        """Whether the data do not reject the fitted model (True for old runs)."""
        return self.summary.get("adequacy", {}).get("verdict", "adequate") == "adequate"

    @property
    def has_posterior(self) -> bool:
        return self.draws is not None

    def __repr__(self) -> str:
        from .._headline import headline_text

        return headline_text(self.summary)

    def _repr_html_(self) -> str:
        from .._headline import headline_html

        return headline_html(self.summary)

    def write(self, out, *, force: bool = False) -> Path:
        """Write the run directory ``out`` (summary, posterior, report, a copy of the
        session's files), whole or not at all; ``force`` replaces an earlier run only."""
        from ..pipeline import write_run

        if self.summary["session"].get("changed_in_memory"):
            raise UsageError(f"{out}: not written: the session was changed in memory, so "
                             f"its files under {self.session_full.root} are not what was "
                             "fitted and the run could not be read back; write the session's "
                             "files (docs/session-format.md) and fit those")
        return write_run(self, Path(out), force=force)

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
        from ..physics.motor import state_space

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
        from ..physics.loop import pi_loop

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


def read_summary(run_dir: Path) -> dict:
    """``summary.json`` of a run directory, or a :class:`UsageError` saying what is wrong."""
    path = Path(run_dir) / "summary.json"
    if not path.is_file():
        raise UsageError(f"{run_dir}: no summary.json here; give the directory a "
                         "'pmdc-bayes fit' run wrote")
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UsageError(f"{path}: not valid JSON ({exc}); rerun 'pmdc-bayes fit'") from None
    if not isinstance(summary, dict) or not {"session", "parameters", "fit"} <= set(summary):
        raise UsageError(f"{path}: not a summary written by 'pmdc-bayes fit' (keys session, "
                         "parameters and fit are missing); rerun 'pmdc-bayes fit'")
    return summary


def _run_session(run_dir: Path, info: dict):
    """The session a run was fitted on: the run's own copy when it is intact, else the
    original, refused if it changed since the fit (naming the copy's damaged file when
    there is a copy); with the nuisances the fit added."""
    copy = run_dir / SESSION_COPY
    hashes = info.get("files") or {}
    # a model search writes the model it chose into the copy's session.toml
    copied = {**hashes, **(info.get("copy_rewritten") or {})}
    damaged = changed_files(copy, copied) if (copy / "session.toml").is_file() else None
    if damaged == []:
        return _with_nuisances(load_session(copy), run_dir, info)
    changed = changed_files(Path(info["path"]), hashes)
    if changed and damaged:
        bad = copy / damaged[0]
        how = "is missing" if not bad.exists() else "differs from the SHA-256 the fit recorded"
        raise UsageError(f"{bad}: {how} in the run's copy of the session (and the original "
                         f"{Path(info['path'])} changed or moved since the fit); restore the "
                         "file or rerun 'pmdc-bayes fit'")
    if changed:
        raise UsageError(f"{Path(info['path']) / changed[0]}: changed or missing since the "
                         f"fit of {run_dir} (the run holds no intact copy); rerun "
                         "'pmdc-bayes fit' on the session as it is now")
    return _with_nuisances(load_session(info["path"]), run_dir, info)


def _with_nuisances(session, run_dir: Path, info: dict):
    """``session`` with the nuisances and loaded traces the summary records."""
    if "nuisances" in info:
        names = info["nuisances"]
        if not isinstance(names, list) or not set(names) <= set(NUISANCES):
            raise UsageError(f"{run_dir / 'summary.json'}: session.nuisances is {names!r}, not "
                             f"a list of {', '.join(NUISANCES)}; rerun 'pmdc-bayes fit'")
        loaded = info.get("loaded_traces") or []
        if not isinstance(loaded, list) or not set(loaded) <= {t.name for t in session.traces}:
            raise UsageError(f"{run_dir / 'summary.json'}: session.loaded_traces is "
                             f"{loaded!r}, not a list of the session's traces; rerun "
                             "'pmdc-bayes fit'")
        kinds = info.get("load_kinds") or {}
        if (not isinstance(kinds, dict) or not set(kinds) <= set(loaded)
                or not set(kinds.values()) <= set(LOAD_KINDS)):
            raise UsageError(f"{run_dir / 'summary.json'}: session.load_kinds is {kinds!r}, "
                             "not a table of loaded traces to constant, viscous or both; "
                             "rerun 'pmdc-bayes fit'")
        coloured = info.get("coloured_traces") or []
        if not isinstance(coloured, list) or not set(coloured) <= {
                t.name for t in session.traces + session.coast_downs}:
            raise UsageError(f"{run_dir / 'summary.json'}: session.coloured_traces is "
                             f"{coloured!r}, not a list of the session's traces; rerun "
                             "'pmdc-bayes fit'")
        dead = info.get("dead_time", "per_trace")
        if dead not in DEAD_TIMES:
            raise UsageError(f"{run_dir / 'summary.json'}: session.dead_time is {dead!r}, "
                             f"not one of {', '.join(DEAD_TIMES)}; rerun 'pmdc-bayes fit'")
        session = dataclasses.replace(session, nuisances=tuple(names),
                                      loaded_traces=tuple(loaded),
                                      load_kinds=tuple(kinds.items()),
                                      coloured_traces=tuple(coloured),
                                      shared_dead_time=dead == "shared")
    return session


def _read_posterior(run_dir: Path, names) -> tuple:
    path = run_dir / "posterior.nc"
    if not path.is_file():
        return None, None
    from .diagnostics import az

    try:
        idata = az.from_netcdf(path)
        post = idata.posterior
        draws = np.stack([np.asarray(post[n].values, dtype=float).reshape(-1) for n in names],
                         axis=1)
    except Exception as exc:  # any unreadable or foreign file: one line, not a traceback
        raise UsageError(f"{path}: cannot be read as this run's posterior ({type(exc).__name__}:"
                         f" {exc}); rerun 'pmdc-bayes fit'") from None
    return draws, idata


@x64
def read_run(run_dir) -> RunResult:
    """The :class:`RunResult` of a finished run directory (the session is re-read from
    the run's own copy, or from the path its summary records when it holds no intact
    copy)."""
    run_dir = Path(run_dir)
    summary = read_summary(run_dir)
    info = summary["session"]
    session_full = _run_session(run_dir, info)
    held = list(info.get("holdout") or [])
    session = session_full.without_traces(held) if held else session_full
    cf = fit_seed(session)
    coulomb = info.get("friction") == "coulomb"
    model = build_model(session, cf, coulomb=coulomb)
    draws, idata = _read_posterior(run_dir, model.names)
    return RunResult(summary, session, session_full, cf, model, None, draws, idata)
