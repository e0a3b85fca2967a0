"""Render the report as one self-contained HTML file (PNGs embedded as data URIs)."""

from __future__ import annotations

import base64
from html import escape

from ._doc import Bullets, Figure, Paragraph, Table

__all__ = ["render_html"]

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 1000px; margin: 2em auto;
       padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.35em; margin: 0 0 0.3em; }
h2 { border-bottom: 1px solid #ccc; margin-top: 2em; } nav + h2 { margin-top: 0.8em; }
h3 { margin: 0.8em 0 0.3em; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.5em; text-align: left; }
th { background: #f3f3f3; } td { font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; }
figcaption, .note { font-size: 0.85em; color: #555; }
nav ul { display: flex; flex-wrap: wrap; gap: 0 1.2em; list-style: none; padding: 0;
         margin: 0; font-size: 0.9em; }
"""


def _block(b) -> str:
    if isinstance(b, Paragraph):
        return f"<p>{escape(b.text)}</p>"
    if isinstance(b, Bullets):
        return "<ul>" + "".join(f"<li>{escape(x)}</li>" for x in b.items) + "</ul>"
    if isinstance(b, Table):
        head = "".join(f"<th>{escape(str(h))}</th>" for h in b.header)
        body = "".join("<tr>" + "".join(f"<td>{escape(str(c))}</td>" for c in r) + "</tr>"
                       for r in b.rows)
        note = f'<p class="note">{escape(b.note)}</p>' if b.note else ""
        return (f"<h3>{escape(b.title)}</h3><table><thead><tr>{head}</tr></thead>"
                f"<tbody>{body}</tbody></table>{note}")
    if isinstance(b, Figure):
        data = base64.b64encode(b.png).decode("ascii")
        return (f'<figure id="fig-{escape(b.name)}"><img alt="{escape(b.caption)}" '
                f'src="data:image/png;base64,{data}"><figcaption>{escape(b.caption)}'
                "</figcaption></figure>")
    raise TypeError(f"unknown block {type(b).__name__}")


def render_html(title: str, sections) -> str:
    """The whole report as an HTML document; needs no network to view."""
    parts = [f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
             f"<title>{escape(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{escape(title)}</h1>"]
    toc = "".join(f'<li><a href="#s{k}">{escape(s.title)}</a></li>'
                  for k, s in enumerate(sections))
    parts.append(f"<nav><ul>{toc}</ul></nav>")
    for k, s in enumerate(sections):
        parts.append(f'<h2 id="s{k}">{escape(s.title)}</h2>')
        parts.extend(_block(b) for b in s.blocks)
    parts.append("</body></html>\n")
    return "\n".join(parts)
