"""The closed-form method against the joint fit: distances and their causes.

For every parameter, the closed-form value's distance from the posterior mean (the
MAP without a posterior) in posterior standard deviations, and an attribution of the
difference to the method's known weaknesses, each with its numbers:

- K: equation (20) uses the bench Ra and one operating point (and may be rounded);
- B: equation (19) lumps all friction at that one operating point into the viscous
  coefficient (Coulomb friction ``Tc`` adds ``Tc/ω`` there), and inherits K's error;
- J: equation (9) from a 63.2 % reading: La is neglected in the first-order τ, the
  reading is quantised by the sampling interval, the step may not start from rest,
  and J inherits the errors of B, K and Ra through ``(B·Ra + K²)/Ra``;
- Tc: the closed form has none.

The decompositions are exact sums (the listed parts plus a stated remainder).  Each
amount of a parameter is written as the tables write that parameter: on its row's
scale, to the decimals its sd supports.
"""

from __future__ import annotations

import functools

import numpy as np

from .._format import off_by, row_format, value_sd
from ..io.units import display_unit
from ..paper.checks import turns
from ..paper.closed_form import kb_from_chopper, only_assumed, steady_rows_with_current
from ..physics.motor import time_constant

__all__ = ["compare_closed_form"]


def _cf_point(session):
    """The steady readings the closed form used for (20) and (19), as arrays (one
    entry for a single point, a steady table's rows otherwise): (V, Ia, ω, label)."""
    op = next((p for p in session.operating_points if p.current is not None), None)
    if op is not None:
        point = op.voltage, op.current, op.speed, f"operating point {op.name!r}"
    else:
        tr = next((t for t in session.traces
                   if t.kind == "step" and t.current is not None and turns(t)), None)
        if tr is not None:
            n = max(3, tr.n // 10)
            point = (float(tr.voltage.at(tr.time[-n:]).mean()), float(tr.current[-n:].mean()),
                     float(tr.speed[-n:].mean()), f"the settled end of trace {tr.name!r}")
        else:
            name, v, i, w = steady_rows_with_current(session)
            point = v, i, w, f"the rows of steady table {name!r} (averaged)"
    v, i, w, label = point
    return np.atleast_1d(v), np.atleast_1d(i), np.atleast_1d(w), label


def _amount(ctx, name: str, x: float, *, sign: bool = True) -> str:
    """An amount of parameter ``name`` (SI) with its unit, on the scale and to the
    decimals of that parameter's row in the tables (``+0.0208 ×1e-3 V·s/rad``)."""
    f = row_format(ctx.best[name], ctx.sd(name))
    text = f.value(x)
    if sign and not text.startswith("-") and text != "—":
        text = "+" + text
    return f"{text} {f.suffix}{display_unit(ctx.unit(name))}"


def _k_causes(ctx, ref, label):
    V, Ia, w, where = _cf_point(ctx.session)
    cf = ctx.cf
    k_raw = float(np.mean(kb_from_chopper(V, 1.0, Ia, w, cf.Ra)))
    k_ra = float(np.mean(kb_from_chopper(V, 1.0, Ia, w, ref["Ra"])))
    gap = cf.K - ref["K"]
    V, Ia, w_mean = float(np.mean(V)), float(np.mean(Ia)), float(np.mean(w))
    k = functools.partial(_amount, ctx, "K")
    ra = functools.partial(_amount, ctx, "Ra", sign=False)
    out = [f"Equation (20) at {where} (Va = {V:.4g} V, Ia = {Ia:.4g} A, ω = {w_mean:.4g} rad/s) "
           f"with the bench Ra = {ra(cf.Ra)} gives K = {k(k_raw, sign=False)}; with the "
           f"{label} Ra = {ra(ref['Ra'])} it gives {k(k_ra, sign=False)}, so Ra accounts for "
           f"{k(k_raw - k_ra)} of the {k(gap)} difference."]
    if abs(cf.K - k_raw) > 0:
        out.append(f"Rounding K to the published digits changes it by {k(cf.K - k_raw)}.")
    rest = gap - (k_raw - k_ra) - (cf.K - k_raw)
    out.append(f"The remaining {k(rest)} is the single operating point's "
               f"disagreement with the rest of the data (one reading, no averaging).")
    return out


def _b_causes(ctx, ref, label):
    V, Ia, w, where = _cf_point(ctx.session)
    cf = ctx.cf
    gap = cf.B - ref["B"]
    k_part = float(np.mean((cf.K - ref["K"]) * Ia / w))
    inv_w, w = float(np.mean(1.0 / w)), float(np.mean(w))
    b = functools.partial(_amount, ctx, "B")
    out = [f"Equation (19), B = K·Ia/ω at {where}, inherits K's error: {b(k_part)} "
           f"of the {b(gap)} difference."]
    lump = 0.0
    if "Tc" in ref:
        lump = ref["Tc"] * inv_w
        out.append(f"It lumps all friction at that point into B: the Coulomb torque "
                   f"Tc = {_amount(ctx, 'Tc', ref['Tc'], sign=False)} at ω = {w:.4g} rad/s "
                   f"looks like Tc/ω = {b(lump)} of viscous friction.")
    else:
        cons = ctx.summary.get("consistency", {})
        off, slope = cons.get("steady_offset"), cons.get("steady_slope")
        if off is not None and off < 0:
            t_eq = -off * ref["K"] / (slope * ref["Ra"])
            out.append(f"Friction that does not grow with speed is lumped into B: the steady "
                       f"points' offset of {off:.3g} rad/s at 0 V is what a constant friction "
                       f"torque of about {t_eq:.3g} N·m would cause, which at ω = {w:.4g} rad/s "
                       f"looks like {b(t_eq * inv_w)} of viscous friction. The viscous "
                       f"model fitted here lumps it too, so it biases both values rather than "
                       f"their difference; fit with --friction coulomb to separate it.")
    rest = gap - k_part - lump
    out.append(f"The remaining {b(rest)} is the operating point's reading "
               f"against the other data.")
    return out


def _tau_source(ctx):
    """(description, sampling interval or None, started from rest?)."""
    s = ctx.session
    if s.step_readings:
        sr = s.step_readings[0]
        return f"step reading {sr.name!r}", None, sr.initial_speed == 0.0
    steps = [t for t in s.traces if t.kind == "step"]
    name = ctx.cf.used.get("tau", "")
    tr = next((t for t in steps if repr(t.name) in name), steps[0])
    v0 = float(tr.voltage.values[0])
    from_rest = tr.initial == "rest" or (tr.initial == "steady" and v0 == 0.0)
    return f"trace {tr.name!r}", tr.dt, from_rest


def _j_causes(ctx, ref, label):
    cf = ctx.cf
    d_cf = (cf.B * cf.Ra + cf.K**2) / cf.Ra
    d_ref = (ref["B"] * ref["Ra"] + ref["K"] ** 2) / ref["Ra"]
    tau_ref = time_constant(ref["Ra"], ref["K"], ref["B"], ref["J"])
    tau_e = ref["La"] / ref["Ra"]
    gap = cf.J - ref["J"]
    read_part = (cf.tau - tau_ref) * d_cf
    par_part = tau_ref * (d_cf - d_ref)
    src, dt, from_rest = _tau_source(ctx)
    j = functools.partial(_amount, ctx, "J")
    out = [f"Equation (9) turns the 63.2 % reading τ = {cf.tau:.4g} s ({src}) into J; the "
           f"{label} parameters give τ = {tau_ref:.4g} s, and the difference accounts for "
           f"{j(read_part)} of the {j(gap)} difference.",
           f"The closed-form B, K and Ra enter through (B·Ra + K²)/Ra "
           f"({100 * (d_cf / d_ref - 1):+.2g} %): {j(par_part)}.",
           f"La is neglected in the first-order τ: the full response lags by about "
           f"τe = La/Ra = {tau_e * 1e3:.3g} ms, worth {j(tau_e * d_cf)}."]
    if dt is not None:
        out.append(f"The 63.2 % crossing is quantised by the sampling interval "
                   f"{dt * 1e3:.3g} ms (±{dt / 2 * 1e3:.2g} ms, {100 * dt / 2 / cf.tau:.2g} % "
                   f"of τ, up to {j(dt / 2 * d_cf, sign=False)}).")
    else:
        out.append("The reading was taken off a plot: its resolution is not recorded (a "
                   "time printed to 0.01 s is ±0.005 s, "
                   f"{100 * 0.005 / cf.tau:.2g} % of τ).")
    out.append("The step started from rest, so the initial-speed bias does not apply."
               if from_rest else
               "The step did not start from rest: the first-order reading assumes it did.")
    return out


def _bench_causes(ctx, name, ref, label):
    m = getattr(ctx.session, name)
    unit = display_unit(ctx.unit(name))
    z_bench = (m.value - ref[name]) / m.sd
    sd = ctx.sd(name)
    better = m.sd / sd if sd > 0 else float("inf")
    text = (f"The closed form takes the bench measurement ({value_sd(m.value, m.sd)} {unit}); "
            f"it is {z_bench:+.2g} bench sd from the {label}.")
    if better > 1.5:
        text += (f" The traces determine {name} {better:.3g} times more precisely than the "
                 f"bench.")
    else:
        f = row_format(sd, sd)
        text += (f" The data add little to the bench measurement ({name} sd "
                 f"{f.sd(sd)} {f.suffix}{unit}).")
    return [text]


def compare_closed_form(ctx) -> list[dict]:
    """One row per parameter: closed form, reference, sd, z, relative difference, causes.

    ``z = (closed form − reference)/sd`` with the posterior mean and sd as reference
    (MAP and Laplace sd without a posterior).
    """
    ref, label = ctx.best, ctx.best_label
    rows = []
    used = ctx.summary.get("closed_form", {}).get("used", {})
    for name in [n for n in ctx.names if n in ctx.values["closed_form"]
                 and not only_assumed(used, n)]:
        cf = ctx.values["closed_form"][name]
        sd = ctx.sd(name)
        z = (cf - ref[name]) / sd if sd > 0 else float("nan")
        rel = cf / ref[name] - 1.0 if ref[name] != 0 else float("nan")
        if name in ("Ra", "La"):  # bench measurements, taken as they are
            causes = _bench_causes(ctx, name, ref, label)
        elif name == "K":
            causes = _k_causes(ctx, ref, label)
        elif name == "B":
            causes = _b_causes(ctx, ref, label)
        elif name == "J":
            causes = _j_causes(ctx, ref, label)
        else:
            causes = [f"The closed form has no Coulomb friction (Tc = 0); the data put it at "
                      f"{_amount(ctx, 'Tc', ref['Tc'], sign=False)}, {ref['Tc'] / sd:.3g} sd "
                      "from zero. At the "
                      "closed form's operating point it is lumped into B (see B)."]
        pct, nsd = off_by(cf, ref[name], sd) or ("—", "—")
        head = (f"{name}: the closed form is {pct} % from the {label}, {nsd} sd."
                if name != "Tc" else
                f"Tc: the closed form's implicit 0 is {nsd} sd from the {label}.")
        rows.append({"name": name, "closed_form": cf, "reference": ref[name], "sd": sd,
                     "z": z, "relative": rel, "headline": head, "causes": causes})
    return rows
