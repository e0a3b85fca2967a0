"""Interrupts that are not lost where Python ignores exceptions.

A signal handler raises in whatever code runs when the signal arrives; when that is a
garbage-collection callback or a finaliser, Python hands the exception to
``sys.unraisablehook`` (which prints a traceback) and carries on.  The handlers here also
record the request; while they are installed, that hook drops a recorded interrupt
without a word and delivers the signal again a moment later, when the program is most
likely back in ordinary code; and :func:`check` raises it again at the points where it
matters: before a run directory or a simulated session is put in place, and between the
sampler's chunks of steps.  Only the command line installs them; from Python, an
interrupt is Python's own KeyboardInterrupt.
"""

from __future__ import annotations

import _thread
import contextlib
import signal
import sys
import threading

__all__ = ["Terminated", "check", "handled"]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is so that partial output is cleaned up."""


_pending: list[type[KeyboardInterrupt]] = []
_session = [0]  # which installation of the handlers is in force (0: none)
_count = [0]  # installations so far
_REDELIVER_S = 0.05  # delay before a signal whose exception was lost is sent again


def _handler(signum, frame):
    exc = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    _pending.append(exc)
    raise exc


def _unraisable(previous):
    """A ``sys.unraisablehook`` that drops a recorded interrupt raised where Python cannot
    propagate it (and sends its signal again), and passes anything else to ``previous``."""

    def hook(unraisable):
        exc = unraisable.exc_value
        if isinstance(exc, KeyboardInterrupt) and type(exc) in _pending:
            signum = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
            timer = threading.Timer(_REDELIVER_S, _redeliver, (signum, _session[0]))
            timer.daemon = True
            timer.start()
            return
        previous(unraisable)

    return hook


def _redeliver(signum, session: int) -> None:
    if session and _session[0] == session:  # never once those handlers are gone
        _thread.interrupt_main(signum)


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
    previous_hook, sys.unraisablehook = sys.unraisablehook, _unraisable(sys.unraisablehook)
    _session[0] = _count[0] = _count[0] + 1
    try:
        yield
    finally:
        _session[0] = 0
        for s, h in previous.items():
            signal.signal(s, h)
        sys.unraisablehook = previous_hook
        _pending.clear()
