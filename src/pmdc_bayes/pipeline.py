"""The ``pmdc-bayes fit`` pipeline: closed form → MAP (→ MCMC) → report, written atomically.

A run directory is built beside its destination under a temporary name and renamed
into place only when complete, so a crash never leaves a half-written run and never
replaces a good one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from . import posterior_stage as _stage
from ._errors import FitFailed, UsageError
from ._x64 import x64
from .candidate import Fitted
from .inference import StageClock, announcing
from .inference.adequacy.verdict import assess
from .inference.fit.joint import fit_map
from .inference.fit.undetermined import identifiability
from .inference.model.contradictions import refuse_contradictions
from .inference.model.objective import build_model
from .inference.model.seed import fit_seed
from .inference.warmup import WarmUp
from .io.loader import load_session
from .io.session import NUISANCES, Session
from .run import RunResult, write_run
from .rundir import check_replaceable, default_out_dir
from .stage_summary import stage_summary

__all__ = ["FitOptions", "fit_session", "run_fit", "search_session", "model_left_open", "write_run"]

SAMPLING_SECONDS = None  # no bound on the sampler's wall time by default: it stops
# by its step budget, so a run's result does not depend on the machine's load
@dataclass(frozen=True)
class FitOptions:
    """What a fit is asked for, as ``pmdc-bayes fit``'s options give it.

    Attributes
    ----------
    mcmc : sample the posterior after the MAP (refused where the data reject the model,
        unless ``allow_inadequate``).
    friction : ``"viscous"`` or ``"coulomb"``; None: the session's.
    seed : seeds the MAP's starts and the sampler.
    holdout : the traces kept out of the fit.
    compare_friction : also fit and sample the other friction model, compared by LOO.
    allow_inadequate : sample a model the data reject (its values stay labelled so).
    max_sampling_seconds : a bound on the sampler's wall time; None: none (it stops by
        its rule or its step budget, the same on any machine).
    add : rig non-idealities to fit on top of those the session declares
        (``io.session.NUISANCES``).
    compare : run the model search from the session's model (:func:`search_session`).
    search : False: never search, even where the model is left to it
        (:func:`model_left_open`).
    pi : ``(kp, ki, delay)`` of a PI speed loop whose stability margins are recorded.
    """

    mcmc: bool = True
    friction: str | None = None
    seed: int = 0
    holdout: tuple[str, ...] = ()
    compare_friction: bool = False
    allow_inadequate: bool = False
    max_sampling_seconds: float | None = SAMPLING_SECONDS
    add: tuple[str, ...] = ()
    compare: bool = False
    search: bool = True
    pi: tuple[float, float, float] | None = None


@x64
def fit_session(session_full: Session, options: FitOptions = FitOptions(), *,
                progress=None, say=None, fitted: Fitted | None = None,
                clock: StageClock | None = None) -> RunResult:
    """Every stage of a fit, in memory: closed form → MAP → adequacy → (MCMC); the
    run's result.  ``say``, when given, is called with a line as each stage starts.
    ``fitted`` (the chosen candidate as the model search leaves it) stands for the
    closed form, MAP and adequacy stages; ``clock``, the :class:`~.inference.StageClock`
    that timed the search, goes on timing.  A posterior stopped by its step budget or
    ``options.max_sampling_seconds`` fails its gates with the reason.

    ``summary`` of the result is what ``summary.json`` holds; nothing is written.  When
    the adequacy checks reject the model the posterior is not sampled (it would only
    describe the misfit) unless ``options.allow_inadequate``.
    """
    say = say or (lambda text: None)
    clock = clock or StageClock()
    session = _held_out(session_full, options.holdout)
    fitted, ident, warm = _map_stages(session, options, fitted, clock, say)
    if not fitted.adequacy.ok and not options.allow_inadequate:
        warm.stop()
    summary = stage_summary(session, fitted, ident, holdout=options.holdout,
                            seed=options.seed)
    post = _posterior_stage(summary, session, fitted, options, warm, clock, say, progress)
    clock.wall["report"] = clock.compile["report"] = 0.0
    clock.total()
    summary["diagnostics"]["wall_s"] = clock.wall
    summary["diagnostics"]["compile_s"] = clock.compile
    model = fitted.model
    draws = None if post is None else post.draws.reshape(-1, len(model.names))
    return RunResult(summary, session, session_full, fitted.seed, model, fitted.fit, draws,
                     None if post is None else post.idata, fitted.adequacy)


def _map_stages(session: Session, options: FitOptions, fitted: Fitted | None,
                clock: StageClock, say) -> tuple[Fitted, dict, WarmUp]:
    """The closed form (or seed), the MAP and the verdict, unless the search's
    ``fitted`` holds them; what the data cannot determine; the later stages' programs
    being made meanwhile."""
    if fitted is not None:  # the model search fitted and checked it (its stage's time)
        warm = WarmUp(fitted.model, mcmc=options.mcmc)
        with clock.stage("identifiability"), warm.stopped_on_error():
            _fit_failed(session, fitted.fit)
            return fitted, identifiability(fitted.model, fitted.fit), warm
    with clock.stage("closed_form"):
        say("closed form (the paper's method), or a seed from the data")
        refuse_contradictions(session)
        cf = fit_seed(session)
    with clock.stage("map"):
        coulomb = None if options.friction is None else options.friction == "coulomb"
        model = build_model(session, cf, coulomb=coulomb)
        say(f"MAP fit of {len(model.names)} parameters")
        warm = WarmUp(model, mcmc=options.mcmc)  # the later stages' programs, meanwhile
        with warm.stopped_on_error():
            fit = fit_map(model, seed=options.seed)
            _fit_failed(session, fit)
            ident = identifiability(model, fit)
    with clock.stage("adequacy"), warm.stopped_on_error():
        say("adequacy checks")
        adequacy = assess(model, fit, cf)
    return Fitted(session, cf, model, fit, adequacy), ident, warm


def _posterior_stage(summary: dict, session: Session, fitted: Fitted, options: FitOptions,
                     warm: WarmUp, clock: StageClock, say, progress):
    """The posterior, where asked for and the verdict allows it, recorded in
    ``summary``; None where not sampled."""
    clock.wall["mcmc"] = clock.compile["mcmc"] = 0.0
    if not options.mcmc:
        return None
    if not fitted.adequacy.ok and not options.allow_inadequate:
        summary["diagnostics"]["sampler_message"] = (
            "not sampled: the data reject the model (pass --allow-inadequate to sample it)")
        return None
    model, params = fitted.model, summary["parameters"]
    with clock.stage("mcmc"), warm.stopped_on_error():
        say("sampling the posterior (emcee)")
        post, stats = _stage.posterior_stage(model, fitted.fit, seed=options.seed,
                                             progress=progress,
                                             max_seconds=options.max_sampling_seconds)
        for name in model.names:
            params[name].update(stats["summary"][name])
        summary["derived"] = stats["derived"]
        summary["laplace_check"] = stats["laplace_check"]
        summary["diagnostics"].update(stats["diagnostics"])
        if options.compare_friction:
            summary["model_comparison"] = _stage.compare_friction(
                session, fitted.seed, model, post, seed=options.seed,
                progress=progress, max_seconds=options.max_sampling_seconds)
    return post


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


def run_fit(session_path, options: FitOptions = FitOptions(), *, out: Path | None = None,
            force: bool = False, say=None, progress=None) -> tuple[Path, dict]:
    """Fit a session directory as ``options`` ask and write the run directory ``out``:
    ``summary.json``, ``posterior.nc`` (with MCMC) and the report, all built beside
    ``out`` and moved into place in one rename once complete.

    Returns the run directory and the summary.  Raises :class:`UsageError` for an
    existing ``out`` without ``force``.  ``options.compare`` first runs the model search
    of :mod:`.search` from the session's model and goes on from the fit of the model it
    chose, recording the search under ``"model_selection"`` and writing the chosen model
    into the run's copy of ``session.toml``; without it the search runs when the model
    is left to it (:func:`model_left_open`), and is recorded only when the data reject
    the ideal model (``options.search=False``: never).  ``options.pi`` records the
    stability margins of that PI speed loop under ``"pi_loop"``.
    """
    say = say or (lambda text: None)
    say(f"loading {session_path}")
    session_full = load_session(session_path)
    if options.add:
        wanted = set(session_full.nuisances) | set(options.add)
        session_full = dataclasses.replace(
            session_full, nuisances=tuple(n for n in NUISANCES if n in wanted))
        _refuse_inert(session_full, options.add)
    out = Path(out) if out is not None else default_out_dir(session_full.name)
    check_replaceable(out, force)
    from .report import start_drawing

    start_drawing()  # the processes that draw the report: they import matplotlib meanwhile
    selection = chosen = None
    clock = StageClock()
    if options.compare or (options.search
                           and model_left_open(session_full, options.add, options.friction)):
        session_full, selection, chosen = search_session(
            session_full, holdout=options.holdout, friction=options.friction,
            seed=options.seed, say=say, compare=options.compare, clock=clock)
    with announcing(say):
        result = fit_session(session_full, options, progress=progress, say=say,
                             fitted=chosen, clock=clock)
    if selection is not None:
        result = result.recorded(model_selection=selection)
    if options.pi is not None:
        result = result.recorded(pi_loop=result.pi_loop(*options.pi))
    say(f"writing {out} (summary, posterior, report)")
    return out, write_run(result, out, force=force).summary


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
