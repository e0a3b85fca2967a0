"""Command line: ``pmdc-bayes closed-form | simulate | fit | report``.

User mistakes (a bad session, a bad option) print one line and exit with code 2.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
from pathlib import Path

from . import cachedir
from ._console import print_fit
from ._errors import SessionError, UsageError
from .io.bundled import DEFAULT_SESSION, bundled_session_dir
from .rundir import check_writable

__all__ = ["main"]

EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INADEQUATE = 3
EXIT_INTERNAL = 4


def _session_path(arg: str | None) -> Path:
    if arg is None:
        return bundled_session_dir(DEFAULT_SESSION)
    p = Path(arg)
    if not p.exists() and arg in ("paper", "demo"):
        return bundled_session_dir(arg)
    return p


def _cmd_closed_form(args) -> int:
    from .io.loader import load_session
    from .paper.closed_form import closed_form

    session = load_session(_session_path(args.session))
    cf = closed_form(session)
    if args.json:
        print(json.dumps(cf.as_json(), indent=2))
        return 0
    num, den = cf.tf22()
    print(f"Closed-form identification (reference paper, Section III): {session.motor}")
    print(f"{'parameter':<12}{'value':>14}  {'unit':<16}source")
    rows = [
        ("Ra", f"{cf.Ra:.4g}", "ohm", cf.used["Ra"]),
        ("La", f"{cf.La * 1e3:.4g}", "mH", cf.used["La"]),
        ("Kt, Kb", f"{cf.K:.4g}", "N*m/A, V*s/rad", cf.used["K"]),
        ("B", f"{cf.B:.4e}", "N*m*s/rad", cf.used["B"]),
        ("J", f"{cf.J:.4e}", "kg*m^2", cf.used["J"]),
        ("tau", f"{cf.tau:.4g}", "s", cf.used["tau"]),
        ("G", f"{cf.G:.4g}", "rad/s per V", "equation (10)"),
    ]
    for name, val, unit, src in rows:
        print(f"{name:<12}{val:>14}  {unit:<16}{src}")
    print(
        "Transfer function (22): w(s)/Va(s) = "
        f"{num[0]:.4g} / ({den[0]:.4g} s^2 + {den[1]:.4g} s + {den[2]:.4g})"
    )
    return 0


def _cmd_simulate(args) -> int:
    from .simulate.session import simulate_session

    plan = Path(args.plan)
    out = simulate_session(plan, Path(args.out) if args.out else plan.parent, seed=args.seed,
                           force=args.force)
    print(f"wrote a SIMULATED session to {out} (true parameters in {out / 'truth.json'}); "
          f"try: pmdc-bayes closed-form {out}")
    return 0


def _cmd_fit(args) -> int:
    from .pipeline import run_fit

    if args.compare and args.add:
        raise UsageError("--compare chooses the non-idealities itself; drop --add (or drop "
                         "--compare to fit the ones you name)")
    if not args.no_cache:
        cachedir.enable()
    out, summary = run_fit(
        _session_path(args.session), out=args.out, force=args.force, mcmc=not args.no_mcmc,
        friction=args.friction, seed=args.seed, holdout=args.holdout or (),
        compare_friction=args.compare_friction, allow_inadequate=args.allow_inadequate,
        add=tuple(a.replace("-", "_") for a in args.add or ()), compare=args.compare,
    )
    if not args.no_cache:
        cachedir.prune()
    adequate = print_fit(summary, out)
    status = 0
    if not adequate:
        first = next(f for f in summary["adequacy"]["findings"] if f["severity"] == "fail")
        print(f"pmdc-bayes: error: model inadequate: {first['where']}: {first['message']}"
              + ("" if args.allow_inadequate else " (see the report; rerun with "
                 "--allow-inadequate to go on)"), file=sys.stderr)
        if not args.allow_inadequate:
            return EXIT_INADEQUATE
    if summary["fit"]["status"] != "converged" and not args.allow_unconverged:
        print(f"pmdc-bayes: error: the fit did not converge: {summary['fit']['message']}",
              file=sys.stderr)
        status = EXIT_FAILED
    diag = summary["diagnostics"]
    if diag.get("gates_passed") is False and not args.allow_unconverged:
        print("pmdc-bayes: error: the posterior failed its convergence gates: "
              + "; ".join(diag["failures"]) + " (rerun with --allow-unconverged to accept)",
              file=sys.stderr)
        status = EXIT_FAILED
    return status


def _cmd_report(args) -> int:
    from .report import write_report

    run_dir = Path(args.run_dir)
    if not (run_dir / "summary.json").is_file():
        raise UsageError(f"{run_dir}: no summary.json here; give a directory that "
                         "'pmdc-bayes fit' wrote")
    check_writable(run_dir, what="copy the run to a writable place and report there")
    if not args.no_cache:
        cachedir.enable()
    paths = write_report(run_dir)
    print(f"Wrote {paths['html']}, {paths['markdown'].name}, {paths['controller'].name} and "
          f"{len(paths['figures'])} figures in {run_dir / 'figures'}")
    return 0


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


def _seed(text: str) -> int:
    """A random seed: a whole number from 0 to 2**32 - 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"{value} is outside 0 .. 4294967295")
    return value


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("pmdc-bayes")
    except metadata.PackageNotFoundError:
        return "unknown"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pmdc-bayes",
        description="Identify a permanent-magnet DC motor's parameters (Ra, La, K, B, J, "
        "Coulomb friction) from bench experiments, with honest uncertainty.",
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    cf = sub.add_parser(
        "closed-form",
        help="the reference paper's closed-form method (Table I, tau, G, transfer function)",
        description="Apply the reference paper's closed-form method to a session and print "
        "a table like its Table I, the time constant, the gain and transfer function (22).",
    )
    cf.add_argument("session", nargs="?", help=f"session directory (default: bundled "
                    f"'{DEFAULT_SESSION}')")
    cf.add_argument("--json", action="store_true", help="print one JSON object with SI floats")
    cf.set_defaults(func=_cmd_closed_form)
    sim = sub.add_parser(
        "simulate",
        help="write a simulated session (bench, steady points, traces) from a plan",
        description="Simulate the bench work a plan describes (true parameters, bench "
        "uncertainties, operating points, steady tables, traces with sensor noise, "
        "quantisation and delay) and write it as a session directory: session.toml, CSV "
        "files and truth.json.  The same plan and seed give byte-identical files.  "
        "Example: pmdc-bayes simulate data/demo/plan.toml --out data/demo --force",
    )
    sim.add_argument("plan", help="the plan TOML file (see data/demo/plan.toml)")
    sim.add_argument("--out", metavar="DIR", help="session directory to write (default: the "
                     "plan's directory)")
    sim.add_argument("--seed", type=_seed, metavar="N", help="random seed (default: the plan's "
                     "seed)")
    sim.add_argument("--force", action="store_true", help="replace the generated files of an "
                     "existing session in DIR (other files such as plan.toml are kept)")
    sim.set_defaults(func=_cmd_simulate)
    ft = sub.add_parser(
        "fit",
        help="closed form, then the joint MAP fit of every trace and steady point",
        description="Identify the motor from a session: the paper's closed form seeds a joint "
        "Levenberg-Marquardt fit of every trace, steady table and operating point, with Laplace "
        "uncertainty and an identifiability report.  Writes OUT/summary.json.",
    )
    ft.add_argument("session", nargs="?", help=f"session directory (default: bundled "
                    f"'{DEFAULT_SESSION}')")
    ft.add_argument("--out", type=Path, help="run directory (default: reports/<session>-<time>)")
    ft.add_argument("--force", action="store_true", help="replace an existing --out directory")
    ft.add_argument("--no-mcmc", action="store_true", help="stop after the MAP fit")
    ft.add_argument("--friction", choices=("viscous", "coulomb"),
                    help="friction model (default: the session's)")
    ft.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    ft.add_argument("--holdout", action="append", metavar="TRACE",
                    help="fit without this trace (repeatable)")
    ft.add_argument("--compare-friction", action="store_true",
                    help="also fit and sample the other friction model and compare the two "
                    "by PSIS-LOO (ArviZ)")
    ft.add_argument("--allow-unconverged", action="store_true",
                    help="exit 0 even if the fit or the sampler fails its checks")
    ft.add_argument("--add", action="append", metavar="NUISANCE",
                    choices=("dead-time", "voltage-drop", "speed-lag", "current-lag",
                             "dead_time", "voltage_drop", "speed_lag", "current_lag"),
                    help="also fit this non-ideality of the rig (repeatable): dead-time (one "
                    "per trace), voltage-drop (brushes and driver), speed-lag or current-lag "
                    "(a first-order sensor or filter lag); same as [model] in session.toml")
    ft.add_argument("--compare", action="store_true",
                    help="fit the candidate sets of rig non-idealities (ideal, + dead-time, "
                    "+ speed-lag, + voltage-drop, + voltage-drop with either), check each for "
                    "adequacy, compare the adequate ones by LOO, and run the simplest "
                    "adequate one")
    ft.add_argument("--allow-inadequate", action="store_true",
                    help="go on (sample the posterior, exit 0) even when the adequacy checks "
                    "reject the model; every value stays labelled as conditional on it")
    ft.add_argument("--no-cache", action="store_true",
                    help="neither read nor store compiled programs in the cache directory")
    ft.set_defaults(func=_cmd_fit)
    rp = sub.add_parser(
        "report",
        help="regenerate the uncertainty report of a finished run",
        description="Write RUN_DIR/report.html (self-contained), RUN_DIR/report.md, "
        "RUN_DIR/figures/*.png and RUN_DIR/controller.json from RUN_DIR/summary.json, "
        "RUN_DIR/posterior.nc (if present) and the session the summary names.",
    )
    rp.add_argument("run_dir", metavar="RUN_DIR", help="a directory written by 'pmdc-bayes fit'")
    rp.add_argument("--no-cache", action="store_true",
                    help="neither read nor store compiled programs in the cache directory")
    rp.set_defaults(func=_cmd_report)
    ch = sub.add_parser(
        "cache",
        help="show or clear the cache of compiled programs",
        description="The cache keeps compiled programs across runs (a session of a shape "
        "seen before fits without compiling) and the logs of internal errors; it lives in "
        "$PMDC_BAYES_CACHE or ~/.cache/pmdc-bayes and is bounded by "
        "$PMDC_BAYES_CACHE_MAX_MB (default 2000).  'clear' deletes only what pmdc-bayes "
        "wrote there.",
    )
    ch.add_argument("action", choices=("info", "clear"), nargs="?", default="info")
    ch.set_defaults(func=_cmd_cache)
    return p


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is so that partial output is cleaned up."""


def _on_sigterm(signum, frame):
    raise _Terminated


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    in_main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if in_main else None
    try:
        return int(args.func(args) or 0)
    except (SessionError, UsageError) as exc:
        print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except _Terminated:
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
    finally:
        if in_main:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
