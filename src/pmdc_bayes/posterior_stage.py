"""The run's posterior stage: the sampler, its summary and gates, the derived quantities,
and the friction models compared by LOO."""

from __future__ import annotations

import numpy as np

from .inference.fit.joint import fit_map
from .inference.model.objective import build_model

__all__ = ["posterior_stage", "compare_friction", "reference_voltage"]


def reference_voltage(session) -> float:
    """The voltage at which derived no-load figures are stated: the highest the session
    applies (step, operating point or table)."""
    volts = [float(np.max(tr.voltage.values)) for tr in session.traces]
    volts += [op.voltage for op in session.operating_points]
    volts += [float(np.max(t.voltage)) for t in session.steady_tables]
    volts += [sr.voltage for sr in session.step_readings]
    return max(volts) if volts else 12.0


def posterior_stage(model, fit, *, seed, progress, max_seconds=None):
    from .inference.sampling.derived import derived_quantities
    from .inference.sampling.diagnostics import widest_direction
    from .inference.sampling.posterior import compare_laplace, gates, sample_posterior, summarize

    post = sample_posterior(model, fit, seed=seed, progress=progress, max_seconds=max_seconds)
    summ = summarize(post)
    passed, failures = gates(summ, posterior=post)
    voltage = reference_voltage(model.session)
    stats = {
        "summary": summ,
        "derived": {"voltage": voltage,
                    "quantities": derived_quantities(post.draws_si(), voltage=voltage)},
        "laplace_check": compare_laplace(fit, summ),
        "diagnostics": {
            "gates_passed": bool(passed), "failures": failures,
            "autocorrelation_time": {k: float(v) for k, v in post.tau.items()},
            "acceptance_fraction": float(np.mean(post.acceptance)),
            "n_walkers": int(post.draws.shape[0]), "n_steps": int(post.n_steps),
            "burn_in": int(post.burn_in), "capped": bool(post.capped),
            "sampler_message": post.message,
            "coordinates": post.idata.posterior.attrs.get("coordinates", "theta"),
            "sampled_in_value": [n for n in post.idata.posterior.attrs.get(
                "sampled_in_value", "").split(",") if n],
            "widest_direction": widest_direction(fit, post.draws_log),
        },
    }
    return post, stats


def compare_friction(session, cf, model, post, *, seed, progress, max_seconds=None):
    """LOO of the viscous and viscous + Coulomb models on the same session."""
    from .inference.sampling.posterior import loo_compare, sample_posterior

    other = build_model(session, cf, coulomb=not model.coulomb)
    other_post = sample_posterior(other, fit_map(other, seed=seed), seed=seed,
                                  progress=progress, max_seconds=max_seconds)
    by_name = {("coulomb" if model.coulomb else "viscous"): post.idata,
               ("coulomb" if other.coulomb else "viscous"): other_post.idata}
    return loo_compare(by_name)
