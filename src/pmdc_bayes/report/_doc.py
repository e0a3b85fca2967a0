"""A tiny document model: sections of paragraphs, tables and figures.

The report is built once as a list of :class:`Section` records and rendered twice, to
HTML (:mod:`.html`) and Markdown (:mod:`.markdown`), so both say the same thing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Paragraph", "Bullets", "Table", "Figure", "Section", "fmt", "pm"]


@dataclass(frozen=True)
class Paragraph:
    """Plain text (no markup)."""

    text: str


@dataclass(frozen=True)
class Bullets:
    """A list of plain-text items."""

    items: tuple


@dataclass(frozen=True)
class Table:
    """A table: ``header`` and ``rows`` of cell strings, a title and a note under it."""

    title: str
    header: tuple
    rows: tuple
    note: str = ""


@dataclass(frozen=True)
class Figure:
    """A PNG figure: ``name`` (file stem in ``figures/``), caption and the PNG bytes (or,
    until the report is written, the :class:`~._render.Drawing` that gives them)."""

    name: str
    caption: str
    png: object


@dataclass
class Section:
    """A titled section of blocks (paragraphs, lists, tables, figures)."""

    title: str
    blocks: list = field(default_factory=list)

    def add(self, block) -> Section:
        self.blocks.append(block)
        return self


def fmt(x, digits: int = 4) -> str:
    """A number with ``digits`` significant figures; ``—`` for None or NaN."""
    if x is None:
        return "—"
    x = float(x)
    if math.isnan(x):
        return "—"
    if x == 0.0:
        return "0"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    mag = abs(x)
    if 1e-3 <= mag < 1e5:
        return f"{x:.{digits}g}"
    return f"{x:.{digits - 1}e}"


def pm(mean, sd, digits: int = 4) -> str:
    """``mean ± sd`` with the mean to ``digits`` and the sd to 2 significant figures."""
    if mean is None:
        return "—"
    if sd is None:
        return fmt(mean, digits)
    return f"{fmt(mean, digits)} ± {fmt(sd, 2)}"
