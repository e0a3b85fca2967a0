"""Assemble the report's sections from a :class:`~._context.ReportContext`."""

from __future__ import annotations

import re

import numpy as np

from ..inference.adequacy.findings import Verdict
from ._doc import Bullets, Figure, Paragraph, Section, Table, fmt
from ._render import later
from ._view import METHODS
from .adequacy import CONDITIONAL, adequacy_section
from .comparison import compare_closed_form
from .export import controller_model
from .fig_chains import chains_figure, ranks_figure
from .fig_control import response_figure
from .fig_params import corner_figure, forest_figure
from .fig_steady import steady_figure
from .fig_traces import trace_figure
from .model_choice import selection_section
from .published import published_findings
from .tables import (
    comparison_table,
    derived_table,
    diagnostics_table,
    holdout_table,
    parameter_table,
    rms_table,
    transfer_table,
)

__all__ = ["build_sections", "CONTROLLER_FILE"]

CONTROLLER_FILE = "controller.json"


def _safe(name: str) -> str:
    return re.sub(r"[^\w.-]+", "_", name)


def _glance(ctx) -> Section:
    """The answer before any detail: the verdict, each parameter rounded to its
    uncertainty beside the closed form and its error, the fit % per channel and what the
    data cannot determine."""
    from .._headline import determinability, fit_table, headline_rows

    s = ctx.summary
    sec = Section("At a glance")
    adequate = Verdict.of(s) is Verdict.ADEQUATE
    sec.add(Paragraph(
        ("Model adequate: the data do not reject the fitted model." if adequate else
         "MODEL INADEQUATE: the data reject the fitted model; every number below is "
         "conditional on it (see Model adequacy for what to add).")
        + f" Fit of {s['session']['name']!r} ({s['session']['friction']} friction)."))
    rows = headline_rows(s)
    source = rows[0]["source"] if rows else "MAP"
    sec.add(Table("Parameters at a glance", (
        "parameter", source, "± sd", "unit", "closed form", "closed form off by"),
        tuple((r["name"], r["estimate"], r["sd"], r["unit"], r["closed_form"], r["off"])
              for r in rows),
        "Each value rounded to its uncertainty; a row's numbers share its scale."))
    header, fits = fit_table(s)
    if fits:
        sec.add(Table("Fit % per trace", header, tuple(fits),
                      "100 × (1 − ‖y − ŷ‖ / ‖y − mean(y)‖), as MATLAB's compare, for each "
                      "channel the trace logged."))
    lines = determinability(s)
    if lines:
        sec.add(Paragraph("What the data can and cannot determine:"))
        sec.add(Bullets(tuple(lines)))
    return sec


def _overview(ctx) -> Section:
    s = ctx.summary
    info = s["session"]
    sec = Section("Overview")
    text = (f"Session {info['name']!r} ({info['motor']}), read from {info['path']}; "
            f"{info['friction']} friction model; fit: {s['fit']['message']}.")
    if info.get("holdout"):
        text += f" Held out of the fit: {', '.join(info['holdout'])}."
    sec.add(Paragraph(text))
    if not ctx.has_posterior:
        sec.add(Paragraph("No posterior was sampled (the run used --no-mcmc, or posterior.nc "
                          "is missing): posterior columns, bands, chain plots and the posterior "
                          "predictive are skipped; uncertainties are the Laplace approximation "
                          "at the MAP."))
    if ctx.truth:
        sec.add(Paragraph("This is a SIMULATED session: the true parameters are known and "
                          "shown beside the estimates."))
    findings = s.get("consistency", {}).get("findings", [])
    if findings:
        sec.add(Paragraph("Where the session's own numbers disagree:"))
        sec.add(Bullets(tuple(findings)))
    return sec


def _published(ctx):
    lines = published_findings(ctx)
    if not lines:
        return None
    sec = Section("The paper's published numbers")
    sec.add(Paragraph("Arithmetic on the paper's own numbers (Table I, Table II, Figures 6 "
                      "and 7); the simulated values are quoted from the paper, not fitted."))
    return sec.add(Bullets(tuple(lines)))


def _parameters(ctx) -> Section:
    sec = Section("Parameters")
    if Verdict.of(ctx.summary) is Verdict.INADEQUATE:
        sec.add(Paragraph(CONDITIONAL))
    sec.add(parameter_table(ctx))
    sec.add(Figure("forest", "Every parameter on a common relative scale: closed form, MAP ± 2 "
                   "sd (Laplace), posterior 94 % HDI and, for a simulated session, the truth.",
                   later(forest_figure, ctx.view(chains=False), None)))
    sec.add(Figure("corner", "Pair plot of the mechanical parameters with the closed-form "
                   "point (an arrow at the edge points to it when it lies off the axes), the "
                   "MAP and the truth when known.", later(corner_figure, ctx.view(chains=False))))
    sec.add(derived_table(ctx))
    return sec


def _comparison(ctx) -> Section:
    sec = Section("Comparison with the closed-form method")
    if not ctx.cf.applicable:
        sec.add(Paragraph(f"The closed-form method does not apply to this session: "
                          f"{ctx.cf.reason}. The fit started from values read from the data "
                          "instead (" + "; ".join(f"{k}: {v}" for k, v in ctx.cf.used.items())
                          + "); the curves marked 'seed' show that start, not the paper's "
                          "method."))
        return sec
    rows = compare_closed_form(ctx)
    sec.add(Paragraph(f"How far the paper's closed-form values lie from the {ctx.best_label}, "
                      "in its standard deviations, and which known weakness of the method "
                      "accounts for the difference (each part with its number; the parts add "
                      "up to the difference)."))
    sec.add(comparison_table(ctx, rows))
    for r in rows:
        sec.add(Paragraph(r["headline"]))
        sec.add(Bullets(tuple(r["causes"])))
    return sec


def _traces(ctx) -> Section:
    sec = Section("Traces")
    if not ctx.predictions:
        return sec.add(Paragraph("The session has no traces (e.g. the paper published none), "
                                 "so there are no time-series figures."))
    sec.add(Paragraph("Each trace against the closed-form model (viscous, as the paper's "
                      "method assumes), the MAP and the posterior predictive 94 % band: the "
                      "model at posterior draws plus measurement noise at each channel's "
                      "fitted level. The parameter uncertainty alone gives a band far narrower "
                      "than the noise (see the table)."))
    note = ("RMS of measured − model. 'inside 94 % band': share of samples within the "
            "posterior predictive band (94 % expected for Gaussian noise).")
    sec.add(rms_table(ctx.predictions, note=note))
    if ctx.has_posterior:
        widths = [f"{tp.trace.name} {c}: "
                  f"{fmt(float(np.mean(tp.param_band[c][1] - tp.param_band[c][0])), 2)}"
                  for tp in ctx.predictions for c in tp.channels]
        sec.add(Paragraph("Mean width of the parameter-only 94 % band: " + "; ".join(widths)
                          + " (rad/s for speed, A for current, rad for angle)."))
    for tp in ctx.predictions:
        sec.add(Figure(f"trace_{_safe(tp.trace.name)}", f"Trace {tp.trace.name!r}: measured "
                       "against the models, residuals underneath.",
                       later(trace_figure, tp, ctx.cf_label)))
    return sec


def _holdout(ctx):
    if not ctx.holdout:
        return None
    sec = Section("Hold-out validation")
    sec.add(holdout_table(ctx))
    for tp in ctx.holdout:
        for c in tp.channels:
            parts = [f"{METHODS[m]} {fmt(tp.rms[m][c], 3)}" for m in METHODS if m in tp.rms]
            sec.add(Paragraph(f"Held-out {tp.trace.name!r} {c}: RMS prediction error "
                              + ", ".join(parts) + f" (noise level {fmt(tp.noise[c], 3)})."))
        sec.add(Figure(f"heldout_{_safe(tp.trace.name)}", f"Held-out trace {tp.trace.name!r} "
                       "predicted by each parameter set.",
                       later(trace_figure, tp, ctx.cf_label)))
    return sec


def _steady(ctx) -> Section:
    sec = Section("Steady state")
    sec.add(Paragraph("Steady speed against voltage (no load) and against load torque: the "
                      "closed-form line (viscous, equations (15)-(18)), the MAP and the "
                      "posterior 94 % band of the parameters, with the measured points and "
                      "their residuals."))
    return sec.add(Figure("steady", "Steady-state speed-voltage and speed-torque lines.",
                          steady_figure(ctx)))


def _diagnostics(ctx) -> Section:
    sec = Section("Diagnostics")
    sec.add(diagnostics_table(ctx))
    if ctx.has_posterior:
        sec.add(Figure("chains", "Trace plot of the walkers.",
                       later(chains_figure, ctx.view(draws=False))))
        sec.add(Figure("ranks", "Rank plots, walkers pooled into four sets.",
                       later(ranks_figure, ctx.view(draws=False))))
    else:
        sec.add(Paragraph("No chains to show (--no-mcmc)."))
    return sec


def _export(ctx) -> tuple[Section, dict]:
    model = controller_model(ctx)
    sec = Section("Controller design")
    sec.add(transfer_table(ctx))
    sec.add(Paragraph(f"{CONTROLLER_FILE} holds the model at the {ctx.best_label}: state-space "
                      "matrices (11)-(14) with x = [ω, ia], u = [TL, Va], y = ω, the transfer "
                      "function (7) and the parameter covariance. "
                      "pmdc_bayes.report.to_control() turns it into python-control objects."))
    rows = tuple((name, "; ".join("[" + ", ".join(fmt(x) for x in r) + "]" for r in model[name]))
                 for name in ("A", "B", "C", "D"))
    sec.add(Table("State-space matrices", ("matrix", "rows"), rows))
    band = ("the 94 % band over posterior draws (the parameters' uncertainty alone, no "
            "noise)" if ctx.has_posterior else "no band (no posterior was sampled)")
    sec.add(Figure("response", f"The speed's response to the voltage, ω/Va of (7), at the "
                   f"{ctx.best_label}, with {band}, beside the response of the "
                   f"{ctx.cf_label}. Coulomb friction is not part of the linear model.",
                   response_figure(ctx)))
    if "pi_loop" in ctx.summary:
        from .._headline import pi_loop_text

        sec.add(Paragraph(pi_loop_text(ctx.summary["pi_loop"]) + " (fit --pi)."))
    return sec, model


def build_sections(ctx) -> tuple[list[Section], dict]:
    """The report's sections and the controller model (for ``controller.json``).  The
    sections whose figures take longest to draw are built first, so that their drawing
    starts first (:mod:`._render`)."""
    diagnostics = _diagnostics(ctx)
    export, model = _export(ctx)
    parts = [_glance(ctx), adequacy_section(ctx), selection_section(ctx), _overview(ctx),
             _published(ctx),
             _parameters(ctx), _comparison(ctx),
             _traces(ctx), _holdout(ctx), _steady(ctx), export, diagnostics]
    return [p for p in parts if p is not None], model
