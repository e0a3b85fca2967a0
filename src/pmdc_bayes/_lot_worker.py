"""Set-up of a lot's local Dask worker process (a Dask *preload*: run in each worker
process as it starts, and again in one the nanny restarts).

A Ctrl-C at the terminal reaches every process of its group: the workers ignore it,
and log only Dask's critical messages, so that a worker's own interrupt, its warnings
about the work the command then cancels and its errors on finding the scheduler gone
while it is closed are not printed; the command stops the lot and closes its workers
(:func:`pmdc_bayes.lot.run_lot`).  A motor whose fit fails in a worker reaches the
command as its future's exception, and is reported there.
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
    for name in ("distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
