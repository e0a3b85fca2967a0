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

import io
import os
import pickle
import signal
import sys

__all__ = ["Drawing", "draw", "later", "start", "shutdown", "workers", "WORKERS_ENV"]

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
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return min(_MAX_WORKERS, cores) if cores >= 2 else 0


def _exit_with(parent) -> None:
    parent.join()
    os._exit(0)


def _worker_init() -> None:
    import multiprocessing
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ[WORKERS_ENV] = "0"  # a worker draws its own figures itself
    parent = multiprocessing.parent_process()
    if parent is not None:  # a worker never outlives the process it draws for (killed)
        threading.Thread(target=_exit_with, args=(parent,), daemon=True).start()
    import matplotlib.figure  # noqa: F401  (imported once, before the first figure)
    from matplotlib.backends import backend_agg  # noqa: F401


def _ready() -> bool:
    return True


def start():
    """Start the pool (idempotent) and return it, or None when figures are drawn
    in-process.  Starting early lets the workers import matplotlib while the fit runs."""
    global _pool, _broken
    n = workers()
    if n == 0 or _broken or _pool is not None:
        return None if n == 0 or _broken else _pool
    import multiprocessing
    import types
    from concurrent.futures import ProcessPoolExecutor

    # A spawned process runs the parent's ``__main__`` again unless it is hidden: a
    # user's script without a ``__main__`` guard would run once per worker.  The workers
    # start here, on these submissions, while a blank ``__main__`` stands in.
    main = sys.modules.get("__main__")
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        _pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("spawn"),
                                    initializer=_worker_init)
        for _ in range(n):
            _pool.submit(_ready)
    except (OSError, RuntimeError, ImportError):
        _broken, _pool = True, None
    finally:
        if main is None:
            del sys.modules["__main__"]
        else:
            sys.modules["__main__"] = main
    return _pool


def shutdown() -> None:
    """Stop the workers, once the figures they have begun are drawn (a later figure
    starts a new pool)."""
    global _pool
    if _pool is not None:
        _pool.shutdown(wait=True, cancel_futures=True)
        _pool = None


def _render(fig, rect, style) -> bytes:
    import matplotlib

    with matplotlib.rc_context(style):
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
        pool = start() if worker is not None else None
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
