"""Synthetic sessions with a known truth: from a plan, by the package's own model
(:func:`simulate_session`), or by the independent bench simulator
(:func:`bench_session`); the catalogue of misspecified benches (:data:`CASES`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from .._lazy import lazy_names

__all__ = ["simulate_session", "bench_session", "CASES"]

_LAZY = {"simulate_session": ".session", "bench_session": ".bench", "CASES": ".cases"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
