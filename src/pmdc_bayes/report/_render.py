"""Figures laid out and drawn to PNG in worker processes while the report goes on.

A figure function builds its :class:`matplotlib.figure.Figure` and hands it to
:func:`draw`, which returns a :class:`Drawing` at once.  The layout (``tight_layout``)
and the rendering to PNG, most of a report's time, run in a small pool of spawned
processes; a figure with many panels is built there too (:func:`later`, from the plain
records of :mod:`._view`, so the workers import matplotlib and nothing of the fitting
stack).  On two cores they overlap with each other and with the tables;
:meth:`Drawing.png` waits for the bytes.

The same figure is drawn in this process instead, with the same result, when it cannot
be pickled, when the machine has one core, when ``PMDC_BAYES_DRAW_WORKERS=0`` or when
the pool cannot start or breaks.  Workers ignore Ctrl-C: the main process handles it.
"""

from __future__ import annotations

import contextlib
import io
import os
import pickle
import signal
import sys
import threading

from .._cores import usable_cores

__all__ = ["Drawing", "draw", "later", "start_drawing", "stop_drawing", "workers", "report_rc",
           "WORKERS_ENV"]

WORKERS_ENV = "PMDC_BAYES_DRAW_WORKERS"
_MAX_WORKERS = 2
_pool = None
_broken = False


def workers() -> int:
    """How many drawing processes to use: ``$PMDC_BAYES_DRAW_WORKERS`` if set, else
    two on a machine with at least two usable cores, else none (draw in-process)."""
    raw = os.environ.get(WORKERS_ENV, "").strip()
    if raw:
        try:
            return max(0, int(raw))
        except ValueError:
            return 0
    cores = usable_cores()
    return min(_MAX_WORKERS, cores) if cores >= 2 else 0


def _exit_with(parent) -> None:
    parent.join()
    os._exit(0)


def _worker_init() -> None:
    import multiprocessing

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # blocked while spawned
    os.environ[WORKERS_ENV] = "0"  # a worker draws its own figures itself
    parent = multiprocessing.parent_process()
    if parent is not None:  # a worker never outlives the process it draws for (killed)
        threading.Thread(target=_exit_with, args=(parent,), daemon=True).start()
    import matplotlib.figure  # noqa: F401  (imported once, before the first figure)
    from matplotlib.backends import backend_agg  # noqa: F401


def _ready() -> bool:
    return True


_LOCK = threading.Lock()


def _forget_pool() -> None:
    """In a forked child: the parent's pool is not this process's to use."""
    global _pool, _broken, _LOCK
    _pool, _broken, _LOCK = None, False, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def start_drawing():
    """Start the pool (idempotent) and return it, or None when figures are drawn
    in-process: also in a process that :mod:`multiprocessing` started (a daemonic one
    may not have children, and one that ends by ``os._exit`` would leave a pool it
    waits for).  Starting early lets the workers import matplotlib while the fit
    runs."""
    global _pool, _broken
    import multiprocessing

    n = workers()
    with _LOCK:
        if n == 0 or _broken or multiprocessing.parent_process() is not None:
            return None
        if _pool is None:
            _pool = _spawn(n)
            _broken = _pool is None
        return _pool


def _spawn(n: int):
    """A pool of ``n`` spawned workers, started now, or None when that fails."""
    import multiprocessing
    import types
    from concurrent.futures import ProcessPoolExecutor

    # A spawned process runs the parent's ``__main__`` again unless it is hidden: a
    # user's script without a ``__main__`` guard would run once per worker.  The workers
    # start here, on these submissions, while a blank ``__main__`` stands in; Ctrl-C is
    # held back meanwhile (the mask is inherited; a worker then ignores it).
    main, blank = sys.modules.get("__main__"), types.ModuleType("__main__")
    sys.modules["__main__"] = blank
    in_main = threading.current_thread() is threading.main_thread()
    if in_main:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    pool = None
    try:
        pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_worker_init)
        for _ in range(n):
            pool.submit(_ready)
    except Exception:  # noqa: BLE001  (no pool: the figures are drawn in this process)
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        pool = None
    finally:
        if sys.modules.get("__main__") is blank:
            if main is None:
                del sys.modules["__main__"]
            else:
                sys.modules["__main__"] = main
        if in_main:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    return pool


def stop_drawing(wait: bool = True) -> None:
    """Stop the workers, once the figures they have begun are drawn (``wait=False``:
    at once, dropping what is queued); a later figure starts a new pool."""
    global _pool
    with _LOCK:
        pool, _pool = _pool, None
    if pool is not None:
        pool.shutdown(wait=wait, cancel_futures=True)


@contextlib.contextmanager
def report_rc(style):
    """matplotlib's defaults with ``style`` on top, whatever the caller has set (restored
    after), so that a figure is the same drawn here or in a worker."""
    import matplotlib

    with matplotlib.rc_context():
        matplotlib.rcdefaults()
        matplotlib.rcParams.update(style)
        yield


def _render(fig, rect, style) -> bytes:
    with report_rc(style):
        fig.tight_layout(rect=rect)
        buf = io.BytesIO()
        fig.savefig(buf, format="png")
    return buf.getvalue()


def _render_pickled(blob: bytes) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig, rect, style = pickle.loads(blob)
    FigureCanvasAgg(fig)
    return _render(fig, rect, style)


def _call_pickled(blob: bytes) -> bytes:
    fn, args = pickle.loads(blob)
    return fn(*args).png()


class Drawing:
    """A figure on its way to PNG bytes (:meth:`png`): ``local`` gives them in this
    process; ``worker(pickle.dumps(payload))`` gives the same in a worker process."""

    def __init__(self, local, worker=None, payload=None):
        self._local = local
        self._future, self._png = None, None
        pool = start_drawing() if worker is not None else None
        if pool is None:
            return
        try:
            blob = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
            self._future = pool.submit(worker, blob)
        except (pickle.PicklingError, TypeError, AttributeError, RuntimeError):
            self._future = None  # something that does not pickle, or a broken pool

    @property
    def in_worker(self) -> bool:
        """Whether a worker process draws this figure."""
        return self._future is not None

    def png(self) -> bytes:
        """The PNG bytes (waiting for the worker, if one draws it)."""
        global _broken, _pool
        if self._png is None:
            if self._future is not None:
                from concurrent.futures.process import BrokenProcessPool

                try:
                    self._png = self._future.result()
                except BrokenProcessPool:
                    _broken, _pool = True, None
                except Exception:  # noqa: BLE001  (drawn again here: a real fault re-raises)
                    pass
            if self._png is None:
                self._png = self._local()
            self._local = self._future = None
        return self._png

    def cancel(self) -> None:
        """Drop the figure unless it is already being drawn."""
        if self._future is not None:
            self._future.cancel()


def draw(fig, rect=(0.0, 0.0, 1.0, 1.0), style=None) -> Drawing:
    """Lay ``fig`` out with ``tight_layout(rect=rect)`` and render it to PNG under the
    rcParams ``style``, in a worker process when there is one."""
    rect, style = tuple(rect), dict(style or {})
    return Drawing(lambda: _render(fig, rect, style), _render_pickled, (fig, rect, style))


def later(fn, *args) -> Drawing:
    """``fn(*args)``, a figure function (module-level, returning a :class:`Drawing`),
    built and drawn in a worker process when there is one: for the figures with many
    panels, whose building costs as much as their drawing."""
    return Drawing(lambda: fn(*args).png(), _call_pickled, (fn, args))
