"""The MAP: the joint fit of a session (:mod:`.joint`, by :mod:`.multistart`'s starts
through :mod:`.optimiser`'s optimistix solver with :mod:`.curvature`'s Gauss–Newton
curvature; distinct optima in :mod:`.optima`), its Laplace approximation, what the data
cannot determine (:mod:`.undetermined`), and one compiled program for many candidate
models (:mod:`.superset`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from ..._lazy import lazy_names

__all__ = ["fit_map", "FitResult", "FitStatus", "laplace", "identifiability",
           "Superset", "extended"]

_LAZY = {"fit_map": ".joint", "FitResult": ".joint", "FitStatus": ".joint",
         "laplace": ".joint", "identifiability": ".undetermined", "Superset":
         ".superset", "extended": ".superset"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
