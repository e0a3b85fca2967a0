"""The session's model and likelihood: the parameter registry (:mod:`.params`, the rig's
entries in :mod:`.nuisances` and :mod:`.trace_states`), their use in the prediction
(:mod:`.effects`), the observations in blocks of channels (:mod:`.channels`), their noise
(:mod:`.noise`, :mod:`.coloured`), the log-posterior (:mod:`.objective`), what the model
predicts (:mod:`.predictions`, :mod:`.pointwise`), where a fit starts (:mod:`.seed`) and
the session's model-free steady levels (:mod:`.levels`, :mod:`.reversal`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from ..._lazy import lazy_names

__all__ = ["SessionModel", "build_model", "Registry", "ParamSpec", "Prior",
           "motor_registry", "nuisance_specs", "fit_seed", "refuse_contradictions",
           "Predictions", "Pointwise"]

_LAZY = {"SessionModel": ".objective", "build_model": ".objective", "Registry":
         ".params", "ParamSpec": ".params", "Prior": ".params", "motor_registry":
         ".params", "nuisance_specs": ".nuisances", "fit_seed": ".seed",
         "refuse_contradictions": ".contradictions", "Predictions": ".predictions", "Pointwise":
         ".pointwise"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
