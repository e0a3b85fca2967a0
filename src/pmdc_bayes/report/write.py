"""Writing the report of a finished run: ``report.html``, ``report.md``,
``figures/*.png`` and ``controller.json`` in the run directory.

:func:`write_report_for` writes them from a run's record, the one a run just produced
or one :func:`pmdc_bayes.readback.read_run` read back from its directory.  Matplotlib is
used here only, with the Agg backend.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from .._errors import UsageError
from .._x64 import x64
from ..inference import StageClock
from ..io.output import dumps, write_whole
from ._context import context_from_result
from ._doc import Figure
from .build import CONTROLLER_FILE, build_sections
from .html import render_html
from .markdown import render_markdown

__all__ = ["write_report_for", "report_stage"]

FIGURES = "figures"


def _built(ctx):
    """The sections and the controller model, with every figure's PNG bytes in place
    (the figures are drawn in worker processes while the tables are built, see
    :mod:`._render`; a failure drops the figures still waiting)."""
    from ._render import start_drawing

    start_drawing()
    sections, model = build_sections(ctx)
    pending = [(sec, i) for sec in sections for i, block in enumerate(sec.blocks)
               if isinstance(block, Figure) and not isinstance(block.png, bytes)]
    try:
        for sec, i in pending:
            sec.blocks[i] = dataclasses.replace(sec.blocks[i], png=sec.blocks[i].png.png())
    except BaseException:
        for sec, i in pending:
            if not isinstance(sec.blocks[i].png, bytes):
                sec.blocks[i].png.cancel()
        raise
    return sections, model


def _figures(sections):
    """The figures, each renamed if its file name (case-folded, as some file systems
    compare names) is taken by an earlier one."""
    figs, taken = [], set()
    for sec in sections:
        for i, fig in enumerate(sec.blocks):
            if not isinstance(fig, Figure):
                continue
            name, k = fig.name, 2
            while name.casefold() in taken:
                name, k = f"{fig.name}-{k}", k + 1
            if name != fig.name:
                fig = sec.blocks[i] = dataclasses.replace(fig, name=name)
            taken.add(name.casefold())
            figs.append(fig)
    return figs


@x64
def write_report_for(result, run_dir, *, into=None, say=None) -> dict[str, Path]:
    """Write the report of a run; return the paths written.

    Parameters
    ----------
    result : the run's :class:`~pmdc_bayes.run.RunResult`.
    run_dir : the run directory (named in the report).
    into : where to write (default ``run_dir``), e.g. a run directory still being built.
    say : called with a line as each stage starts (None: silent).

    Keys of the result: ``html``, ``markdown``, ``controller`` and ``figures`` (a list).
    """
    say = say or (lambda text: None)
    ctx = context_from_result(result, run_dir)
    dest = Path(run_dir if into is None else into)
    say("drawing the figures and building the tables")
    sections, model = _built(ctx)
    s = ctx.summary["session"]
    title = f"pmdc-bayes report: {s['motor']} (session {s['name']!r})"
    figdir = dest / FIGURES
    if figdir.exists() and not figdir.is_dir():
        raise UsageError(f"{figdir}: a file where the report's figures go; move it away "
                         "and rerun")
    figdir.mkdir(exist_ok=True)
    say(f"writing report.html, report.md, {CONTROLLER_FILE} and the figures into {dest}")
    figs = []
    for fig in _figures(sections):
        path = figdir / f"{fig.name}.png"
        write_whole(path, fig.png)
        figs.append(path)
    paths = {"html": dest / "report.html", "markdown": dest / "report.md",
             "controller": dest / CONTROLLER_FILE, "figures": figs}
    write_whole(paths["controller"], json.dumps(model, indent=2))
    write_whole(paths["markdown"], render_markdown(title, sections, figdir=FIGURES))
    write_whole(paths["html"], render_html(title, sections))
    return paths


def report_stage(result, run_dir, into):
    """The report stage of ``pmdc-bayes fit``: write the report of ``result`` into the run
    directory being built (``into``), and ``summary.json`` there again with the report's
    wall time and the part of it spent making JAX programs in ``summary["diagnostics"]``
    (``wall_s`` and ``compile_s``: ``report`` and ``total``).  Returns the run so
    recorded."""
    clock = StageClock()
    with clock.stage("report"):
        write_report_for(result, run_dir, into=into)
    diag = dict(result.summary.get("diagnostics", {}))
    for key, times in (("wall_s", clock.wall), ("compile_s", clock.compile)):
        record = dict(diag.get(key, {}))
        # a result written twice counts its report once
        record["total"] = record.get("total", 0.0) - record.get("report", 0.0) \
            + times["report"]
        record["report"] = times["report"]
        diag[key] = record
    run = result.recorded(diagnostics=diag)
    write_whole(Path(into) / "summary.json", dumps(run.summary))
    return run
