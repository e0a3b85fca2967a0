"""The posterior sampler's stopping rule: how far the draws are from the convergence
gates and when to look again, how many steps the rule projects the chain to need and
whether that is beyond the step budget, and why the sampler stopped, in words, from the
rule's state at its last check (the chain's length in autocorrelation times, whether τ
has settled, whether the draws pass the gates).

Every decision here is a function of the chain alone, never of the time it took: the
same seed gives the same stop on a busy machine as on an idle one.  Only a wall-time
limit the caller asks for (``max_seconds``) depends on the machine.
"""

from __future__ import annotations

import enum
import math

import numpy as np

from .arviz_import import az
from .diagnostics import ESS_MIN, R_HAT_MAX
from .ensembles import r_hat_between

__all__ = ["TAU_RTOL", "CHECK", "TRUST_TAU", "Stop", "burn_in", "gate_shortfall",
           "next_gate_check", "steps_needed", "over_budget", "stop_message"]

TAU_RTOL = 0.05  # relative change of τ between checks that counts as settled
CHECK = 100  # least steps between checks once the chain is long enough
TRUST_TAU = 10  # a τ estimated on a chain this many τ_max long is trusted to project


class Stop(enum.Enum):
    """Why the sampler stopped."""

    CONVERGED = "the stopping rule was met"
    OVER_BUDGET = "the rule projects more steps than the step budget"
    STEP_CAP = "the step budget was used up"
    TIME_LIMIT = "the wall-time limit the caller set was reached"


def burn_in(tau, steps: int, adapted: int) -> int:
    """Steps discarded: those before the proposals' last refit, and 2 τ_max after it
    (at most half of what follows)."""
    return adapted + min(math.ceil(2.0 * float(np.max(tau))), (steps - adapted) // 2)


def steps_needed(steps: int, adapted: int, tau, *, min_tau_multiple: float,
                 gates: tuple[int, int, float] | None = None) -> float:
    """The chain length (steps, the burn-in included) the stopping rule projects from
    the chain's state: ``min_tau_multiple`` × τ_max after the proposals' last refit at
    step ``adapted``, and, from the gates' last check ``gates = (at, burn, shortfall)``
    (:func:`gate_shortfall` of the draws after ``burn`` at step ``at``), the length at
    which they would pass (the draws after burn-in grown ``shortfall`` times)."""
    need = adapted + min_tau_multiple * float(np.max(tau))
    if gates is not None:
        at, burn, short = gates
        need = max(need, burn + short * (at - burn))
    return need


def over_budget(steps: int, adapted: int, tau, need: float, max_steps: int) -> bool:
    """Whether to give up now: the projected length ``need`` (:func:`steps_needed`)
    exceeds the step budget ``max_steps``, by a τ the chain can vouch for (the chain
    since the last refit is at least :data:`TRUST_TAU` × τ_max long, where an estimate
    of τ errs low rather than high, so a projection beyond the budget is no accident of
    a short chain)."""
    t_max = float(np.max(tau))
    return need > max_steps and steps - adapted >= TRUST_TAU * t_max


def gate_shortfall(sampler, burn: int, k: int = 1, *, thin: int = 1, values=None,
                    r_hat_max: float = R_HAT_MAX, ess_min: float = ESS_MIN) -> float:
    """How many times longer the chain after ``burn`` must grow for the convergence gates
    to pass (≤ 1: they pass now), from its every ``thin``-th step: over the walkers as
    chains, and across the ``k`` independent ensembles.  ``values`` maps θ to the
    quantities the gates are judged on (the SI values of the summary: R-hat's folded
    part is not invariant under the log transform).

    An ESS grows in proportion to the chain's length; so does ``m/(R̂² − 1)``, the
    effective sample size that an R-hat over ``m`` chains reflects (Vats & Knudson 2021),
    which is how a short R-hat is turned into a length.  A thinned check is cheaper and
    noisier: the sampler uses it to schedule, and decides on the whole chain.
    """
    chain = np.swapaxes(sampler.get_chain(discard=burn, thin=thin), 0, 1)
    if values is not None:
        chain = values(chain)
    data = {f"p{i}": chain[..., i] for i in range(chain.shape[-1])}
    rhat = az.rhat(data)
    r_hat = [float(rhat[v]) for v in data]
    r_hat += list((r_hat_between(chain, k, list(data)) or {}).values())
    ess = []
    for method in ("bulk", "tail"):
        e = az.ess(data, method=method)
        ess += [float(e[v]) for v in data]
    short = [ess_min / max(e, 1e-12) for e in ess]
    short += [(r * r - 1.0) / (r_hat_max**2 - 1.0) if np.isfinite(r) else np.inf for r in r_hat]
    return float(max(short))


def next_gate_check(steps: int, burn: int, shortfall: float) -> int:
    """The step at which a failed gate check is worth repeating: nine tenths of the way to
    the length it predicts, at least :data:`CHECK` steps or a twentieth of the steps run so
    far, and at most a quarter of them, away."""
    wait = 0.9 * (shortfall - 1.0) * (steps - burn) if np.isfinite(shortfall) else np.inf
    return steps + int(np.clip(wait, max(CHECK, steps // 20), max(CHECK, steps // 4)))


def stop_message(steps: int, tau, names, *, min_tau_multiple: float, settled: bool | None,
                 converged: bool = False, max_steps: int | None = None,
                 elapsed: float | None = None, max_seconds: float | None = None,
                 adapted: int = 0, need: float | None = None) -> str:
    """The sampler's status line.

    Parameters
    ----------
    steps : steps run.
    tau : integrated autocorrelation time of each parameter (steps), at the last check.
    names : the parameters' names, in the order of ``tau``.
    min_tau_multiple : the chain length, in τ_max, the stopping rule asks for.
    settled : every τ changed by less than :data:`TAU_RTOL` since the check before (or
        the chain is twice ``min_tau_multiple`` τ_max long);
        None when τ was estimated only once.
    converged : the stopping rule was met.
    max_steps : the step budget that stopped the run (when no time limit did).
    elapsed, max_seconds : the sampling's wall time and the limit that stopped it.
    adapted : the steps before the proposals' last refit (burn-in the stopping rule does
        not count).
    need : the steps the rule projected (:func:`steps_needed`) when the run gave up
        because they exceed ``max_steps`` (:func:`over_budget`).
    """
    tau = np.asarray(tau, dtype=float)
    worst, t_max = names[int(np.argmax(tau))], float(tau.max())
    run = steps - adapted
    if converged:
        return (f"converged after {steps} steps: {run / t_max:.0f} × τ_max "
                f"(τ_max {t_max:.1f} steps, {worst})")
    if need is not None:
        by_tau = need <= adapted + min_tau_multiple * t_max + 0.5
        why = (f"{min_tau_multiple:g} × τ_max (slowest parameter {worst}, τ ≈ {t_max:.0f} "
               "steps)"
               if by_tau else f"for the draws after burn-in to reach the gates (R-hat ≤ "
               f"{R_HAT_MAX:g}, bulk and tail ESS ≥ {ESS_MIN:g}; slowest parameter {worst}, "
               f"τ ≈ {t_max:.0f} steps)")
        return (f"gave up after {steps} steps: the chain would need about "
                f"{math.ceil(need)} steps, {why}, more than the step budget "
                f"({max_steps:g} steps): the posterior may be far from Gaussian, "
                "multimodal or poorly identified by the data")
    timed = max_seconds is not None
    head = (f"stopped after {elapsed:.0f} s of sampling (the limit, {max_seconds:g} s; "
            f"{steps} steps)" if timed else f"stopped at max_steps={max_steps}")
    need = min_tau_multiple * t_max
    if run < need:
        when = f", ~{(need + adapted) / steps * elapsed:.0f} s here," if timed else ""
        text = (f"{head} before the chain was {min_tau_multiple:g} × τ_max long with τ "
                f"settled; slowest parameter {worst} (τ ≈ {t_max:.0f} steps, so about "
                f"{need + adapted:.0f} steps{when} would be needed): "
                + ("its posterior may be far from Gaussian or poorly identified by the data"
                   if timed else "it may be poorly identified by the data"))
    elif not settled:
        how = (f"still changing by more than {TAU_RTOL * 100:g} % between checks" if settled
               is False else f"estimated only once, not yet seen to settle (within "
               f"{TAU_RTOL * 100:g} % between checks)")
        text = (f"{head}, the chain {run / t_max:.0f} × τ_max long but τ {how} (slowest "
                f"parameter {worst}, τ ≈ {t_max:.0f} steps): its estimate is not yet to be "
                "trusted")
    else:
        text = (f"{head}, the chain {run / t_max:.0f} × τ_max long with τ settled "
                f"(slowest parameter {worst}, τ ≈ {t_max:.0f} steps), but the draws after "
                f"burn-in not yet at the gates (R-hat ≤ {R_HAT_MAX:g}, bulk and tail ESS ≥ "
                f"{ESS_MIN:g})")
    return text + ("; raise the limit (--max-sampling-seconds) to wait for it" if timed else "")
