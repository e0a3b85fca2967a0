"""Making the programs of a fit's later stages while the MAP runs.

The MAP makes and runs the Gauss–Newton kernel in the calling thread.  The programs
the later stages call (the prediction of the adequacy checks and the report, the
sampler's batch log-posterior, the pointwise residuals of the ArviZ record) depend
only on the session's structure, so background threads make them meanwhile, each by
one call at the seed θ; XLA compiles outside the GIL, so on two cores they overlap.
A program the calling thread reaches first is waited for, never made twice
(:class:`.cache._Compiled`).  A run that fits several models in turn (``--compare``)
makes the next models' fitting programs the same way (:meth:`WarmUp.fits`), a bounded
number of models ahead of the one being fitted, so that the programs held at once stay
few (a stick-slip model's hold about half a gigabyte).  A failure here is dropped: the
stage that needs the program makes it again and reports its own error.
"""

from __future__ import annotations

import contextlib
import queue
import threading

import numpy as np

from .._cores import usable_cores
from .._x64 import x64
from .model.predictions import RESIDUAL_BATCH

__all__ = ["WarmUp", "THREAD_NAME"]

THREAD_NAME = "pmdc-bayes warm-up"


def _queue(items) -> queue.SimpleQueue:
    """``items``, each ``(index, model, job)``: the index the model's place among those a
    :meth:`WarmUp.fits` makes (0 for one model's later stages)."""
    jobs = queue.SimpleQueue()
    for item in items:
        jobs.put(item)
    return jobs


class WarmUp:
    """Background threads making ``model``'s later programs: the prediction, then (when
    ``mcmc``) the sampler's batch log-posterior, and in a thread of its own the
    pointwise residuals; :meth:`stop` skips what has not begun.  :meth:`fits` makes
    the programs of several fits instead."""

    def __init__(self, model, *, mcmc: bool, n_walkers: int | None = None,
                 start: bool = True):
        self.n_walkers, self._models = n_walkers, [model]
        lines = [_queue([(0, model, self._predict)]
                        + ([(0, model, self._sampler)] if mcmc else []))]
        if mcmc:
            lines.append(_queue([(0, model, self._pointwise)]))
        self._threads(lines, start)

    @classmethod
    def fits(cls, models, *, threads: int | None = None, start: bool = True,
             kernels=None, lookahead: int | None = None) -> WarmUp:
        """``threads`` threads (default: two, or one on a single core) making, model
        after model (each taking the next job in order), what a MAP fit and its
        adequacy checks call (the Gauss–Newton kernel, the prediction): for a run that
        fits several models in turn (``--compare``), so that the next models' programs
        are made while this one is fitted (an XLA compilation keeps to one core).
        ``kernels``, per model, whether it needs its own kernel (not when it is fitted
        in a superset's, :mod:`.superset`); default all.  ``lookahead``: the programs of
        at most that many models beyond the one being fitted (:meth:`fitting`) are made
        (default: every model's at once)."""
        if threads is None:
            threads = min(2, usable_cores())
        if kernels is None:
            kernels = [True] * len(models)
        self = cls.__new__(cls)
        self.n_walkers, self._models = None, list(models)
        jobs = _queue((j, m, job) for j, (m, own) in enumerate(zip(models, kernels, strict=True))
                      for job in ((self._kernel, self._predict) if own else (self._predict,)))
        self._threads([jobs] * max(1, threads), start, lookahead)
        return self

    def fitting(self, model) -> None:
        """The caller begins to fit ``model``, one of :meth:`fits`'s ``models``: the
        programs of the ``lookahead`` models after it may now be made.  (Before any
        such call, those of the first ``lookahead`` models may: the caller fits
        something else meanwhile.)"""
        k = next((k for k, m in enumerate(self._models) if m is model), None)
        if k is None:
            raise ValueError("fitting(model): not one of the models the warm-up makes")
        with self._bound:
            self._limit = max(self._limit, k + 1 + self._lookahead)
            self._bound.notify_all()

    def waiting(self) -> int:
        """How many threads wait for the fits to catch up (:meth:`fitting`)."""
        with self._bound:
            return self._waiting

    def _threads(self, lines, start: bool, lookahead: int | None = None) -> None:
        self._bound, self._waiting = threading.Condition(), 0
        self._lookahead = float("inf") if lookahead is None else lookahead
        self._limit = self._lookahead
        self._stop = threading.Event()
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
        with self._bound:
            self._stop.set()
            self._bound.notify_all()

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
    def _run(self, jobs: queue.SimpleQueue) -> None:
        """The jobs of ``jobs`` (a queue, perhaps shared with other threads), in order."""
        while not self._stop.is_set():
            try:
                index, model, job = jobs.get_nowait()
            except queue.Empty:
                return
            with self._bound:  # no further ahead of the fits than the bound
                self._waiting += 1
                self._bound.wait_for(lambda j=index: self._stop.is_set() or j < self._limit)
                self._waiting -= 1
            if self._stop.is_set():
                return
            try:
                job(model, model.theta_seed())
            except Exception:  # noqa: BLE001  (the stage that needs it reports it)
                pass

    @staticmethod
    def _kernel(model, theta) -> None:
        from .fit.optimiser import Stepper

        Stepper.of(model).terms(theta)

    @staticmethod
    def _predict(model, theta) -> None:
        model.predict(theta)

    def _sampler(self, model, theta) -> None:
        from .sampling.posterior import warm_up

        warm_up(model, theta, self.n_walkers)

    @staticmethod
    def _pointwise(model, theta) -> None:
        theta = np.asarray(theta, dtype=float)
        model.residuals_of_batch(np.repeat(theta[None], RESIDUAL_BATCH, axis=0))
