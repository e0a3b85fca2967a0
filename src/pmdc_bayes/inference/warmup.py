"""Making the programs of a fit's later stages while the MAP runs.

The MAP makes and runs the Gauss–Newton kernel in the calling thread.  The programs
the later stages call (the prediction of the adequacy checks and the report, the
sampler's batch log-posterior, the pointwise residuals of the ArviZ record) depend
only on the session's structure, so background threads make them meanwhile, each by
one call at the seed θ; XLA compiles outside the GIL, so on two cores they overlap.
A program the calling thread reaches first is waited for, never made twice
(:class:`.cache._Compiled`).  A failure here is dropped: the stage that needs the
program makes it again and reports its own error.
"""

from __future__ import annotations

import contextlib
import threading

import numpy as np

from .._x64 import x64
from .predictions import RESIDUAL_BATCH

__all__ = ["WarmUp", "THREAD_NAME"]

THREAD_NAME = "pmdc-bayes warm-up"


class WarmUp:
    """Background threads making ``model``'s later programs: the prediction, then (when
    ``mcmc``) the sampler's batch log-posterior, and in a thread of its own the
    pointwise residuals; :meth:`stop` skips what has not begun."""

    def __init__(self, model, *, mcmc: bool, n_walkers: int | None = None,
                 start: bool = True):
        self.model, self.n_walkers = model, n_walkers
        self._stop = threading.Event()
        lines = [[self._predict] + ([self._sampler] if mcmc else [])]
        if mcmc:
            lines.append([self._pointwise])
        self.threads = [threading.Thread(target=self._run, args=(jobs,), name=THREAD_NAME,
                                         daemon=False) for jobs in lines]
        if start:
            self.start()

    def start(self) -> None:
        for thread in self.threads:
            thread.start()

    def join(self) -> None:
        for thread in self.threads:
            thread.join()

    def stop(self) -> None:
        """Begin no further program (one being made is finished)."""
        self._stop.set()

    @contextlib.contextmanager
    def stopped_on_error(self):
        """Stop when the block raises (an error or an interrupt): nothing more is made
        for stages that will not run."""
        try:
            yield
        except BaseException:
            self.stop()
            raise

    @x64  # in these threads too: JAX's 64-bit mode is a thread's own setting
    def _run(self, jobs) -> None:
        theta = self.model.theta_seed()
        for job in jobs:
            if self._stop.is_set():
                return
            try:
                job(theta)
            except Exception:  # noqa: BLE001  (the stage that needs it reports it)
                pass

    def _predict(self, theta) -> None:
        self.model.predict(theta)

    def _sampler(self, theta) -> None:
        from .sampling import warm_up

        warm_up(self.model, theta, self.n_walkers)

    def _pointwise(self, theta) -> None:
        theta = np.asarray(theta, dtype=float)
        self.model.residuals_of_batch(np.repeat(theta[None], RESIDUAL_BATCH, axis=0))
