"""Interrupts that are not lost where Python ignores exceptions.

A signal handler raises in whatever code runs when the signal arrives; when that is a
garbage-collection callback or a finaliser, Python prints the exception and carries on.
The handlers here also record the request, and :func:`check` raises it again at the points
where it matters: before a run directory or a simulated session is put in place, and
between the sampler's chunks of steps.  Only the command line installs them; from
Python, an interrupt is Python's own KeyboardInterrupt.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["Terminated", "check", "handled"]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is so that partial output is cleaned up."""


_pending: list[type[KeyboardInterrupt]] = []


def _handler(signum, frame):
    exc = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    _pending.append(exc)
    raise exc


def check() -> None:
    """Raise the first interrupt received, if any, even when its first raise was lost."""
    if _pending:
        raise _pending[0]


@contextlib.contextmanager
def handled():
    """SIGINT and SIGTERM recorded and raised while the block runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _pending.clear()
    previous = {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        _pending.clear()
