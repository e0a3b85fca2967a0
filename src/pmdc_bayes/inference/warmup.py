"""Making the programs of a fit's later stages while the MAP runs.

The MAP makes and runs the Gauss–Newton kernel in the calling thread.  The programs
the later stages call (the prediction of the adequacy checks and the report, the
sampler's batch log-posterior, the pointwise residuals of the ArviZ record) depend
only on the session's structure, so a background thread makes them meanwhile, each by
one call at the seed θ; XLA compiles outside the GIL, so on two cores the two
overlap.  A program the calling thread reaches first is waited for, never made twice
(:class:`.cache._Compiled`).  A failure here is dropped: the stage that needs the
program makes it again and reports its own error.
"""

from __future__ import annotations

import threading

from .._x64 import x64

__all__ = ["WarmUp", "THREAD_NAME"]

THREAD_NAME = "pmdc-bayes warm-up"


class WarmUp:
    """A background thread making ``model``'s later programs (the sampler's too when
    ``mcmc``); :meth:`stop` skips those not yet begun."""

    def __init__(self, model, *, mcmc: bool, n_walkers: int | None = None,
                 start: bool = True):
        self.model, self.mcmc, self.n_walkers = model, mcmc, n_walkers
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name=THREAD_NAME,
                                       daemon=False)
        if start:
            self.thread.start()

    @x64  # in this thread too: JAX's 64-bit mode is a thread's own setting
    def _run(self) -> None:
        model = self.model
        theta = model.theta_seed()
        jobs = [lambda: model.predict(theta)]
        if self.mcmc:
            def sampler():
                from .sampling import warm_up

                warm_up(model, theta, self.n_walkers)

            jobs.append(sampler)
        for job in jobs:
            if self._stop.is_set():
                return
            try:
                job()
            except Exception:  # noqa: BLE001  (the stage that needs it reports it)
                pass

    def stop(self) -> None:
        """Begin no further program (one being made is finished)."""
        self._stop.set()
