"""The sampler's loop as a rule stepped between chunks of steps, in the shape of
optimistix's solvers: :meth:`StoppingRule.init` gives the first :class:`RuleState`,
:meth:`~StoppingRule.step` the next once the sampler has run a
:meth:`~StoppingRule.chunk` of steps, until :meth:`~StoppingRule.terminate`.  Each
step refits the independence proposals while the chain is young, estimates τ and checks
the gates when their time has come, and decides with :mod:`.stopping`'s pieces whether
to stop.  Nothing but a wall-time limit the caller set depends on the time it took.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from .stopping import (
    CHECK,
    TAU_RTOL,
    Stop,
    burn_in,
    gate_shortfall,
    next_gate_check,
    over_budget,
    steps_needed,
    stop_message,
)

__all__ = ["CHUNK", "PILOT", "RuleState", "StoppingRule"]

CHUNK = 200  # steps between autocorrelation checks while the chain is too short to stop
PILOT = 50  # the first check: whether the independence proposals can take more steps
THINNED_NEAR = 1.3  # a thinned gate check this close to the gates is redone unthinned
ADAPT_UNTIL = 4 * CHUNK  # the independence proposals may be refitted up to here ...
ADAPT_BELOW = 0.3  # ... while fewer than this share of their proposals are accepted,
ADAPT_WIDER = 1.5  # or the chain spreads more than this times their sd in some direction
@dataclass(frozen=True)
class RuleState:
    """Where the stopping rule stands after a chunk of steps.

    Attributes
    ----------
    steps : steps run.
    check_at : the step of the next estimate of τ (and perhaps of the gates).
    adapted : the step of the proposals' last refit: the chain before it is burn-in.
    tau : τ per parameter at the last check since that refit (None before one).
    checked : the step of the last estimate of τ.
    settled : whether τ had settled at the last check that could tell (None before one).
    gate_at, gate : the step of the next check of the gates, and ``(at, burn,
        shortfall)`` of the last (:func:`gate_shortfall`; None before one).
    need : the chain length the rule projected at the last check (:func:`steps_needed`).
    stop : why the run stops, once it does.
    """

    steps: int
    check_at: int
    adapted: int = 0
    tau: np.ndarray | None = None
    checked: int = -1
    settled: bool | None = None
    gate_at: int = 0
    gate: tuple[int, int, float] | None = None
    need: float | None = None
    stop: Stop | None = None


@dataclass(frozen=True)
class StoppingRule:
    """The sampler's stopping rule, stepped as optimistix steps a solver: :meth:`init`,
    then :meth:`step` after each :meth:`chunk` of steps the sampler ran, until
    :meth:`terminate`.

    ``adapting``: the default moves, whose independence proposals are checked early
    (:data:`PILOT`) and refitted on the chain while it is young (:data:`ADAPT_UNTIL`);
    ``k``: the independent ensembles; ``values``: θ to the quantities the gates are
    judged on.  ``max_steps``, ``min_tau_multiple``, ``budget`` and ``max_seconds`` are
    :func:`~.posterior.sample_posterior`'s.
    """

    max_steps: int
    min_tau_multiple: float
    budget: float
    max_seconds: float | None = None
    adapting: bool = True
    k: int = 1
    values: Callable | None = None

    def init(self) -> RuleState:
        return RuleState(steps=0, check_at=PILOT if self.adapting else CHUNK)

    def chunk(self, state: RuleState) -> int:
        """The steps to run before the next :meth:`step`."""
        return min(CHUNK, self.max_steps - state.steps, max(1, state.check_at - state.steps))

    def terminate(self, state: RuleState) -> bool:
        return state.stop is not None

    def step(self, state: RuleState, sampler, n: int, elapsed: float) -> RuleState:
        """The rule's state once ``sampler`` (:class:`~.ensembles.Ensembles`) has run
        ``n`` more steps, ``elapsed`` seconds into the run: the proposals refitted, τ
        estimated, the gates checked, when their time has come."""
        steps = state.steps + n
        timed_out = self.max_seconds is not None and elapsed >= self.max_seconds
        last = steps >= self.max_steps or timed_out
        if steps < state.check_at and not last:
            return replace(state, steps=steps)
        if self.adapting and steps <= ADAPT_UNTIL and not last \
                and sampler.adapt(below=ADAPT_BELOW, wider=ADAPT_WIDER, refit=steps > PILOT):
            return replace(state, steps=steps, adapted=steps, tau=None, gate=None,
                           check_at=steps + CHUNK)
        return self._check(replace(state, steps=steps), sampler, last)

    def _check(self, state: RuleState, sampler, last: bool) -> RuleState:
        steps, adapted = state.steps, state.adapted
        tau = sampler.get_autocorr_time(discard=adapted)
        run = steps - adapted
        long_enough = run >= self.min_tau_multiple * tau.max()
        # τ's estimate costs more as the chain grows: a long chain is checked every 5 %
        check_at = steps + (max(CHECK, run // 20) if long_enough else CHUNK)
        settled, gate, gate_at = state.settled, state.gate, state.gate_at
        if state.tau is not None:
            # τ has settled, or the chain is so long (twice the multiple) that an
            # estimate off by the noise of a short τ cannot make it too short
            settled = bool(np.all(np.abs(tau - state.tau) < TAU_RTOL * tau)) \
                or run >= 2 * self.min_tau_multiple * tau.max()
            if settled and long_enough and steps >= gate_at:
                burn = burn_in(tau, steps, adapted)
                short = self._shortfall(sampler, burn, tau)
                if short <= 1.0:
                    return replace(state, tau=tau, checked=steps, settled=settled,
                                   stop=Stop.CONVERGED)
                gate = (steps, burn, short)
                gate_at = next_gate_check(steps, burn, max(short, 1.0 + 1e-3))
                check_at = max(check_at, gate_at)
        need = steps_needed(steps, adapted, tau, min_tau_multiple=self.min_tau_multiple,
                            gates=gate)
        stop = None
        if over_budget(steps, adapted, tau, need, self.budget):
            stop = Stop.OVER_BUDGET
        elif last:
            stop = Stop.STEP_CAP if steps >= self.max_steps else Stop.TIME_LIMIT
        return replace(state, tau=tau, checked=steps, settled=settled, gate=gate,
                       gate_at=gate_at, check_at=check_at, need=need, stop=stop)

    def _shortfall(self, sampler, burn: int, tau) -> float:
        """:func:`gate_shortfall`, first on every (τ_min/4)-th step (the gates' cost grows
        with the chain), then, near the gates, on every step."""
        thin = max(1, int(tau.min() / 4))
        short = gate_shortfall(sampler, burn, self.k, thin=thin, values=self.values)
        if thin > 1 and short <= THINNED_NEAR:  # near: the exact check decides
            short = gate_shortfall(sampler, burn, self.k, values=self.values)
        return short

    def projected(self, state: RuleState) -> int:
        """The length the rule needs at the current τ and the gates' last check (capped
        at ``max_steps``): a progress bar's total."""
        return int(min(self.max_steps, max(state.steps + CHECK, state.gate_at, state.need)))

    def message(self, state: RuleState, names, elapsed: float) -> str:
        """Why the run stopped, in words (:func:`stop_message`)."""
        timed = {"elapsed": elapsed, "max_seconds": self.max_seconds} \
            if state.stop is Stop.TIME_LIMIT else {}
        budget = {"need": state.need, "max_steps": self.budget} \
            if state.stop is Stop.OVER_BUDGET else {"max_steps": self.max_steps}
        return stop_message(state.steps, state.tau, names,
                            min_tau_multiple=self.min_tau_multiple, settled=state.settled,
                            converged=state.stop is Stop.CONVERGED, adapted=state.adapted,
                            **timed, **budget)
