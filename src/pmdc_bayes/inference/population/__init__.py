"""A lot of motors as a population, the second stage of a hierarchical fit: what each
motor's own fit tells it (:mod:`.evidence`), the population sampled
(:mod:`.hierarchical`), and the pooled values, outliers and lot record
(:mod:`.pooling`).

The public names are imported on first use, so that importing one module does not
import the rest.
"""

from ..._lazy import lazy_names

__all__ = ["fit_population", "Population", "motor_evidence", "MotorEvidence",
           "analyse_lot", "lot_record"]

_LAZY = {"fit_population": ".hierarchical", "Population": ".hierarchical",
         "motor_evidence": ".evidence", "MotorEvidence": ".evidence",
         "analyse_lot": ".pooling", "lot_record": ".pooling"}


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
