"""Does the session reject the fitted model, and what would it need?  The verdict
(:mod:`.verdict`) from the residual checks (:mod:`.trace_checks`, :mod:`.glitches`,
:mod:`.residual_stats`), the parameter checks (:mod:`.checks`), the model's own
(:mod:`.model_checks`) and the plausibility checks (:mod:`.plausibility`), each a
:class:`~.findings.Finding` with its p-value (:mod:`.calibrate`); and the diagnosis
(:mod:`.diagnosis`, :mod:`.diagnosis_levels`, :mod:`.onset`) with what it proposes to
add (:mod:`.proposals`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from ..._lazy import lazy_names

__all__ = ["assess", "Adequacy", "Finding", "Check", "Severity", "Verdict",
           "diagnose", "Proposal"]

_LAZY = {"assess": ".verdict", "Adequacy": ".verdict", "Finding": ".findings",
         "Check": ".findings", "Severity": ".findings", "Verdict": ".findings",
         "diagnose": ".diagnosis", "Proposal": ".proposals"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
