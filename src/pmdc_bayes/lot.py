"""A production lot (``pmdc-bayes lot``): each motor's session fitted on its own, on a
Dask cluster (a local one of one worker per core by default, or an existing one), then
the lot as a population (:mod:`.inference.population.pooling`) where the command runs.

A motor is fitted by :func:`fit_motor` in a worker process, which keeps compiled
programs in the shared disk cache so that the motors after the first of a session
shape do not compile.  A motor whose session is bad input, whose fit fails or that
breaks its worker is reported with its one line and passed over; the others go on.
The population takes the motors that passed (fit converged, model adequate, gates
met).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import time
from dataclasses import dataclass
from pathlib import Path

from ._console import run_outcome
from ._errors import (
    EXIT_FAILED,
    EXIT_INTERNAL,
    EXIT_USAGE,
    FitFailed,
    SessionError,
    UsageError,
)
from .rundir import sweep_unfinished

__all__ = ["MotorRun", "fit_motor", "run_lot", "connect", "reachable", "pooled_names",
           "status_name"]

POOLED = ("Ra", "La", "K", "B", "J", "Tc")


@dataclass(frozen=True)
class MotorRun:
    """One motor of the lot: its session, exit status (as ``pmdc-bayes fit`` would
    end), run directory, the one-line error when there was one, its evidence for the
    population stage and the seconds its fit took."""

    session: Path
    name: str
    status: int
    run: Path | None = None
    error: str = ""
    evidence: object = None
    seconds: float = 0.0
    summary: dict | None = None


def status_name(code: int) -> str:
    """A motor's exit code in words, as ``lot.csv`` and the progress lines give it."""
    from ._batch import STATUS

    return STATUS.get(code, "internal error")


def fit_motor(session: Path, out: Path, *, name: str, mcmc: bool = True, seed: int = 0,
              force: bool = False, cache: bool = True) -> MotorRun:
    """Fit one motor's session into ``out`` (in a worker process): its status and, when
    it passed, its evidence about every motor parameter it has."""
    from . import cachedir
    from .inference.population.evidence import from_run
    from .pipeline import FitOptions, run_fit
    from .readback import read_run

    t0 = time.perf_counter()
    if cache:
        cachedir.enable()
    try:
        run, summary = run_fit(session, FitOptions(mcmc=mcmc, seed=seed), out=out,
                               force=force)
        status, errors = run_outcome(summary, advice=False)
        evidence = None
        if status == 0:
            result = read_run(run)
            names = [n for n in POOLED if n in result.model.registry]
            evidence = dataclasses.replace(from_run(result, names), name=name)
    except (SessionError, UsageError) as exc:
        return MotorRun(session, name, EXIT_USAGE, error=str(exc),
                        seconds=time.perf_counter() - t0)
    except FitFailed as exc:
        return MotorRun(session, name, EXIT_FAILED, error=str(exc),
                        seconds=time.perf_counter() - t0)
    except Exception as exc:  # noqa: BLE001  (a fault of the tool: this motor only)
        log = cachedir.save_traceback()
        return MotorRun(session, name, EXIT_INTERNAL,
                        error=f"internal error ({type(exc).__name__}: {exc}); traceback "
                              f"saved to {log}", seconds=time.perf_counter() - t0)
    return MotorRun(session, name, status, Path(run), errors[0] if errors else "", evidence,
                    time.perf_counter() - t0, summary)


def pooled_names(motors) -> tuple:
    """The parameters the lot is pooled over: K, B, J and Ra, La where every motor's
    was measured on the bench, Tc where every motor has Coulomb friction."""
    out = []
    for name in POOLED:
        have = [name in m.names for m in motors]
        if not all(have):
            continue
        if name == "La" and any(m.priors[m.names.index("La")][0] != "normal" for m in motors):
            continue
        out.append(name)
    return tuple(out)


def reachable(address: str) -> str:
    """``address`` of a Dask scheduler, checked before a client is made of it: anything
    but a TCP address (``tcp://HOST:PORT``), or one where nothing accepts a connection,
    is the user's mistake (:class:`UsageError`, one line)."""
    import socket

    from distributed.comm.addressing import parse_address, parse_host_port

    fix = ("give the address the scheduler prints (tcp://HOST:PORT), or drop --scheduler "
           "for a local cluster")
    timeout = connect_timeout()
    try:
        scheme, location = parse_address(address)
        if scheme != "tcp":
            raise ValueError(f"only tcp:// addresses are taken, not {scheme}://")
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise UsageError(f"--scheduler {address}: not a Dask scheduler's address ({exc}); "
                         f"{fix}") from None
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise UsageError(f"--scheduler {address}: no scheduler answers there "
                         f"({exc.strerror or exc}); start one (dask scheduler) and "
                         f"{fix}") from None
    return address


def connect_timeout() -> float:
    """Seconds to reach a scheduler: Dask's own setting (``distributed.comm.timeouts.
    connect``, 30 s unless configured)."""
    import dask
    from dask.utils import parse_timedelta

    return float(parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), "s"))


def connect(address: str):
    """A client of the Dask scheduler at ``address``, or one line saying why there is
    none (:class:`UsageError`): the address is checked first (:func:`reachable`), and as
    a server there that does not speak Dask's protocol may never answer, the client is
    made in a thread given twice :func:`connect_timeout`."""
    import threading

    from dask.distributed import Client

    reachable(address)
    timeout = connect_timeout()
    made: list = []

    def make():
        try:
            made.append(Client(address, timeout=timeout))
        except Exception as exc:  # noqa: BLE001  (said below, in one line)
            made.append(exc)

    thread = threading.Thread(target=make, daemon=True)
    thread.start()
    thread.join(2 * timeout)
    if made and not isinstance(made[0], Exception):
        return made[0]
    why = f"{type(made[0]).__name__}: {made[0]}" if made else \
        f"no Dask handshake within {2 * timeout:.0f} s"
    raise UsageError(f"--scheduler {address}: no Dask scheduler answered ({why}); give the "
                     "address the scheduler prints (tcp://HOST:PORT), not its dashboard's, "
                     "or drop --scheduler for a local cluster")


@contextlib.contextmanager
def _quiet_dask(quiet: bool):
    """Dask's loggers held to critical messages (then as they were) while a stopped lot's
    workers are closed: their complaints about work cut short are not the user's."""
    loggers = [logging.getLogger(n) for n in ("distributed", "tornado")] if quiet else []
    levels = [log.level for log in loggers]
    for log in loggers:
        log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for log, level in zip(loggers, levels, strict=True):
            log.setLevel(level)


def run_lot(sessions, outs, *, workers: int | None = None, scheduler: str | None = None,
            client=None, mcmc: bool = True, seed: int = 0, force: bool = False,
            say=None) -> list[MotorRun]:
    """Fit every motor of ``sessions`` into its run directory of ``outs`` on a Dask
    cluster (a local one of ``workers``, the one at ``scheduler``, or ``client``'s, which
    is closed at the end), ``say(line)`` as each finishes; the motors in the order
    given."""
    from dask.distributed import Client, LocalCluster, as_completed

    from ._cores import usable_cores

    say = say or (lambda text: None)
    names = [Path(o).name for o in outs]
    cluster = None
    if client is None and scheduler is not None:
        client = connect(scheduler)
    elif client is None:
        cluster = LocalCluster(n_workers=workers or usable_cores(), threads_per_worker=1,
                               processes=True, memory_limit=0,  # the dashboard on any
                               dashboard_address=":0",  # free port: two lots side by side
                               preload=["pmdc_bayes._lot_worker"])
        client = Client(cluster)
    futures, stopped = {}, True
    try:
        sessions = [Path(s).absolute() for s in sessions]  # as workers elsewhere see them
        futures = {client.submit(fit_motor, s, Path(o).absolute(), name=name, mcmc=mcmc,
                                 seed=seed, force=force, pure=False): k
                   for k, (s, o, name) in enumerate(zip(sessions, outs, names, strict=True))}
        done: list[MotorRun | None] = [None] * len(futures)
        for count, future in enumerate(as_completed(futures), start=1):
            k = futures[future]
            try:
                run = future.result()
            except Exception as exc:  # noqa: BLE001  (a worker's fault: this motor only)
                run = MotorRun(Path(sessions[k]), names[k], EXIT_INTERNAL,
                               error=f"internal error ({type(exc).__name__}: {exc})")
            done[k] = run
            say(f"motor {count} of {len(futures)}: {run.name}: {status_name(run.status)} "
                f"({run.seconds:.0f} s){': ' + run.error if run.error else ''}")
        stopped = False
        return done
    finally:
        with _quiet_dask(stopped):
            _close(client, cluster, futures)
        if cluster is not None:  # its workers are gone: a motor cut short left its folder
            for out in outs:
                sweep_unfinished(Path(out).absolute())


def _close(client, cluster, futures) -> None:
    """Cancel what is left and close the client and the local cluster (which stops its
    workers), each step taken whatever the one before raised.  Dask's errors in closing
    (a worker slow to stop, a scheduler gone) change nothing the lot has written, and do
    not replace the lot's own outcome or interrupt."""
    steps = [lambda: client.cancel(list(futures)), client.close]
    steps += [cluster.close] if cluster is not None else []
    for step in steps:
        with contextlib.suppress(Exception):
            step()
