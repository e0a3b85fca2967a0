"""The posterior: emcee's ensembles (:mod:`.posterior`, :mod:`.ensembles`) moving in
:mod:`.coordinates`' coordinates by :mod:`.moves`' moves on :mod:`.logprob`'s
log-density, stopped by :mod:`.stopping`'s rule; their diagnostics (:mod:`.diagnostics`),
ArviZ record (:mod:`.idata`, ArviZ imported by :mod:`.arviz_import`) and derived
quantities (:mod:`.derived`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from ..._lazy import lazy_names

__all__ = ["sample_posterior", "Posterior", "summarize", "gates", "compare_laplace",
           "loo_compare", "widest_direction", "derived_quantities",
           "to_inference_data"]

_LAZY = {"sample_posterior": ".posterior", "Posterior": ".posterior", "summarize":
         ".diagnostics", "gates": ".diagnostics", "compare_laplace": ".diagnostics",
         "loo_compare": ".diagnostics", "widest_direction": ".diagnostics",
         "derived_quantities": ".derived", "to_inference_data": ".idata"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
