"""The report's tables, as :class:`~._doc.Table` records (cells already formatted)."""

from __future__ import annotations

import numpy as np

from ..physics.motor import gain, tf_full, time_constant
from ..inference.derived import derived_draws
from .._format import row_format
from ._doc import Table, fmt, pm
from ..io.units import display_unit
from .predictive import METHODS

__all__ = ["parameter_table", "derived_table", "diagnostics_table", "rms_table",
           "transfer_table", "comparison_table", "holdout_table", "TABLE_TITLES"]

TABLE_TITLES = {
    "parameters": "Parameters",
    "derived": "Derived quantities",
    "diagnostics": "Diagnostics and gates",
    "rms": "Per-trace RMS error",
    "transfer": "Transfer functions",
    "comparison": "Closed form against the posterior",
    "holdout": "Hold-out validation",
}


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
            + ("Posterior: emcee ensemble; R-hat is ArviZ's rank-normalised split R-hat with "
               "walkers as chains." if post else "No posterior was sampled (--no-mcmc)."))
    return Table(TABLE_TITLES["parameters"], tuple(header), tuple(rows), note)


def derived_table(ctx) -> Table:
    d = ctx.summary.get("derived") or {}
    voltage = d.get("voltage") or ctx.summary.get("derived_voltage") or 12.0
    q = d.get("quantities", {})
    single = {k: derived_draws({n: np.array([v]) for n, v in ctx.values[m].items()},
                               voltage=voltage) for k, m in (("cf", "closed_form"), ("map", "map"))}
    rows = []
    for name, (unit, _) in single["map"].items():
        r = q.get(name, {})
        rows.append((name, unit, fmt(single["cf"][name][1][0]), fmt(single["map"][name][1][0]),
                     pm(r.get("mean"), r.get("sd")),
                     f"[{fmt(r.get('hdi_3%'))}, {fmt(r.get('hdi_97%'))}]" if r else "—"))
    note = (f"No-load and stall quantities at {voltage:.4g} V. Posterior columns are computed "
            "draw by draw, so they carry the correlations of the parameters."
            + ("" if q else " No posterior was sampled (--no-mcmc)."))
    return Table(TABLE_TITLES["derived"], ("quantity", "unit", "closed form", "MAP",
                                           "posterior mean ± sd", "94 % HDI"), tuple(rows), note)


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
    wall = diag.get("wall_s", {})
    if wall:
        rows.append(("wall time (s)", ", ".join(f"{k} {v:.1f}" for k, v in wall.items()), ""))
    return Table(TABLE_TITLES["diagnostics"], ("check", "result", "detail"), tuple(rows))


def rms_table(preds, *, title=TABLE_TITLES["rms"], note="") -> Table:
    methods = [m for m in METHODS if preds and m in preds[0].sims]
    rows = []
    for tp in preds:
        for c in tp.channels:
            unit = {"speed": "rad/s", "current": "A", "position": "rad"}[c]
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


def _tf_draws(ctx):
    vals = ctx.draws if ctx.draws is not None else None
    if vals is None:
        return None
    d = {n: vals[:, k] for k, n in enumerate(ctx.names)}
    num, den = tf_full(d["Ra"], d["La"], d["K"], d["B"], d["J"])
    return {"(7) numerator K": num[0], "(7) s² coefficient La·J": den[0],
            "(7) s coefficient La·B + Ra·J": den[1], "(7) constant Ra·B + K²": den[2],
            "(8) gain G": gain(d["Ra"], d["K"], d["B"]),
            "(8) time constant τ": time_constant(d["Ra"], d["K"], d["B"], d["J"]),
            "(22) numerator K/J": num[0] / d["J"], "(22) s² coefficient La": den[0] / d["J"],
            "(22) s coefficient (La·B + Ra·J)/J": den[1] / d["J"],
            "(22) constant (Ra·B + K²)/J": den[2] / d["J"]}


def _tf_point(v):
    num, den = tf_full(v["Ra"], v["La"], v["K"], v["B"], v["J"])
    out = [num[0], *den, gain(v["Ra"], v["K"], v["B"]),
           time_constant(v["Ra"], v["K"], v["B"], v["J"]), num[0] / v["J"], *(den / v["J"])]
    return out


def transfer_table(ctx) -> Table:
    draws = _tf_draws(ctx)
    names = ["(7) numerator K", "(7) s² coefficient La·J", "(7) s coefficient La·B + Ra·J",
             "(7) constant Ra·B + K²", "(8) gain G", "(8) time constant τ",
             "(22) numerator K/J", "(22) s² coefficient La",
             "(22) s coefficient (La·B + Ra·J)/J", "(22) constant (Ra·B + K²)/J"]
    units = ["V·s/rad", "H·kg·m²", "Ω·kg·m²", "(V·s/rad)²", "rad/s per V", "s",
             "(7) ÷ kg·m²", "H", "(7) ÷ kg·m²", "(7) ÷ kg·m²"]
    cf, mp = _tf_point(ctx.values["closed_form"]), _tf_point(ctx.values["map"])
    rows = []
    for k, n in enumerate(names):
        post = (pm(float(np.mean(draws[n])), float(np.std(draws[n], ddof=1))) if draws
                else "—")
        rows.append((n, units[k], fmt(cf[k]), fmt(mp[k]), post))
    note = ("ω(s)/Va(s) = K / ((La·s + Ra)(J·s + B) + K²) (7); G/(τ·s + 1) with La neglected "
            "(8); (22) is (7) with numerator and denominator divided by J. Posterior columns: "
            "mean ± sd of each coefficient over the draws; with Coulomb friction the transfer "
            "functions describe the motion about a running operating point (Tc is a constant "
            "disturbance torque).")
    return Table(TABLE_TITLES["transfer"], ("coefficient", "unit", "closed form", "MAP",
                                            "posterior mean ± sd"), tuple(rows), note)


def comparison_table(ctx, rows) -> Table:
    out = []
    for r in rows:
        out.append((r["name"], fmt(r["closed_form"]), fmt(r["reference"]), fmt(r["sd"], 2),
                    f"{r['z']:+.3g}", f"{100 * r['relative']:+.3g} %"))
    return Table(TABLE_TITLES["comparison"],
                 ("parameter", "closed form", ctx.best_label, "sd", "distance (sd)",
                  "relative difference"), tuple(out),
                 "distance = (closed form − reference)/sd; the causes follow below.")
