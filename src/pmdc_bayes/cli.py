"""Command line: ``pmdc-bayes closed-form | simulate | fit | report``.

User mistakes (a bad session, a bad option) print one line and exit with code 2.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import threading
from pathlib import Path

from . import _signals, cachedir
from ._cli_parser import build_parser
from ._console import print_fit, run_outcome
from ._errors import EXIT_FAILED, EXIT_INTERNAL, EXIT_USAGE, FitFailed, SessionError, UsageError
from .io.bundled import session_path
from .io.units import display_unit
from .rundir import check_writable

__all__ = ["main"]



def _cmd_closed_form(args) -> int:
    from .inference.model.contradictions import refuse_contradictions
    from .io.loader import load_session
    from .paper.closed_form import closed_form

    _note_bundled(args.session)
    session = load_session(session_path(args.session))
    refuse_contradictions(session)  # before the method reads a wiring error as the motor
    cf = closed_form(session)
    code = _closed_form_warnings(cf)
    if args.json:
        print(json.dumps(cf.as_json(), indent=2))
        return code
    num, den = cf.tf22()
    print(f"Closed-form identification (reference paper, Section III): {session.motor}")
    print(f"{'parameter':<12}{'value':>14}  {'unit':<16}source")
    rows = [  # to the paper's printed precision (the method states no uncertainty)
        ("Ra", f"{cf.Ra:.4g}", display_unit("ohm"), cf.used["Ra"]),
        ("La", f"{cf.La * 1e3:.4g}", "mH", cf.used["La"]),
        ("Kt, Kb", f"{cf.K:.4g}", f"{display_unit('N*m/A')}, {display_unit('V*s/rad')}",
         cf.used["K"]),
        ("B", f"{cf.B:.4e}", display_unit("N*m*s/rad"), cf.used["B"]),
        ("J", f"{cf.J:.4e}", display_unit("kg*m^2"), cf.used["J"]),
        ("τ", f"{cf.tau:.4g}", "s", cf.used["tau"]),
        ("G", f"{cf.G:.4g}", display_unit("rad/s/V"), "equation (10)"),
    ]
    for name, val, unit, src in rows:
        print(f"{name:<12}{val:>14}  {unit:<16}{src}")
    print(
        "Transfer function (22): ω(s)/Va(s) = "
        f"{num[0]:.4g} / ({den[0]:.4g} s² + {den[1]:.4g} s + {den[2]:.4g})"
    )
    return code


def _closed_form_warnings(cf) -> int:
    """Each warning of the closed form on stderr; exit code 1 when there is one."""
    for text in cf.warnings:
        print(f"pmdc-bayes: error: {text}", file=sys.stderr)
    return EXIT_FAILED if cf.warnings else 0


def _note(text: str) -> None:
    print(f"pmdc-bayes: note: {text}", file=sys.stderr, flush=True)


def _note_bundled(arg) -> None:
    """Say so when a bundled session is used in place of a local non-session of its name."""
    from ._batch import bundled_note
    from .io.bundled import passed_over

    if (local := passed_over(arg)) is not None:
        _note(bundled_note(arg, local, session_path(arg)))


def _cmd_simulate(args) -> int:
    from .simulate.session import simulate_session

    plan = Path(args.plan)
    out = simulate_session(plan, Path(args.out) if args.out else plan.parent, seed=args.seed,
                           force=args.force)
    print(f"wrote a SIMULATED session to {out} (true parameters in {out / 'truth.json'}); "
          f"try: pmdc-bayes closed-form {out}")
    return 0


def _cmd_fit(args) -> int:
    from ._batch import expand_sessions

    if args.compare and args.add:
        raise UsageError("--compare chooses the non-idealities itself; drop --add (or drop "
                         "--compare to fit the ones you name)")
    if args.compare and args.no_search:
        raise UsageError("--compare is the model search; drop --no-search (or drop "
                         "--compare to fit the session's own model)")
    paths = expand_sessions(args.session, note=None if args.quiet else _note)
    if not args.no_cache:
        cachedir.enable()
    if len(paths) == 1:
        status = _fit_one(args, paths[0], args.out)[0]
    else:
        status = _fit_lot(args, paths)
    if not args.no_cache:
        cachedir.prune()
    return status


def _fit_lot(args, paths) -> int:
    """Each session in turn, one's bad input not stopping the others; the lot's table
    at the end (and ``lot.csv`` in ``--out``); the largest exit code of the motors."""
    from ._batch import LotEntry, claim_lot, lot_outs, lot_table, write_lot

    entries = []
    outs = lot_outs(paths, args.out, args.force)
    claim_lot(args.out)
    for k, (path, out) in enumerate(zip(paths, outs, strict=True)):
        if not args.quiet:
            print(f"== motor {k + 1} of {len(paths)}: {path}", flush=True)
        try:
            status, summary, run = _fit_one(args, path, out)
            entries.append(LotEntry(path, status, run, summary))
        except (SessionError, UsageError) as exc:
            print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
            entries.append(LotEntry(path, EXIT_USAGE, error=str(exc)))
        except FitFailed as exc:
            print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
            entries.append(LotEntry(path, EXIT_FAILED, error=str(exc)))
    if not args.quiet:
        print(lot_table(entries))
    if args.out is not None:
        table = write_lot(args.out, entries)
        if not args.quiet:
            print(f"Wrote {table}")
    return max(e.status for e in entries)


def _fit_one(args, path, out) -> tuple[int, dict, Path]:
    from .pipeline import FitOptions, run_fit

    options = FitOptions(
        mcmc=not args.no_mcmc, friction=args.friction, seed=args.seed,
        holdout=tuple(args.holdout or ()), compare_friction=args.compare_friction,
        allow_inadequate=args.allow_inadequate,
        max_sampling_seconds=args.max_sampling_seconds or None,
        add=tuple(a.replace("-", "_") for a in args.add or ()), compare=args.compare,
        search=not args.no_search, pi=args.pi)
    out, summary = run_fit(path, options, out=out, force=args.force,
                           say=_stage_printer(args), progress=_bar(args))
    if args.quiet:
        with contextlib.redirect_stdout(io.StringIO()):
            print_fit(summary, out)
    else:
        print_fit(summary, out)
    status, errors = run_outcome(summary, allow_unconverged=args.allow_unconverged,
                                 allow_inadequate=args.allow_inadequate)
    for error in errors:
        print(f"pmdc-bayes: error: {error}", file=sys.stderr)
    return status, summary, out


def _cmd_lot(args) -> int:
    from ._lot_command import run_lot_command

    return run_lot_command(args, note=None if args.quiet else _note)


def _cmd_report(args) -> int:
    from .readback import write_report

    run_dir = Path(args.run_dir)
    if not (run_dir / "summary.json").is_file():
        raise UsageError(f"{run_dir}: no summary.json here; give a directory that "
                         "'pmdc-bayes fit' wrote")
    check_writable(run_dir, what="copy the run to a writable place and report there")
    if not args.no_cache:
        cachedir.enable()
    paths = write_report(run_dir, say=_stage_printer(args))
    if not args.quiet:
        print(f"Wrote {paths['html']}, {paths['markdown'].name}, {paths['controller'].name} "
              f"and {len(paths['figures'])} figures in {run_dir / 'figures'}")
    return 0


def _stage_printer(args):
    """A line on stderr as each stage starts (on a terminal, or with --verbose), with the
    seconds since the command started; nothing with --quiet."""
    import time

    if args.quiet or not (args.verbose or sys.stderr.isatty()):
        return None
    start = time.perf_counter()
    lock = threading.Lock()  # the warm-up threads announce their compilations too

    def say(text: str) -> None:
        line = f"pmdc-bayes: [{time.perf_counter() - start:6.1f} s] {text}\n"
        with lock:
            sys.stderr.write(line)  # one write: a line is never split by another
            sys.stderr.flush()

    return say


def _bar(args):
    return False if args.quiet else (True if args.verbose else None)


def _cmd_cache(args) -> int:
    if args.action == "clear":
        freed = cachedir.clear()
        print(f"cleared {cachedir.location()} ({freed / 2**20:.1f} MB freed)")
        return 0
    report = cachedir.info()
    print(f"cache: {report['location']} (bound {report['max_bytes'] / 2**20:.0f} MB of compiled "
          "programs; PMDC_BAYES_CACHE moves it, PMDC_BAYES_CACHE_MAX_MB bounds it)")
    for part, n in report["parts"].items():
        print(f"  {part:<7}{n['files']:>6} files {n['bytes'] / 2**20:>9.1f} MB")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser({"closed-form": _cmd_closed_form, "simulate": _cmd_simulate,
                         "fit": _cmd_fit, "report": _cmd_report, "cache": _cmd_cache,
                         "lot": _cmd_lot},
                        ).parse_args(argv)
    try:
        with _signals.handled():
            return int(args.func(args) or 0)
    except (SessionError, UsageError) as exc:
        print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except FitFailed as exc:
        print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except _signals.Terminated:
        print("pmdc-bayes: terminated (no partial output is left)", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("pmdc-bayes: interrupted (no partial output is left)", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of the output went away (e.g. ``| head``)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception as exc:  # a fault of the tool, not of the user's input
        log = cachedir.save_traceback()
        print(f"pmdc-bayes: internal error ({type(exc).__name__}: {exc}); traceback saved "
              f"to {log}", file=sys.stderr)
        return EXIT_INTERNAL


def run() -> None:
    """The command's entry point: :func:`main`, then the process ends at once with its
    exit code, its output flushed.  Every file the command writes is complete and in
    place before :func:`main` returns; ending at once skips the interpreter's teardown
    of the compiled programs (about half a second).  The processes drawing figures
    are stopped first (queued figures dropped), and after a success a thread still
    making a program is waited for, as a normal exit would.  Under a profiler or a
    coverage tool the exit is a normal one."""
    code = main()
    try:
        warmup = sys.modules.get("pmdc_bayes.inference.warmup")  # imported when used
        if "pmdc_bayes.report._render" in sys.modules:  # figures queued are dropped, one
            sys.modules["pmdc_bayes.report"].stop_drawing()  # being drawn finishes
        for thread in threading.enumerate() if warmup is not None and code == 0 else ():
            if thread.name == warmup.THREAD_NAME:
                thread.join()
    except KeyboardInterrupt:
        code = 130
    if _observed():
        sys.exit(code)  # a profiler or coverage tool writes its record at a normal exit
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)


def _observed() -> bool:
    """Whether a profiler or tracer watches this process (``sys.setprofile``,
    ``sys.settrace``, or from Python 3.12 a ``sys.monitoring`` tool)."""
    if sys.getprofile() is not None or sys.gettrace() is not None:
        return True
    monitoring = getattr(sys, "monitoring", None)
    return monitoring is not None and any(monitoring.get_tool(i) is not None
                                          for i in range(6))


if __name__ == "__main__":
    run()
