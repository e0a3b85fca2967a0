"""A run directory read back: its summary, its copy of the session, its posterior, as
the :class:`~.run.RunResult` the report is built from."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ._errors import UsageError
from ._x64 import x64
from .inference.model.objective import build_model
from .inference.model.seed import fit_seed
from .io.loader import load_session
from .io.session import DEAD_TIMES, LOAD_KINDS, NUISANCES
from .run import RunResult
from .rundir import SESSION_COPY, changed_files

__all__ = ["read_run", "read_summary", "write_report"]


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
    from .inference.sampling.arviz_import import az

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


def write_report(run_dir, *, say=None) -> dict[str, Path]:
    """Write the report of a finished run directory again, from ``summary.json``,
    ``posterior.nc`` (optional: without it the posterior parts are skipped and the
    report says so) and the run's own copy of the session; return the paths written
    (:func:`~.report.write_report_for`).  Raises :class:`pmdc_bayes.UsageError` when
    ``run_dir`` holds no usable run."""
    from .report import write_report_for

    say = say or (lambda text: None)
    say(f"reading {run_dir}: summary.json, its copy of the session, posterior.nc")
    return write_report_for(read_run(run_dir), run_dir, say=say)
