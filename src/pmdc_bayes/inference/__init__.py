"""Everything statistical, by concern: the model and likelihood (:mod:`.model`), the MAP
(:mod:`.fit`), the verdict on the model and its diagnosis (:mod:`.adequacy`), the
posterior (:mod:`.sampling`), a lot as a population (:mod:`.population`); the later
stages' programs made while the MAP runs (:mod:`.warmup`) and the compiled programs
kept across calls (``_runtime``, private: its public names are exported here).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from .._lazy import lazy_names

__all__ = ["build_model", "SessionModel", "motor_registry", "fit_seed", "fit_map",
           "FitResult", "assess", "Adequacy", "Verdict", "sample_posterior",
           "Posterior", "fit_population", "WarmUp", "StageClock", "announcing",
           "enable_cache"]

_LAZY = {"build_model": ".model", "SessionModel": ".model", "motor_registry":
         ".model", "fit_seed": ".model", "fit_map": ".fit", "FitResult": ".fit",
         "assess": ".adequacy", "Adequacy": ".adequacy", "Verdict": ".adequacy",
         "sample_posterior": ".sampling", "Posterior": ".sampling",
         "fit_population": ".population", "WarmUp": ".warmup", "StageClock":
         "._runtime", "announcing": "._runtime", "enable_cache": "._runtime"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
