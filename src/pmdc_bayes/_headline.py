"""The headline of a fit, as text and as HTML: the verdict first, then each parameter
rounded to its uncertainty beside the closed form and how far the closed form is off.

What ``repr`` and a notebook show for a :class:`~pmdc_bayes.RunResult`.
"""

from __future__ import annotations

import html
import math

from ._format import row_format
from .io.units import display_unit

__all__ = ["headline_rows", "headline_text", "headline_html"]


def _verdict(summary: dict) -> str:
    adequacy = summary.get("adequacy", {})
    if adequacy.get("verdict", "adequate") == "adequate":
        return "model adequate: the data do not reject the fitted model"
    return "MODEL INADEQUATE: the data reject the fitted model; the values below are " \
           "conditional on it"


def _signed(x: float) -> str:
    """Two significant digits: +24, -1.8, +0.034, +256; below 0.001 one digit, +3e-05."""
    return f"{x:+.0f}" if abs(x) >= 10 else f"{x:+.2g}" if abs(x) >= 1e-3 else f"{x:+.0e}"


def headline_rows(summary: dict) -> list[dict]:
    """One row per parameter, every number already a string rounded to its uncertainty:
    ``name``, ``estimate``, ``sd``, ``unit`` (with the row's scale), ``closed_form`` and
    ``off`` (the closed form's distance from the estimate, in % and in sd; ``off_sd``
    the number of sd, or None)."""
    rows = []
    for name, p in summary["parameters"].items():
        post = "mean" in p
        est, sd = (p["mean"], p["sd"]) if post else (p["map"], p.get("map_sd"))
        f = row_format(est, sd)
        cf = p.get("closed_form")
        off, nsd = "", None
        if all(x is not None and math.isfinite(x) for x in (cf, est, sd)) and est and sd > 0:
            pct, nsd = 100.0 * (cf - est) / abs(est), (cf - est) / sd
            off = f"{_signed(pct)} %, {_signed(nsd)} sd"
        rows.append({"name": name, "estimate": f.value(est), "sd": f.sd(sd),
                     "unit": f"{f.suffix}{display_unit(p['unit'])}".strip(),
                     "closed_form": f.value(cf) if cf is not None else "—", "off": off,
                     "off_sd": nsd,
                     "source": "posterior mean" if post else "MAP"})
    return rows


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
    lines.append(f"(values: {rows[0]['source'] if rows else '—'})")
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
    return (f"<div><p><b>pmdc-bayes fit of {e(str(session.get('name', '?')))}</b> "
            f"({e(str(session.get('friction', '?')))} friction): {e(_verdict(summary))}</p>"
            "<table><thead><tr><th>parameter</th><th>value</th><th>sd</th><th>unit</th>"
            "<th>closed form</th><th>closed form off by</th></tr></thead>"
            f"<tbody>{body}</tbody></table>"
            f"<p>values: {e(rows[0]['source'] if rows else '—')}</p></div>")
