"""pmdc-bayes: identify permanent-magnet DC motor parameters with honest uncertainty.

The public names below are imported on first use, so that ``import pmdc_bayes`` (and the
command line's start-up) stays light.
"""

from ._errors import FitFailed, SessionError, UsageError
from ._lazy import lazy_names

__all__ = [
    "ClosedForm",
    "FitFailed",
    "FitOptions",
    "RunResult",
    "Session",
    "SessionError",
    "UsageError",
    "closed_form",
    "fit",
    "fit_session",
    "load_session",
    "read_run",
    "run_fit",
    "simulate_session",
    "use_cache",
    "write_report",
    "__version__",
]

__version__ = "0.1.0"

_LAZY = {
    "ClosedForm": ".paper.closed_form",
    "closed_form": ".paper.closed_form",
    "fit": ".api",
    "Session": ".io.session",
    "load_session": ".io.loader",
    "RunResult": ".run",
    "read_run": ".readback",
    "fit_session": ".pipeline",
    "FitOptions": ".pipeline",
    "run_fit": ".pipeline",
    "simulate_session": ".simulate.session",
    "use_cache": ".cachedir",
    "write_report": ".readback",
}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
