"""pmdc-bayes: identify permanent-magnet DC motor parameters with honest uncertainty."""

from ._errors import SessionError, UsageError
from .paper.closed_form import ClosedForm, closed_form
from .io.session import Session

__all__ = ["ClosedForm", "Session", "SessionError", "UsageError", "closed_form", "__version__"]

__version__ = "0.1.0"
