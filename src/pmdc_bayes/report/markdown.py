"""Render the report as Markdown, figures linked from ``figures/``."""

from __future__ import annotations

from ._doc import Bullets, Figure, Paragraph, Table

__all__ = ["render_markdown"]


def _cell(x) -> str:
    return str(x).replace("|", "\\|").replace("\n", " ")


def _block(b, figdir: str) -> str:
    if isinstance(b, Paragraph):
        return b.text
    if isinstance(b, Bullets):
        return "\n".join(f"- {x}" for x in b.items)
    if isinstance(b, Table):
        lines = [f"### {b.title}", "", "| " + " | ".join(_cell(h) for h in b.header) + " |",
                 "|" + "---|" * len(b.header)]
        lines += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in b.rows]
        if b.note:
            lines += ["", f"*{b.note}*"]
        return "\n".join(lines)
    if isinstance(b, Figure):
        return f"![{b.caption}]({figdir}/{b.name}.png)\n\n*{b.caption}*"
    raise TypeError(f"unknown block {type(b).__name__}")


def render_markdown(title: str, sections, *, figdir: str = "figures") -> str:
    """The whole report as Markdown (figures as relative links into ``figdir``)."""
    parts = [f"# {title}"]
    for s in sections:
        parts.append(f"## {s.title}")
        parts.extend(_block(b, figdir) for b in s.blocks)
    return "\n\n".join(parts) + "\n"
