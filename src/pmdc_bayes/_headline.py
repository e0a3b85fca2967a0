"""The headline of a fit, as text and as HTML: the verdict first, then each parameter
rounded to its uncertainty beside the closed form and how far the closed form is off,
the fit % of each trace (closed form against MAP) and what the data cannot determine.

What ``repr`` and a notebook show for a :class:`~pmdc_bayes.RunResult`, what
``pmdc-bayes fit`` prints and what the report's first section, "At a glance", holds.
"""

from __future__ import annotations

import html
import math

from ._format import off_by, row_format, spread_format
from .inference.adequacy.findings import Verdict
from .io.units import display_unit

__all__ = ["headline_rows", "fit_table", "fit_lines", "determinability", "pi_loop_text",
           "spread_text", "headline_text", "headline_html", "left_out_lines",
           "level_lines"]

UNCONVERGED = "MAP (the posterior's draws failed their gates)"
SPREAD_WORTH_SAYING = 2.0  # posterior sd over Laplace sd along the widest direction

EVERYTHING_DETERMINED = ("The data determine every parameter: no weakly constrained "
                         "combination, none set by its prior or bench value alone, no "
                         "strongly correlated pair.")


def _verdict(summary: dict) -> str:
    if Verdict.of(summary) is Verdict.ADEQUATE:
        return "model adequate: the data do not reject the fitted model"
    return "MODEL INADEQUATE: the data reject the fitted model; the values below are " \
           "conditional on it"


def headline_rows(summary: dict) -> list[dict]:
    """One row per parameter, every number already a string rounded to its uncertainty:
    ``name``, ``estimate``, ``sd``, ``unit`` (with the row's scale), ``closed_form`` and
    ``off`` (the closed form's distance from the estimate, in % and in sd; ``off_sd``
    the number of sd, or None).  The estimate is the posterior mean, or the MAP and its
    Laplace sd where nothing was sampled or the draws failed their gates: a sampler that
    has not mixed can sit in a corner of the posterior, its sd a fraction of the
    posterior's, where the Laplace approximation spans it (``source`` says which)."""
    unconverged = summary.get("diagnostics", {}).get("gates_passed") is False
    rows = []
    for name, p in summary["parameters"].items():
        post = "mean" in p and not unconverged
        est, sd = (p["mean"], p["sd"]) if post else (p["map"], p.get("map_sd"))
        f = row_format(est, sd)
        cf = p.get("closed_form")
        off, nsd = "", None
        parts = off_by(cf, est, sd)
        if parts is not None:
            nsd = (cf - est) / sd
            off = f"{parts[0]} %, {parts[1]} sd"
        rows.append({"name": name, "estimate": f.value(est), "sd": f.sd(sd),
                     "unit": f"{f.suffix}{display_unit(p['unit'])}".strip(),
                     "closed_form": f.value(cf) if cf is not None else "—", "off": off,
                     "off_sd": nsd,
                     "source": "posterior mean" if post else
                     UNCONVERGED if unconverged and "mean" in p else "MAP"})
    return rows


def _percent(x) -> str:
    return f"{x:.1f}" if x is not None and math.isfinite(x) else "—"


def _fit_cells(summary: dict) -> tuple[list[str], dict[str, dict]]:
    """The signals, and per trace per signal its fit % cells (closed form, MAP)."""
    traces: dict[str, dict] = {}
    for name, c in summary.get("adequacy", {}).get("channels", {}).items():
        if c.get("fit_percent_map") is None:
            continue
        traces.setdefault(c.get("trace", name), {})[c.get("signal", "signal")] = (
            _percent(c.get("fit_percent_closed_form")), _percent(c["fit_percent_map"]))
    return list(dict.fromkeys(w for chans in traces.values() for w in chans)), traces


def fit_table(summary: dict) -> tuple[tuple, list[tuple]]:
    """The fit % (MATLAB's compare) of each trace's channels, closed form and MAP side
    by side: ``(header, rows)``, one row per trace, cells already strings; no rows
    without per-channel statistics."""
    kinds, traces = _fit_cells(summary)
    header = ("trace", *(f"{w}: {m}" for w in kinds for m in ("closed form", "MAP")))
    rows = [(trace, *(x for w in kinds for x in chans.get(w, ("", ""))))
            for trace, chans in traces.items()]
    return header, rows


def determinability(summary: dict) -> list[str]:
    """What the data cannot determine, in sentences; that they determine everything
    when the identifiability analysis found nothing."""
    ident = summary.get("identifiability")
    if ident is None:
        return []
    return list(ident.get("findings") or []) or [EVERYTHING_DETERMINED]


def fit_lines(summary: dict) -> list[str]:
    """:func:`fit_table` as indented lines for a terminal, ``"  trace: speed 96.4 → 99.2"``."""
    kinds, _ = _fit_cells(summary)
    _, rows = fit_table(summary)
    return [f"  {r[0]}: " + ", ".join(f"{w} {cf} → {m}" for w, cf, m
                                      in zip(kinds, r[1::2], r[2::2], strict=True) if m)
            for r in rows]


def pi_loop_text(rec: dict) -> str:
    """One line for people on a PI loop's margins (``summary["pi_loop"]``): at the
    estimate and their 94 % range over posterior draws, each kind of margin written to
    the precision of that range's width."""
    def margin(x, f, unit):
        return "∞" if x is None else f"{f.value(x)}{unit}"

    a, d = rec["at_estimate"], rec.get("over_draws")
    pm, gm = (d["phase_margin_deg"], d["gain_margin_db"]) if d else ((None,) * 3,) * 2
    fp = spread_format(pm[0], pm[2])
    fg = spread_format(gm[0], gm[2])
    text = (f"PI loop kp={rec['kp']:g}, ki={rec['ki']:g}"
            + (f", delay {rec['delay'] * 1e3:g} ms" if rec["delay"] else "")
            + f": phase margin {margin(a['phase_margin_deg'], fp, '°')}, gain margin "
              f"{margin(a['gain_margin_db'], fg, ' dB')}")
    if not d:
        return text + " (no posterior draws: no spread)"
    return text + (f"; over {d['n']} posterior draws, 94 % of phase margins in "
                   f"[{margin(pm[0], fp, '°')}, {margin(pm[2], fp, '°')}], of gain margins in "
                   f"[{margin(gm[0], fg, ' dB')}, {margin(gm[2], fg, ' dB')}]; "
                   f"{100 * d['share_pm_below_45']:.0f} % of draws under 45°")


def spread_text(diag: dict) -> str:
    """The widest direction of the posterior beyond the Laplace approximation, in words,
    when it is worth saying (empty otherwise)."""
    wide = diag.get("widest_direction")
    if not wide or wide["ratio"] < SPREAD_WORTH_SAYING:
        return ""
    names = wide["parameters"]
    if len(names) == 1:
        return (f"in {names[0]} the posterior spreads {wide['ratio']:.1f} times as far as the "
                "Laplace approximation: a parameter the data barely constrain (near a bound "
                "or set by its prior), slow to sample, whose Laplace sd is too small")
    shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
    return (f"along {shown} together the posterior spreads {wide['ratio']:.1f} times as far "
            "as the Laplace approximation: a combination the data barely constrain, slow "
            "to sample, whose Laplace sd is too small")


def _shaft(session: dict) -> str:
    """Where the values hold, for a gearmotor measured at its output."""
    ratio = session.get("gear_ratio", 1.0)
    return "" if ratio == 1.0 else (f"; at the motor shaft of a {ratio:g}:1 gearmotor, J, B "
                                    "and friction with the gearbox and load reflected to it")


def left_out_lines(summary: dict) -> list[str]:
    """A sentence per trace whose CSV had rows left out for a missing reading."""
    out = []
    for name, lines in (summary.get("session", {}).get("rows_left_out") or {}).items():
        shown = ", ".join(str(x) for x in lines[:5]) + (", ..." if len(lines) > 5 else "")
        out.append(f"{name}: {len(lines)} row{'s' if len(lines) > 1 else ''} with a missing "
                   f"reading left out (file line{'s' if len(lines) > 1 else ''} {shown})")
    return out


def level_lines(summary: dict) -> list[str]:
    """A sentence per logged input column read as the levels its driver held."""
    units = {"voltage": "V", "load_torque": "N·m"}
    out = []
    for name, roles in (summary.get("session", {}).get("columns_as_levels") or {}).items():
        for role, held in roles.items():
            n = f"{held['levels']} level{'s' if held['levels'] > 1 else ''}"
            if held.get("switched"):
                out.append(f"{name}: the {role.replace('_', ' ')} column samples a switching "
                           "driver's output (each reading a rail or zero), so it is read as "
                           f"the {n} of its duty")
                continue
            out.append(f"{name}: the {role.replace('_', ' ')} column's readings carry noise "
                       f"(sd {held['noise_sd']:.2g} {units[role]}), so it is read as the "
                       f"{n} its driver held")
    return out


def headline_text(summary: dict) -> str:
    rows = headline_rows(summary)
    session = summary.get("session", {})
    w = max([10] + [len(r["name"]) + 1 for r in rows])
    lines = [f"pmdc-bayes fit of {session.get('name', '?')} "
             f"({session.get('friction', '?')} friction): {_verdict(summary)}",
             f"{'parameter':<{w}}{'value':>12}{'± sd':>10}  {'unit':<18}{'closed form':>12}"
             "  closed form off by"]
    for r in rows:
        lines.append(f"{r['name']:<{w}}{r['estimate']:>12}{r['sd']:>10}  {r['unit']:<18}"
                     f"{r['closed_form']:>12}  {r['off']}")
    lines.append(f"(values: {rows[0]['source'] if rows else '—'}{_shaft(session)})")
    fits = fit_lines(summary)
    if fits:
        lines += ["Fit % per trace (closed form → MAP):", *fits]
    lines += [f"- {x}" for x in determinability(summary) + left_out_lines(summary)
              + level_lines(summary)]
    return "\n".join(lines)


def headline_html(summary: dict) -> str:
    e = html.escape
    rows = headline_rows(summary)
    session = summary.get("session", {})
    body = "".join(
        f"<tr><td>{e(r['name'])}</td><td style='text-align:right'>{e(r['estimate'])}</td>"
        f"<td style='text-align:right'>± {e(r['sd'])}</td><td>{e(r['unit'])}</td>"
        f"<td style='text-align:right'>{e(r['closed_form'])}</td><td>{e(r['off'])}</td></tr>"
        for r in rows)
    header, fits = fit_table(summary)
    fit_html = ("<p>fit % per trace</p><table><thead><tr>"
                + "".join(f"<th>{e(h)}</th>" for h in header) + "</tr></thead><tbody>"
                + "".join("<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>"
                          for r in fits) + "</tbody></table>") if fits else ""
    notes = "".join(f"<li>{e(x)}</li>"
                    for x in determinability(summary) + left_out_lines(summary)
                    + level_lines(summary))
    return (f"<div><p><b>pmdc-bayes fit of {e(str(session.get('name', '?')))}</b> "
            f"({e(str(session.get('friction', '?')))} friction): {e(_verdict(summary))}</p>"
            "<table><thead><tr><th>parameter</th><th>value</th><th>sd</th><th>unit</th>"
            "<th>closed form</th><th>closed form off by</th></tr></thead>"
            f"<tbody>{body}</tbody></table>"
            f"<p>values: {e(rows[0]['source'] if rows else '—')}</p>{fit_html}"
            + (f"<ul>{notes}</ul>" if notes else "") + "</div>")
