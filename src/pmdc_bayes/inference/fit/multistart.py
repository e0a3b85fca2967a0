"""Several starts of the MAP fit moved side by side from the host, each by optimistix's
Levenberg–Marquardt (:mod:`.optimiser`), and how each ended.

A round steps every running start once (one evaluation of the objective), the starts
of a round side by side in threads (one per core; the compiled step runs outside
Python's lock).  Each start ends with a typed :class:`Outcome` (as optimistix's
``RESULTS``): converged, on a slow curved ridge within the posterior's resolution,
stalled, abandoned, not finite, at its step limit, or stopped by the solver; the best
start, the MAP's candidate, is given a larger limit while it still improves, and one
that ends at it says so rather than passing for an optimum.  A round's starts depend
only on their own state and the round before, never on which thread finishes first.
"""

from __future__ import annotations

import enum
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ..._cores import usable_cores
from ..._x64 import x64
from .optimiser import Step, Stepper

__all__ = ["maximise", "Start", "Outcome", "MAX_STEPS", "BEST_MAX_STEPS", "WINDOW"]

MAX_STEPS = 200        # steps a start may take ...
BEST_MAX_STEPS = 2000  # ... and the best start, while it still improves
DECREMENT_TOL = 1e-8   # converged: ½·gᵀH⁻¹g below this (log-posterior units)
STALL_TOL = 1e-4       # ... or no step can improve while ½·gᵀH⁻¹g is below this
REJECTIONS = 40        # steps in a row rejected: the trust region has shrunk 4⁴⁰-fold
RESOLUTION = 0.05      # per parameter: a gap in log-posterior too small to matter
WINDOW = 20            # steps over which a crawl's progress is measured


class Outcome(enum.Enum):
    """How a start ended, in words."""

    RUNNING = ""
    CONVERGED = "converged"
    RESOLVED = "converged to within the posterior's resolution (a slow, curved ridge)"
    STALLED = "no step improves the log-posterior"
    MAX_STEPS = "step limit"
    ABANDONED = "far below the best"
    NONFINITE = "the model is not finite at the start"
    SOLVER = "the solver stopped with an error"

    @property
    def converged(self) -> bool:
        return self in (Outcome.CONVERGED, Outcome.RESOLVED)


@dataclass
class Start:
    """One start's progress: optimistix's ``step`` where it is (the :class:`Terms` at
    its last accepted point), its steps (every evaluation counts), its step ``limit``
    and how it ended (``outcome``, with the solver's own words in ``detail`` when it
    stopped with an error); ``accepted_at`` the step of its last accepted step,
    ``history`` the log-posterior after each."""

    at: Step
    steps: int = 0
    limit: int = MAX_STEPS
    outcome: Outcome = Outcome.RUNNING
    accepted_at: int = 0
    history: list = field(default_factory=list)
    detail: str = ""

    terms = property(lambda self: self.at.terms)
    theta = property(lambda self: self.at.terms.theta)
    lp = property(lambda self: self.at.terms.lp)
    done = property(lambda self: self.outcome is not Outcome.RUNNING)
    converged = property(lambda self: self.outcome.converged)
    improving = property(lambda self: bool(self.history) and self.steps - self.accepted_at
                         < WINDOW, doc="whether it accepted a step in its last WINDOW steps")

    @property
    def stopped(self) -> str:
        """How it ended, in words."""
        return f"{self.outcome.value}: {self.detail}" if self.detail else self.outcome.value


def _resolved(s: Start, gain: float) -> bool:
    """Whether ``s`` crawls along a curved ridge close enough to its top to stop: its last
    :data:`WINDOW` accepted steps gained, and a full Newton step would still gain
    (``gain``), less than :data:`RESOLUTION` log-posterior units per parameter.  The
    posterior's typical draws lie about P/2 units below its mode, so such a gap does not
    move the Laplace approximation or the sampler's start in any way that matters."""
    tol = RESOLUTION * s.theta.size
    h = s.history
    return len(h) > WINDOW and h[-1] - h[-1 - WINDOW] < tol and gain < tol


def _advance(s: Start, stepper: Stepper) -> None:
    """One step of ``s`` (one evaluation), or its end: converged, on a crawl within the
    resolution, stalled, at its step limit or stopped by the solver."""
    gain = s.at.decrement
    if gain < DECREMENT_TOL:
        s.outcome = Outcome.CONVERGED
        return
    if _resolved(s, gain):
        s.outcome = Outcome.RESOLVED
        return
    if s.steps >= s.limit:
        s.outcome = Outcome.MAX_STEPS
        return
    before = s.at
    s.at = stepper.step(before)
    s.steps += 1
    if not np.array_equal(s.at.y, before.y):
        s.history.append(s.lp)
        s.accepted_at = s.steps
    if s.at.result:
        s.outcome, s.detail = Outcome.SOLVER, s.at.result
    elif s.at.terminated or s.steps - s.accepted_at >= REJECTIONS:
        s.outcome = Outcome.CONVERGED if s.at.decrement < STALL_TOL else Outcome.STALLED


def maximise(stepper: Stepper, starts, *, abandon=None, max_steps: int = MAX_STEPS,
             best_max_steps: int = BEST_MAX_STEPS) -> list[Start]:
    """Maximise the objective of ``stepper`` from each of ``starts`` (θ rows), a step of
    each per round.

    ``abandon(start, best_lp)``, checked after each round, stops a start that is not
    worth finishing (a poor local optimum far below the best); it is then not
    ``converged``.  A start ends at ``max_steps`` steps, except the best one (the MAP's
    candidate) while it still improves (:attr:`Start.improving`): its limit doubles, up
    to ``best_max_steps``; one that ends at its limit has the outcome
    :attr:`Outcome.MAX_STEPS`.
    """

    def begin(theta) -> Start:
        first = stepper.start(theta)
        if not first.terms.finite:
            return Start(first, outcome=Outcome.NONFINITE)
        return Start(first, limit=max_steps)

    with ThreadPoolExecutor(min(len(starts), usable_cores()) or 1) as pool:
        states = list(pool.map(x64(begin), starts))
        while True:
            lps = [s.lp for s in states if np.isfinite(s.lp)]
            best = max(lps) if lps else -np.inf
            for s in states:  # the MAP's candidate goes on while it still improves
                if s.outcome is Outcome.MAX_STEPS and s.lp == best and s.improving \
                        and s.limit < best_max_steps:
                    s.limit, s.outcome = min(2 * s.limit, best_max_steps), Outcome.RUNNING
            active = [s for s in states if not s.done]
            if not active:
                return states
            for _ in pool.map(x64(lambda s: _advance(s, stepper)), active):
                pass
            if abandon is not None:
                lps = [s.lp for s in states if np.isfinite(s.lp)]
                best = max(lps) if lps else -np.inf
                for s in states:
                    if not s.done and abandon(s, best):
                        s.outcome = Outcome.ABANDONED
