"""The report's first section: does the session reject the fitted model?"""

from __future__ import annotations

from .._format import row_format
from ..inference.adequacy.findings import Severity
from ..inference.adequacy.steady import Noise
from ..inference.model.channels import STEADY_RELATIVE_NOISE
from ..io.units import display_unit
from ._doc import Bullets, Paragraph, Section, Table, fmt

__all__ = ["adequacy_section", "bench_table", "CONDITIONAL"]

CONDITIONAL = ("Every value and interval below is CONDITIONAL on a model the data reject "
               "(see 'Model adequacy'): treat them as a description of the misfit, not as "
               "the motor's parameters.")


def _p(x) -> str:
    return "—" if x is None else (f"{x:.2g}" if x >= 1e-4 else "< 1e-4")


def adequacy_section(ctx) -> Section | None:
    """Verdict, findings, diagnosis and the per-channel figures (None for a run written
    before the checks existed)."""
    a = ctx.summary.get("adequacy")
    if not a:
        return None
    sec = Section("Model adequacy")
    fails = [f for f in a["findings"] if Severity(f["severity"]) is Severity.FAIL]
    warns = [f for f in a["findings"] if Severity(f["severity"]) is not Severity.FAIL]
    if fails:
        sec.add(Paragraph("VERDICT: MODEL INADEQUATE. The data reject the fitted model; "
                          "the numbers in this report describe a misfit. What failed (each "
                          "with its p-value under the fitted model; the session's checks "
                          f"are corrected together at {_level(a)} family-wise):"))
        sec.add(Bullets(tuple(f"{f['where']}: {f['message']} ({f['check']}; {f['size']}"
                              f"{_pv(f)})" for f in fails)))
        sec.add(Paragraph("What the pattern suggests the model lacks:"))
        sec.add(Bullets(tuple(a["diagnosis"])))
    else:
        sec.add(Paragraph("Verdict: adequate. The checks below do not reject the fitted model "
                          "(residuals white or immaterial, noise levels as the data's own, "
                          "bench values and logged levels respected)."))
    if warns:
        sec.add(Paragraph("Warnings:"))
        sec.add(Bullets(tuple(f"{f['where']}: {f['message']}{_pv(f, '  (')}"
                              f"{')' if f.get('p_value') is not None else ''}"
                              for f in warns)))
    rows = []
    for name, c in a["channels"].items():
        if "whiteness" not in c:
            label = "of the largest reading" + (", on its noise prior"
                                                if c.get("noise") == Noise.PRIOR else "")
            rows.append((name, "—", "—", "—", "—",
                         f"{100 * c['rms_miss_fraction']:.2g} (rms miss {label})",
                         _p(c.get("p_value")), "—", "—"))
            continue
        rows.append((name, fmt(c["fitted_sd"], 2), fmt(c["model_free_sd"], 2),
                     f"{c['inflation']:.2f}", _p(c["whiteness"]["p_value"]),
                     f"{100 * c['systematic_fraction']:.2g}", _p(c.get("systematic_p")),
                     _percent(c["fit_percent_closed_form"]), _percent(c["fit_percent_map"])))
    sec.add(Table("Per channel", ("channel", "fitted noise sd", "model-free sd", "ratio",
                                  "Ljung-Box p", "systematic misfit (% span)", "its p",
                                  "fit % closed form", "fit % MAP"), tuple(rows),
                  "Fit % is MATLAB's compare figure, 100·(1 − ‖y − ŷ‖/‖y − ȳ‖). Each p-value "
                  "is the check's under the fitted model (a known distribution, or a "
                  "parametric bootstrap at the MAP through the data's quantisation). A "
                  "channel fails when the session's checks, corrected together (Holm) at "
                  f"{_level(a)} family-wise, reject its systematic misfit and that misfit is "
                  "material (above 1.5 % of the span). A steady channel's p is that of "
                  "its miss beyond the readings' own scatter about a line in voltage and "
                  "load, or where too few readings show no scatter, beyond the channel's "
                  f"noise prior ({100 * STEADY_RELATIVE_NOISE:.0f} % of the typical reading, "
                  "heavy-tailed)."))
    bench = a.get("bench", {})
    if bench:
        sec.add(bench_table(ctx, bench))
    return sec


def _level(a) -> str:
    return f"{100 * a.get('family_level', 0.01):.3g} %"


def _pv(f, lead: str = "; ") -> str:
    """A finding's p-value under the fitted model, when it has one."""
    p = f.get("p_value")
    return "" if p is None else f"{lead}p = {p:.2g}"


def _percent(x) -> str:
    """A fit %, to a tenth as in 'At a glance'."""
    return "—" if x is None else f"{x:.1f}"


def bench_table(ctx, bench: dict) -> Table:
    """Each bench value beside the fitted one: a row on one scale, the bench value
    rounded to its own sd, the fitted value to the fit's."""
    rows = []
    for k, b in bench.items():
        f = row_format(b["fitted"], ctx.sd(k) if k in ctx.summary["parameters"] else None)
        fb = f.same_scale(b["bench_sd"])
        rows.append((k, f"{f.suffix}{display_unit(b['unit'])}".strip(),
                     f"{fb.value(b['bench'])} ± {fb.sd(b['bench_sd'])}", f.value(b["fitted"]),
                     f"{b['z']:+.1f}"))
    return Table("Bench values", ("parameter", "unit", "bench ± sd", "fitted",
                                  "bench sd away"), tuple(rows),
                 "Each value rounded to its own uncertainty: the bench value to the bench "
                 "sd, the fitted value to the fit's sd.")

