"""The Python entry point: :func:`fit` a session in memory, as ``pmdc-bayes fit`` does
(``docs/python-api.md`` has a worked example)."""

from __future__ import annotations

import dataclasses

from ._errors import UsageError
from .inference.result import RunResult
from .io.bundled import session_path
from .io.loader import load_session
from .io.session import NUISANCES, Session
from .pipeline import fit_session

__all__ = ["fit"]


def fit(session, *, mcmc: bool = True, add=(), friction: str | None = None, holdout=(),
        seed: int = 0, allow_inadequate: bool = False, progress=None) -> RunResult:
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

    Returns the :class:`RunResult`: ``.adequate``, ``.values()``, ``.summary``,
    ``.idata``, ``.to_control(draws=N)``, ``.write(dir)``.  Raises
    :class:`SessionError` for a session that cannot be read and :class:`UsageError`
    for arguments that do not apply to it.
    """
    if not isinstance(session, Session):
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
    if friction not in (None, "viscous", "coulomb"):
        raise UsageError(f"friction: {friction!r} is not 'viscous' or 'coulomb'")
    return fit_session(session, mcmc=mcmc, friction=friction, seed=seed,
                       holdout=tuple([holdout] if isinstance(holdout, str) else holdout),
                       progress=progress, allow_inadequate=allow_inadequate)
