"""Set-up of a lot's local Dask worker process (a Dask *preload*: run in each worker
process as it starts, and again in one the nanny restarts).

A Ctrl-C at the terminal reaches every process of its group: the workers ignore it,
and log only Dask's errors, so that a worker's own interrupt or its warnings about the
work the command then cancels are not printed; the command stops the lot and closes
its workers (:func:`pmdc_bayes.lot.run_lot`).
"""

from __future__ import annotations

import logging
import signal
import threading

__all__ = ["dask_setup"]


def dask_setup(worker) -> None:
    """Called by Dask with the worker it sets up."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.ERROR)
