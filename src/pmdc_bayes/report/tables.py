"""The report's tables, as :class:`~._doc.Table` records (cells already formatted)."""

from __future__ import annotations

import numpy as np

from .._format import off_by, row_format
from .._headline import spread_text
from ..inference.sampling.derived import LABELS as DERIVED_LABELS
from ..inference.sampling.derived import derived_draws
from ..io.units import SI_UNIT, display_unit
from ..physics.motor import gain, tf_full, time_constant
from ._doc import Table, fmt
from .predictive import METHODS

__all__ = ["parameter_table", "derived_table", "diagnostics_table", "rms_table",
           "transfer_table", "comparison_table", "holdout_table", "laplace_sd", "TABLE_TITLES"]

TABLE_TITLES = {
    "parameters": "Parameters",
    "derived": "Derived quantities",
    "diagnostics": "Diagnostics and gates",
    "rms": "Per-trace RMS error",
    "transfer": "Transfer functions",
    "comparison": "Closed form against the fit",
    "holdout": "Hold-out validation",
}


_MOTOR = ("Ra", "La", "K", "B", "J", "Tc")  # named as in the paper; the rig's are explained


def parameter_table(ctx) -> Table:
    post = ctx.has_posterior
    header = ["parameter", "unit", "closed form", "MAP ± sd"]
    if post:
        header += ["posterior mean ± sd", "94 % HDI", "R-hat", "bulk ESS"]
    if ctx.truth:
        header.append("truth")
    rows = []
    for n in ctx.names:
        r = ctx.summary["parameters"][n]
        sds = [x for x in (r.get("map_sd"), r.get("sd")) if x is not None and x > 0]
        f = row_format(r["mean"] if post else r["map"], min(sds) if sds else None)
        cells = [n, f.suffix + display_unit(r["unit"]),
                 f.value(r["closed_form"]) if r["closed_form"] is not None else "— (none)",
                 f"{f.value(r['map'])} ± {f.sd(r['map_sd'])}"]
        if post:
            cells += [f"{f.value(r.get('mean'))} ± {f.sd(r.get('sd'))}",
                      f"[{f.value(r.get('hdi_3%'))}, {f.value(r.get('hdi_97%'))}]",
                      fmt(r.get("r_hat"), 4), f"{r.get('ess_bulk', float('nan')):.0f}"]
        if ctx.truth:
            cells.append(f.value(ctx.truth.get(n)) if ctx.truth.get(n) is not None else "—")
        rows.append(tuple(cells))
    note = ("Each row is rounded to its uncertainty (two significant digits of the sd) "
            "and written on one scale, given before the unit. MAP sd: Laplace "
            "approximation at the MAP. "
            + ("Posterior: emcee, two independent ensembles; R-hat is ArviZ's "
               "rank-normalised split R-hat with walkers as chains, and the gates also ask "
               "it of the ensembles, each one's walkers pooled (summary.json: "
               "r_hat_ensembles)." if post else "No posterior was sampled (--no-mcmc)."))
    rig = [f"{n}: {ctx.model.registry[n].description}" for n in ctx.names
           if n not in _MOTOR and ctx.model.registry[n].description]
    if rig:
        note += " The rig's parameters (named as in summary.json): " + "; ".join(rig) + "."
    return Table(TABLE_TITLES["parameters"], tuple(header), tuple(rows), note)


def laplace_sd(ctx, quantities) -> dict:
    """The sd of each quantity of the parameters under the Laplace approximation at
    the MAP, linearised: ``sqrt(g·Σ·g)`` with ``g`` the quantity's gradient (central
    differences) and ``Σ`` the parameters' covariance.  ``quantities`` maps a dict of
    SI arrays (one entry per parameter) to ``{name: array}``."""
    names, v0 = list(ctx.names), ctx.values["map"]
    steps = np.array([1e-6 * abs(v0[n]) or 1e-12 for n in names])
    cols = {n: np.full(2 * len(names), v0[n], dtype=float) for n in names}
    for k, n in enumerate(names):
        cols[n][2 * k] += steps[k]
        cols[n][2 * k + 1] -= steps[k]
    cov = ctx.covariance()
    out = {}
    for q, x in quantities(cols).items():
        g = (np.asarray(x)[0::2] - np.asarray(x)[1::2]) / (2.0 * steps)
        out[q] = float(np.sqrt(max(g @ cov @ g, 0.0)))
    return out


def _derived(values: dict, voltage: float) -> dict:
    return {q: x for q, (_, x) in derived_draws(values, voltage=voltage).items()}


def derived_table(ctx) -> Table:
    """Time constants, gain, no-load and stall quantities: each row rounded to the
    quantity's posterior sd (the Laplace sd at the MAP without a posterior)."""
    d = ctx.summary.get("derived") or {}
    voltage = d.get("voltage") or ctx.summary.get("derived_voltage") or 12.0
    q = d.get("quantities", {})
    single = {k: derived_draws({n: np.array([v]) for n, v in ctx.values[m].items()},
                               voltage=voltage) for k, m in (("cf", "closed_form"), ("map", "map"))}
    laplace = {} if q else laplace_sd(ctx, lambda v: _derived(v, voltage))
    rows = []
    for name, (unit, x_map) in single["map"].items():
        r = q.get(name, {})
        est = r.get("mean", float(x_map[0]))
        sd = r.get("sd") if r else laplace.get(name)
        f = row_format(est, sd)
        cells = [DERIVED_LABELS.get(name, name), f"{f.suffix}{display_unit(unit)}".strip(),
                 f.value(float(single["cf"][name][1][0]))]
        if r:
            cells += [f.value(float(x_map[0])), f"{f.value(r['mean'])} ± {f.sd(r['sd'])}",
                      f.interval(r.get("hdi_3%"), r.get("hdi_97%"))]
        else:
            cells.append(f"{f.value(float(x_map[0]))} ± {f.sd(sd)}")
        rows.append(tuple(cells))
    header = ("quantity", "unit", "closed form",
              *(("MAP", "posterior mean ± sd", "94 % HDI") if q else ("MAP ± sd (Laplace)",)))
    note = (f"No-load and stall quantities at {voltage:.4g} V. Each row is rounded to its "
            "uncertainty and written on one scale, given before the unit. "
            + ("Posterior columns are computed draw by draw, so they carry the correlations "
               "of the parameters." if q else "No posterior was sampled (--no-mcmc): the sd "
               "is the Laplace approximation's, propagated linearly."))
    return Table(TABLE_TITLES["derived"], header, tuple(rows), note)


# The stages of a run (keys of summary.json's diagnostics.wall_s), as people name them.
_STAGES = {"model_search": "model search", "closed_form": "closed form", "map": "MAP",
           "mcmc": "MCMC"}


def diagnostics_table(ctx) -> Table:
    s = ctx.summary
    diag = s.get("diagnostics", {})
    fit = s["fit"]
    agree = sum(1 for st in fit.get("starts", []) if st.get("agrees"))
    rows = [("MAP fit", fit["status"], fit["message"]),
            ("multi-start", f"{agree} of {len(fit.get('starts', []))} agree", "")]
    gp = diag.get("gates_passed")
    rows.append(("posterior gates", {True: "passed", False: "FAILED", None: "not run"}[gp],
                 "; ".join(diag.get("failures", [])) or ("R-hat ≤ 1.01, bulk and tail ESS ≥ 400"
                                                         if gp is not None else "--no-mcmc")))
    if "sampler_message" in diag and "n_walkers" not in diag:
        rows.append(("sampler", "not run", diag["sampler_message"]))
    elif "sampler_message" in diag:
        rows.append(("sampler", f"{diag['n_walkers']} walkers, {diag['n_steps']} steps, "
                     f"burn-in {diag['burn_in']}", diag["sampler_message"]))
        rows.append(("acceptance fraction", fmt(diag.get("acceptance_fraction"), 3), ""))
        tau = diag.get("autocorrelation_time", {})
        rows.append(("autocorrelation time (steps)",
                     ", ".join(f"{k} {v:.1f}" for k, v in tau.items()), ""))
    for r in s.get("laplace_check", []):
        rows.append((f"Laplace check {r['name']}", f"posterior/Laplace sd {r['ratio']:.3f}",
                     r["note"] or "agrees within 20 %"))
    wide = diag.get("widest_direction")
    if wide:
        rows.append(("Laplace check, jointly",
                     f"posterior/Laplace sd {wide['ratio']:.3f} along "
                     + ", ".join(wide["parameters"]),
                     spread_text(diag) or "agrees within a factor of 2"))
    wall = diag.get("wall_s", {})
    if wall:
        rows.append(("wall time (s)", ", ".join(f"{_STAGES.get(k, k.replace('_', ' '))} "
                                                f"{v:.1f}" for k, v in wall.items()), ""))
    return Table(TABLE_TITLES["diagnostics"], ("check", "result", "detail"), tuple(rows))


_KIND = {"speed": "speed", "current": "current", "position": "angle"}  # channel -> unit kind


def rms_table(preds, *, title=TABLE_TITLES["rms"], note="") -> Table:
    methods = [m for m in METHODS if preds and m in preds[0].sims]
    rows = []
    for tp in preds:
        for c in tp.channels:
            unit = display_unit(SI_UNIT[_KIND[c]])
            cells = [tp.trace.name, f"{c} ({unit})", fmt(tp.noise[c], 3)]
            cells += [fmt(tp.rms[m][c], 4) for m in methods]
            cells.append(f"{100 * tp.coverage[c]:.0f} %" if tp.coverage else "—")
            rows.append(tuple(cells))
    header = ("trace", "channel", "noise sd", *(f"RMS {METHODS[m]}" for m in methods),
              "inside 94 % band")
    return Table(title, header, tuple(rows), note)


def holdout_table(ctx) -> Table:
    note = ("Traces left out of the fit (--holdout), predicted by each parameter set. "
            "The posterior predictive is its mean over posterior draws; its 94 % band adds "
            "the noise level estimated from the held-out trace itself.")
    if not ctx.has_posterior:
        note += " No posterior was sampled (--no-mcmc), so the posterior predictive is absent."
    return rms_table(ctx.holdout, title=TABLE_TITLES["holdout"], note=note)


# The coefficients of (7), (8) and (22): label and SI unit (io.units' display table).
_TF = (("(7) numerator K", "V*s/rad"), ("(7) s² coefficient La·J", "H*kg*m^2"),
       ("(7) s coefficient La·B + Ra·J", "ohm*kg*m^2"),
       ("(7) constant Ra·B + K²", "(V*s/rad)^2"), ("(8) gain G", "rad/s/V"),
       ("(8) time constant τ", "s"), ("(22) numerator K/J", "rad/s^2/A"),
       ("(22) s² coefficient La", "H"), ("(22) s coefficient (La·B + Ra·J)/J", "ohm"),
       ("(22) constant (Ra·B + K²)/J", "ohm/s"))


def _tf_coefficients(d: dict) -> dict:
    """The coefficients of :data:`_TF` from parameter values or arrays of them (SI)."""
    num, den = tf_full(d["Ra"], d["La"], d["K"], d["B"], d["J"])
    values = (num[0], den[0], den[1], den[2], gain(d["Ra"], d["K"], d["B"]),
              time_constant(d["Ra"], d["K"], d["B"], d["J"]), num[0] / d["J"],
              den[0] / d["J"], den[1] / d["J"], den[2] / d["J"])
    return {label: np.asarray(v, dtype=float) for (label, _), v in zip(_TF, values, strict=True)}


def transfer_table(ctx) -> Table:
    """The transfer functions' coefficients, each row rounded to the coefficient's
    posterior sd (the Laplace sd at the MAP without a posterior)."""
    cf, mp = _tf_coefficients(ctx.values["closed_form"]), _tf_coefficients(ctx.values["map"])
    draws = None
    if ctx.draws is not None:
        draws = _tf_coefficients({n: ctx.draws[:, k] for k, n in enumerate(ctx.names)})
    laplace = {} if draws else laplace_sd(ctx, _tf_coefficients)
    rows = []
    for label, unit in _TF:
        if draws:
            mean, sd = float(np.mean(draws[label])), float(np.std(draws[label], ddof=1))
        else:
            mean, sd = float(mp[label]), laplace[label]
        f = row_format(mean, sd)
        cells = [label, f"{f.suffix}{display_unit(unit)}".strip(), f.value(float(cf[label]))]
        cells += ([f.value(float(mp[label])), f"{f.value(mean)} ± {f.sd(sd)}"] if draws
                  else [f"{f.value(mean)} ± {f.sd(sd)}"])
        rows.append(tuple(cells))
    note = ("ω(s)/Va(s) = K / ((La·s + Ra)(J·s + B) + K²) (7); G/(τ·s + 1) with La neglected "
            "(8); (22) is (7) with numerator and denominator divided by J. Each row is "
            "rounded to its uncertainty, on one scale given before the unit. "
            + ("Posterior columns: mean ± sd of each coefficient over the draws" if draws else
               "No posterior was sampled (--no-mcmc): the sd is the Laplace approximation's, "
               "propagated linearly")
            + "; with Coulomb friction the transfer functions describe the motion about a "
            "running operating point (Tc is a constant disturbance torque).")
    header = ("coefficient", "unit", "closed form",
              *(("MAP", "posterior mean ± sd") if draws else ("MAP ± sd (Laplace)",)))
    return Table(TABLE_TITLES["transfer"], header, tuple(rows), note)


def _distance(r: dict) -> tuple[str, str]:
    """(distance in sd, relative difference in %) of a comparison row, as the headline
    writes them (0 below a hundredth of an sd)."""
    parts = off_by(r["closed_form"], r["reference"], r["sd"])
    return ("—", "—") if parts is None else (parts[1], f"{parts[0]} %")


def comparison_table(ctx, rows) -> Table:
    """The closed form against the reference (posterior mean, else MAP), each row
    rounded to the parameter's sd, on one scale given before the unit."""
    out = []
    for r in rows:
        f = row_format(r["reference"], r["sd"])
        out.append((r["name"], f"{f.suffix}{display_unit(ctx.unit(r['name']))}".strip(),
                    f.value(r["closed_form"]), f.value(r["reference"]), f.sd(r["sd"]),
                    *_distance(r)))
    return Table(TABLE_TITLES["comparison"],
                 ("parameter", "unit", "closed form", ctx.best_label, "sd", "distance (sd)",
                  "relative difference"), tuple(out),
                 "distance = (closed form − reference)/sd; the causes follow below.")
