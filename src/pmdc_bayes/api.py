"""The Python entry point: :func:`fit` a session in memory, as ``pmdc-bayes fit`` does
(``docs/python-api.md`` has a worked example)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ._errors import SessionError, UsageError
from .inference import StageClock
from .io.bundled import session_path
from .io.loader import load_session
from .io.session import NUISANCES, Session
from .pipeline import (
    SAMPLING_SECONDS,
    FitOptions,
    fit_session,
    model_left_open,
    search_session,
)
from .run import RunResult

__all__ = ["fit"]


def fit(session, *, mcmc: bool = True, add=(), friction: str | None = None, holdout=(),
        seed: int = 0, allow_inadequate: bool = False, progress=None, search=None,
        max_sampling_seconds: float | None = SAMPLING_SECONDS) -> RunResult:
    """Fit a session: the closed form, the MAP, the adequacy checks and (``mcmc``) the
    posterior, all in memory; nothing is written until ``result.write(dir)``.

    Parameters
    ----------
    session : a :class:`Session`, a session directory or a bundled session's name.
    mcmc : sample the posterior (emcee) after the MAP; refused, as on the command line,
        when the data reject the model, unless ``allow_inadequate``.
    add : rig non-idealities to fit on top of those the session declares
        (``"dead_time"``, ``"voltage_drop"``, ``"current_limit"``, ...).
    friction : ``"viscous"`` or ``"coulomb"``; by default the session's.
    holdout : names of traces kept out of the fit.
    progress : the sampler's progress bar; by default in a terminal or a notebook.
    search : run the model search of :mod:`.search` (``fit --compare``) and go on from
        the fit of the model it chooses: True always (from the session's model), False
        never; by default (None) when the session declares no ``[model]``, nothing is
        added and no ``friction`` is given (the search then ends at its start when the
        data do not reject the ideal model).  A search that went past its start, or any
        with True, is recorded in ``summary["model_selection"]``.
    max_sampling_seconds : stop a sampler that has not converged after this long, with
        the reason in ``summary["diagnostics"]`` (its gates then fail); None: no limit.

    Returns the :class:`RunResult`: ``.adequate``, ``.values()``, ``.summary``,
    ``.idata``, ``.to_control(draws=N)``, ``.write(dir)``.  Raises
    :class:`SessionError` for a session that cannot be read and :class:`UsageError`
    for arguments that do not apply to it.
    """
    changed = False
    if isinstance(session, Session):
        changed = not _as_on_disk(session)
    else:
        session = load_session(session_path(session))
    names = tuple(a.replace("-", "_") for a in ([add] if isinstance(add, str) else add))
    unknown = [a for a in names if a not in NUISANCES]
    if unknown:
        raise UsageError(f"add: unknown non-ideality {unknown[0]!r}; choose from "
                         f"{', '.join(NUISANCES)}")
    if names:
        wanted = set(session.nuisances) | set(names)
        session = dataclasses.replace(
            session, nuisances=tuple(n for n in NUISANCES if n in wanted))
        inert = session.inert_nuisance(names)
        if inert is not None:
            raise UsageError(f"add: {inert[0]!r}: {inert[1]}: there is nothing for it to "
                             "fit; leave it out")
    if friction not in (None, "viscous", "coulomb"):
        raise UsageError(f"friction: {friction!r} is not 'viscous' or 'coulomb'")
    held = tuple([holdout] if isinstance(holdout, str) else holdout)
    selection = chosen = None
    clock = StageClock()
    if search or (search is None and model_left_open(session, names, friction)):
        session, selection, chosen = search_session(
            session, holdout=held, friction=friction, seed=seed, say=None,
            compare=bool(search), clock=clock)
    options = FitOptions(mcmc=mcmc, friction=friction, seed=seed, holdout=held,
                         allow_inadequate=allow_inadequate,
                         max_sampling_seconds=max_sampling_seconds)
    result = fit_session(session, options, progress=progress, fitted=chosen, clock=clock)
    if selection is not None:
        result = result.recorded(model_selection=selection)
    if changed:
        result = result.session_recorded(changed_in_memory=True)
    return result


# what the run's summary keeps of the session
_RECORDED = {"nuisances", "loaded_traces", "load_kinds", "shared_dead_time", "friction",
             "coloured_traces"}


def _same(a, b) -> bool:
    if dataclasses.is_dataclass(a) and type(a) is type(b):
        return all(_same(getattr(a, f.name), getattr(b, f.name))
                   for f in dataclasses.fields(a) if f.name not in _RECORDED)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b)


def _as_on_disk(session: Session) -> bool:
    """Whether ``session`` is what its files say (but for what a run records apart:
    the non-idealities, the loaded traces and the friction model)."""
    try:
        return _same(session, load_session(session.root))
    except SessionError:
        return False
