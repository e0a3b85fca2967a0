"""The posterior sampler's stopping rule: how far the draws are from the convergence
gates and when to look again, and why the sampler stopped, in words, from the rule's
state at its last check (the chain's length in autocorrelation times, whether τ has
settled, whether the draws pass the gates)."""

from __future__ import annotations

import numpy as np

from .diagnostics import ESS_MIN, R_HAT_MAX, az
from .ensembles import r_hat_between

__all__ = ["TAU_RTOL", "CHECK", "gate_shortfall", "next_gate_check", "stop_message"]

TAU_RTOL = 0.05  # relative change of τ between checks that counts as settled
CHECK = 100  # least steps between checks once the chain is long enough


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
                 adapted: int = 0) -> str:
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
    max_steps : the step cap that stopped the run (when no time limit did).
    elapsed, max_seconds : the sampling's wall time and the limit that stopped it.
    adapted : the steps before the proposals' last refit (burn-in the stopping rule does
        not count).
    """
    tau = np.asarray(tau, dtype=float)
    worst, t_max = names[int(np.argmax(tau))], float(tau.max())
    run = steps - adapted
    if converged:
        return (f"converged after {steps} steps: {run / t_max:.0f} × τ_max "
                f"(τ_max {t_max:.1f} steps, {worst})")
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
