"""ArviZ, imported once for the package, without the notice of its 1.0 refactor."""

from __future__ import annotations

import warnings

with warnings.catch_warnings():
    # ArviZ 0.23 emits a once-a-day FutureWarning on import announcing its 1.0
    # refactor; the project pins arviz<0.24, so the notice does not concern users.
    warnings.filterwarnings("ignore", message=r"\s*ArviZ is undergoing", category=FutureWarning)
    import arviz as az

__all__ = ["az"]
