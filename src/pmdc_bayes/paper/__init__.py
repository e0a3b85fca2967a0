"""The reference paper's closed-form method (:mod:`.closed_form`) and the session's own
checks of its results (:mod:`.consistency`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from .._lazy import lazy_names

__all__ = ["closed_form", "consistency"]

_LAZY = {"closed_form": ".closed_form", "consistency": ".consistency"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
