"""Why the posterior sampler stopped, in words, from the stopping rule's state at its
last check: the chain's length in autocorrelation times, whether τ has settled, and
whether the draws pass the convergence gates."""

from __future__ import annotations

import numpy as np

from .diagnostics import ESS_MIN, R_HAT_MAX

__all__ = ["TAU_RTOL", "stop_message"]

TAU_RTOL = 0.05  # relative change of τ between checks that counts as settled


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
