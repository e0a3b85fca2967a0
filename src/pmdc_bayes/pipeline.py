"""The ``pmdc-bayes fit`` pipeline: closed form → MAP (→ MCMC) → report, written atomically.

A run directory is built beside its destination under a temporary name and renamed
into place only when complete, so a crash never leaves a half-written run and never
replaces a good one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import posterior_stage as _stage
from ._errors import FitFailed, UsageError
from ._x64 import x64
from .inference import StageClock, announcing
from .inference.adequacy.assess import assess
from .inference.fit.identifiability import identifiability
from .inference.fit.joint import fit_map
from .inference.model.objective import build_model
from .inference.model.seed import fit_seed, refuse_reversed
from .inference.warmup import WarmUp
from .io.loader import load_session
from .io.session import NUISANCES, Session
from .paper.consistency import consistency_checks
from .run import RunResult, write_run
from .rundir import check_replaceable, default_out_dir, versions

__all__ = ["fit_session", "run_fit", "search_session", "model_left_open", "write_run"]

SAMPLING_SECONDS = None  # no bound on the sampler's wall time by default: it stops
# by its step budget, so a run's result does not depend on the machine's load
def _rms(x) -> float:
    x = np.asarray(x)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def trace_rms(model, theta) -> dict:
    """Per trace RMS of the residuals of each channel it logged: ``speed`` (rad/s),
    ``current`` (A), ``position`` (rad; where an encoder's count has not started, no
    sample).  A speed estimated from the angle is not a measurement and has no row."""
    out = {}
    angles = model.predict_angles(theta)
    for tr, (ia, w), a in zip(model.session.traces, model.predict(theta),
                              angles, strict=True):
        row = {}
        if tr.speed_logged:
            row["speed"] = _rms(tr.speed - w)
        if tr.current is not None:
            row["current"] = _rms(tr.current - ia)
        if tr.position is not None and a is not None:
            row["position"] = _rms(tr.position - a)
        out[tr.name] = row
    return out


def _closed_form_theta(model, cf):
    return np.asarray(model.theta(dict(cf.params(), Tc=0.0)))


@x64
def fit_session(session_full: Session, *, mcmc: bool = True, friction: str | None = None,
                seed: int = 0, holdout=(), compare_friction: bool = False,
                progress=None, allow_inadequate: bool = False, say=None,
                max_sampling_seconds: float | None = SAMPLING_SECONDS,
                fitted=None, clock: StageClock | None = None) -> RunResult:
    """Every stage of a fit, in memory: closed form → MAP → adequacy → (MCMC); the
    run's result.  ``say``, when given, is called with a line as each stage starts.
    ``fitted`` (a :class:`~.search.Fitted` of this session's model, as the model search
    leaves it) stands for the closed form, MAP and adequacy stages; ``clock``, the
    :class:`~.inference.StageClock` that timed the search, goes on timing.
    The sampler stops by its rule or its step budget (the same on any machine);
    ``max_sampling_seconds``, when given, also bounds its wall time (default None: no
    bound); a posterior stopped by either fails its gates with the reason.

    ``summary`` of the result is what ``summary.json`` holds; nothing is written.  When
    the adequacy checks reject the model the posterior is not sampled (it would only
    describe the misfit) unless ``allow_inadequate``.
    """
    say = say or (lambda text: None)
    clock = clock or StageClock()
    session = _held_out(session_full, holdout)
    if fitted is not None:  # the model search fitted and checked it (its stage's time)
        cf, model, fit, adequacy = fitted.seed, fitted.model, fitted.fit, fitted.adequacy
        warm = WarmUp(model, mcmc=mcmc)
        with clock.stage("identifiability"), warm.stopped_on_error():
            _fit_failed(session, fit)
            ident = identifiability(model, fit)
    else:
        with clock.stage("closed_form"):
            say("closed form (the paper's method), or a seed from the data")
            refuse_reversed(session)
            cf = fit_seed(session)
        with clock.stage("map"):
            coulomb = None if friction is None else friction == "coulomb"
            model = build_model(session, cf, coulomb=coulomb)
            say(f"MAP fit of {len(model.names)} parameters")
            warm = WarmUp(model, mcmc=mcmc)  # the later stages' programs, meanwhile
            with warm.stopped_on_error():
                fit = fit_map(model, seed=seed)
                _fit_failed(session, fit)
                ident = identifiability(model, fit)
        with clock.stage("adequacy"), warm.stopped_on_error():
            say("adequacy checks")
            adequacy = assess(model, fit, cf)
    if not adequacy.ok and not allow_inadequate:
        warm.stop()

    cf_theta = _closed_form_theta(model, cf)
    params = {}
    for name in model.names:
        params[name] = {"unit": model.registry[name].unit,
                        "description": model.registry[name].description,
                        "block": model.registry[name].block,
                        "closed_form": cf.known().get(name) if cf.applicable else None,
                        "map": fit.values[name], "map_sd": fit.sd[name]}
        if not adequacy.ok:
            params[name]["note"] = "conditional on a model the data reject"
    summary = {
        "session": {"name": session.name, "path": str(session.root), "motor": session.motor,
                    "friction": "coulomb" if model.coulomb else "viscous",
                    "holdout": list(holdout), "nuisances": list(session.nuisances),
                    "loaded_traces": list(session.unknown_load_traces()),
                    "load_kinds": dict(session.load_kinds),
                    "coloured_traces": list(session.coloured_noise_traces()),
                    "dead_time": "shared" if session.shared_dead_time else "per_trace",
                    "gear_ratio": session.gear_ratio,
                    "rows_left_out": {tr.name: list(tr.rows_left_out)
                                      for tr in session.traces + session.coast_downs
                                      if tr.rows_left_out}},
        "adequacy": adequacy.as_json(),
        "seed": seed,
        "parameters": params,
        "closed_form": cf.as_json(),
        "fit": {"status": str(fit.status), "message": fit.message,
                "log_posterior": fit.log_posterior,
                "starts": fit.starts, "correlation": np.asarray(fit.corr).tolist(),
                "names": list(model.names),
                "noise_sd": {str(c): sd for c, sd in fit.noise_sd.items()}},
        "identifiability": ident,
        "consistency": consistency_checks(session, cf),
        "residuals": {"closed_form": trace_rms(model, cf_theta),
                      "map": trace_rms(model, fit.theta)},
        "versions": versions(),
    }
    if session.truth:
        summary["truth"] = {k: session.truth.get(k) for k in model.names}
    summary["diagnostics"] = {"gates_passed": None, "failures": []}
    post = None
    clock.wall["mcmc"] = clock.compile["mcmc"] = 0.0
    if mcmc and not adequacy.ok and not allow_inadequate:
        mcmc = False
        summary["diagnostics"]["sampler_message"] = (
            "not sampled: the data reject the model (pass --allow-inadequate to sample it)")
    if mcmc:
        with clock.stage("mcmc"), warm.stopped_on_error():
            say("sampling the posterior (emcee)")
            post, stats = _stage.posterior_stage(model, fit, seed=seed, progress=progress,
                                                  max_seconds=max_sampling_seconds)
            for name in model.names:
                params[name].update(stats["summary"][name])
            summary["derived"] = stats["derived"]
            summary["laplace_check"] = stats["laplace_check"]
            summary["diagnostics"].update(stats["diagnostics"])
            if compare_friction:
                summary["model_comparison"] = _stage.compare_friction(
                    session, cf, model, post, seed=seed, progress=progress,
                    max_seconds=max_sampling_seconds)
    clock.wall["report"] = clock.compile["report"] = 0.0
    clock.total()
    summary["diagnostics"]["wall_s"] = clock.wall
    summary["diagnostics"]["compile_s"] = clock.compile
    draws = None if post is None else post.draws.reshape(-1, len(model.names))
    return RunResult(summary, session, session_full, cf, model, fit, draws,
                     None if post is None else post.idata, adequacy)


def _fit_failed(session: Session, fit) -> None:
    """A MAP without a finite curvature (the model overflows near it) fails the run."""
    if fit.overflows:
        raise FitFailed(f"{session.root}: the MAP fit failed: {fit.message}")


def _held_out(session_full: Session, holdout) -> Session:
    """The session without the traces ``holdout`` names; bad input when that leaves one
    of its non-idealities nothing to act on (a dead time of none, coloured noise on a
    trace held out), or when it names no trace."""
    for name in holdout:
        if name not in {t.name for t in session_full.traces}:
            _no_trace(session_full, name)
    if not holdout:
        return session_full
    session = session_full.without_traces(holdout)
    inert = session.inert_nuisance()
    if inert is not None:
        raise UsageError(f"--holdout {', '.join(holdout)}: without it, {inert[0]} in "
                         f"session {session.name!r} has nothing to act on ({inert[1]}); "
                         "hold out another trace or leave it out of [model]")
    return session


@x64
def _refuse_inert(session: Session, added) -> None:
    """A non-ideality asked for with nothing in the session to act on is bad input."""
    inert = session.inert_nuisance(added)
    if inert is not None:
        raise UsageError(f"--add {inert[0].replace('_', '-')}: {inert[1]} in session "
                         f"{session.name!r}: there is nothing for it to fit; leave it out")


def run_fit(session_path, *, out: Path | None = None, force: bool = False,
            mcmc: bool = True, friction: str | None = None, seed: int = 0,
            holdout=(), compare_friction: bool = False,
            progress=None, allow_inadequate: bool = False,
            add=(), compare: bool = False, search: bool = True, say=None, pi=None,
            max_sampling_seconds: float | None = SAMPLING_SECONDS) -> tuple[Path, dict]:
    """Fit a session directory and write the run directory ``out``: ``summary.json``,
    ``posterior.nc`` (with MCMC) and the report, all built beside ``out`` and moved into
    place in one rename once complete.

    Returns the run directory and the summary.  Raises :class:`UsageError` for an
    existing ``out`` without ``force``.  ``add`` names rig non-idealities to fit on top
    of those the session declares (``io.session.NUISANCES``); ``compare`` first runs the
    model search of :mod:`.search` from the session's model and goes on from the fit of
    the model it chose, recording the search under ``"model_selection"`` and writing the
    chosen model into the run's copy of ``session.toml``; without ``compare`` the search
    runs when the model is left to it (:func:`model_left_open`), and is recorded only
    when the data reject the ideal model (``search=False``: never).  ``pi = (kp, ki,
    delay)`` records the stability margins of that PI speed loop under ``"pi_loop"``.
    """
    say = say or (lambda text: None)
    say(f"loading {session_path}")
    session_full = load_session(session_path)
    if add:
        import dataclasses

        wanted = set(session_full.nuisances) | set(add)
        session_full = dataclasses.replace(
            session_full, nuisances=tuple(n for n in NUISANCES if n in wanted))
        _refuse_inert(session_full, add)
    name = session_full.name
    out = Path(out) if out is not None else default_out_dir(name)
    check_replaceable(out, force)
    from .report import start_drawing

    start_drawing()  # the processes that draw the report: they import matplotlib meanwhile
    selection = chosen = None
    clock = StageClock()
    if compare or (search and model_left_open(session_full, add, friction)):
        session_full, selection, chosen = search_session(
            session_full, holdout=holdout, friction=friction, seed=seed, say=say,
            compare=compare, clock=clock)
    with announcing(say):
        result = fit_session(session_full, mcmc=mcmc, friction=friction, seed=seed,
                             holdout=holdout, compare_friction=compare_friction,
                             progress=progress, allow_inadequate=allow_inadequate, say=say,
                             max_sampling_seconds=max_sampling_seconds, fitted=chosen,
                             clock=clock)
    if selection is not None:
        result.summary["model_selection"] = selection
    if pi is not None:
        result.summary["pi_loop"] = result.pi_loop(*pi)
    say(f"writing {out} (summary, posterior, report)")
    write_run(result, out, force=force)
    return out, result.summary


def model_left_open(session: Session, add, friction: str | None) -> bool:
    """Whether the user left the model to the search: the session declares no
    ``[model]``, and neither a non-ideality nor the friction is asked for."""
    return not add and not session.nuisances and friction is None


def search_session(session_full: Session, *, holdout, friction, seed, say, compare,
                   clock: StageClock):
    """The session with the model the search chose, the search's record (None when, run
    without ``compare``, the data do not reject the session's model or its fit failed)
    and the chosen candidate's :class:`~.search.Fitted`, for :func:`fit_session` to go on
    from; ``clock`` times it as the stage ``model_search``."""
    from .search import Stop, run_search
    from .terms import with_terms

    fitted = _held_out(session_full, holdout)
    with announcing(say), clock.stage("model_search"):
        searched = run_search(fitted, friction=friction, seed=seed, say=say,
                              only_if_rejected=not compare)
    selection = searched.record
    if not compare and searched.stop in (Stop.ADEQUATE_START, Stop.FIT_FAILED):
        return session_full, None, searched.chosen
    return with_terms(session_full, selection["terms"]), selection, searched.chosen


def _no_trace(session, name):
    names = ", ".join(t.name for t in session.traces) or "none"
    raise UsageError(f"{session.root / 'session.toml'}: --holdout {name!r} names no trace; "
                     f"traces are: {names}")
