"""Figures for the report, drawn without touching the caller's matplotlib state.

Each figure is a :class:`matplotlib.figure.Figure` with its own Agg canvas (no pyplot
figure manager, so nothing is shown in a notebook and the backend is never switched),
and every figure function runs inside :func:`styled`: matplotlib's defaults with the
report's style on top (:func:`~._render.report_rc`), so the report looks the same
whatever the caller's ``rcParams``, and they are left as they were.
"""

from __future__ import annotations

import functools

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import NullLocator

from .._format import row_format
from ..io.units import display_unit
from ._render import draw, report_rc

__all__ = ["subplots", "styled", "png", "COLORS", "LABELS", "scale_of",
           "Line2D", "NullLocator", "STYLE"]

COLORS = {"measured": "0.35", "closed_form": "tab:orange", "map": "tab:blue",
          "mean": "tab:green", "truth": "tab:purple", "published": "tab:red"}
LABELS = {"closed_form": "closed form", "map": "MAP", "mean": "posterior predictive mean",
          "truth": "truth (simulated session)"}

STYLE = {"figure.dpi": 110, "savefig.dpi": 110, "font.size": 9, "axes.titlesize": 10,
         "legend.fontsize": 8, "axes.grid": True, "grid.alpha": 0.3}


def styled(fn):
    """Run a figure function inside ``rc_context(STYLE)``."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with report_rc(STYLE):
            return fn(*args, **kwargs)

    return wrapper


def subplots(nrows: int = 1, ncols: int = 1, *, figsize=None, **kwargs):
    """``(figure, axes)`` like ``pyplot.subplots``, on a figure of its own (Agg canvas)."""
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, **kwargs)


def png(fig, rect=(0.0, 0.0, 1.0, 1.0)):
    """The figure, laid out by ``tight_layout(rect=rect)`` and rendered to PNG in the
    report's style: a :class:`~._render.Drawing` whose ``png()`` gives the bytes,
    drawn in a worker process when there is one (:mod:`._render`)."""
    return draw(fig, rect, STYLE)


def scale_of(name: str, value: float, unit: str) -> tuple[float, str]:
    """A factor and an axis label for a parameter on the tables' scale, e.g.
    ``J (×1e-6 kg·m²)`` for 5.9e-4 (a power of 1000 outside [0.1, 10⁴), as
    :func:`pmdc_bayes._format.row_format` chooses); ``unit`` is the SI unit as written in
    ``summary.json``."""
    f = row_format(value, None)
    return 10.0 ** -f.exponent, f"{name} ({f.suffix}{display_unit(unit)})"
