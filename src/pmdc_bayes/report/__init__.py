"""The uncertainty report of a finished run: ``report.html``, ``report.md``,
``figures/*.png`` and ``controller.json`` in the run directory (:mod:`.write`).

The public names are imported on first use, so that importing a submodule (as the
processes that draw the figures do, see :mod:`._render`) does not import the rest.
"""

from .._lazy import lazy_names

__all__ = ["write_report_for", "report_stage", "start_drawing", "stop_drawing",
           "controller_model", "to_control"]

_LAZY = {"write_report_for": ".write", "report_stage": ".write", "start_drawing": "._render",
         "stop_drawing": "._render", "controller_model": ".export", "to_control": ".export"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
