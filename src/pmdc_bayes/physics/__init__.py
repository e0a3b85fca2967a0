"""The motor: its equations written once (:mod:`.motor`), an experiment's inputs and
sample times (:func:`make_experiment`) and the exact solution of the model through them
(:func:`simulate`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from .._lazy import lazy_names

__all__ = ["motor", "make_experiment", "simulate"]

_LAZY = {"motor": ".motor", "make_experiment": ".experiment", "simulate": ".solution"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
