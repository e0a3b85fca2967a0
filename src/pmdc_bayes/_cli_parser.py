"""The command line's arguments: sub-commands, options and their help."""

from __future__ import annotations

import argparse
import math
import textwrap
from pathlib import Path

from .io.bundled import DEFAULT_SESSION
from .io.session import NUISANCES

__all__ = ["build_parser", "EXIT_CODES"]

EXIT_CODES = """exit codes:
  0    done (model adequate, gates passed)
  1    the fit or the posterior's gates failed (--allow-unconverged to go on)
  2    bad input: one line naming the file, the place and the fix
  3    model inadequate: the data reject it (--allow-inadequate to go on)
  4    internal error: one line, the traceback saved to a log it names
  130  interrupted (143: terminated); no partial output is left"""


def _seed(text: str) -> int:
    """A random seed: a whole number from 0 to 2**32 - 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"{value} is outside 0 .. 4294967295")
    return value


def _workers(text: str) -> int:
    """A number of workers: a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError("at least one worker is needed")
    return value


def _seconds(text: str) -> float:
    """A duration in seconds, >= 0."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds >= 0, "
                                         "e.g. 120 (0: no limit)")
    return value


def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("pmdc-bayes")
    except metadata.PackageNotFoundError:
        return "unknown"


class _Parser(argparse.ArgumentParser):
    """Usage errors in one line naming the option and where the help is."""

    def error(self, message):
        self.exit(2, f"pmdc-bayes: error: {message}; see '{self.prog} --help'\n")


def _pi(text: str) -> tuple[float, float, float]:
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3) or not all(math.isfinite(v) and v >= 0 for v in values) \
            or values[0] + values[1] == 0:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give KP,KI or KP,KI,DELAY (non-negative numbers, SI: V·s/rad, "
            "V/rad, s), e.g. --pi 0.5,5")
    return (values[0], values[1], values[2] if len(values) == 3 else 0.0)


def _talk(parser, lines: str) -> None:
    """--quiet and --verbose, of the same meaning for every command that has them."""
    talk = parser.add_mutually_exclusive_group()
    talk.add_argument("--quiet", "-q", action="store_true",
                      help="print nothing but errors (the run directory holds everything)")
    talk.add_argument("--verbose", "-v", action="store_true",
                      help=f"{lines} even when not on a terminal (e.g. into a log)")


def build_parser(commands: dict) -> argparse.ArgumentParser:
    """The argument parser; ``commands`` maps each sub-command to the function that runs it."""
    p = _Parser(
        prog="pmdc-bayes",
        description=textwrap.fill("Identify a permanent-magnet DC motor's parameters (Ra, "
        "La, K, B, J, Coulomb friction) from bench experiments, with honest uncertainty.  "
        "SESSION is a session directory, or 'demo', 'paper' or 'bench' for the bundled "
        "ones.", 79),
        epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_closed_form(sub, commands['closed-form'])
    _add_simulate(sub, commands['simulate'])
    _add_fit(sub, commands['fit'])
    _add_report(sub, commands['report'])
    _add_lot(sub, commands['lot'])
    _add_cache(sub, commands['cache'])
    return p


# each sub-command: its options and help
def _add_closed_form(sub, run) -> None:
    cf = sub.add_parser(
        "closed-form",
        help="the reference paper's closed-form method (Table I, tau, G, transfer function)",
        description="Apply the reference paper's closed-form method to a session and print "
        "a table like its Table I, the time constant, the gain and transfer function (22).",
    )
    cf.add_argument("session", nargs="?", help=f"session directory (default: bundled "
                    f"'{DEFAULT_SESSION}')")
    cf.add_argument("--json", action="store_true", help="print one JSON object with SI floats")
    cf.set_defaults(func=run)


def _add_simulate(sub, run) -> None:
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
    sim.set_defaults(func=run)


def _add_fit(sub, run) -> None:
    ft = sub.add_parser(
        "fit",
        help="closed form, joint MAP fit, adequacy checks, MCMC posterior and the report",
        description=textwrap.fill("Identify the motor from a session: the paper's closed "
        "form (or a seed "
        "from the data) starts a joint Levenberg-Marquardt fit of every trace, steady table "
        "and operating point; the adequacy checks say whether the data reject the model and "
        "what to add; an emcee posterior (unless --no-mcmc) gives the uncertainty.  Writes "
        "OUT/summary.json, posterior.nc, report.html, report.md, figures/ and controller.json, "
        "all at once when complete.", 79),
        epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ft.add_argument("session", nargs="*", help=f"session directory (default: bundled "
                    f"'{DEFAULT_SESSION}'); several, or a folder of session directories, fit "
                    "a lot in one process, sharing compiled programs")
    ft.add_argument("--out", type=Path, help="run directory (default: reports/<session>-<time>);"
                    " with several sessions, the folder that gets one run per session and "
                    "lot.csv, the lot's table")
    ft.add_argument("--force", action="store_true", help="replace an existing --out directory")
    ft.add_argument("--no-mcmc", action="store_true", help="stop after the MAP fit")
    ft.add_argument("--friction", choices=("viscous", "coulomb"),
                    help="friction model (default: the session's)")
    ft.add_argument("--seed", type=_seed, default=0, help="random seed (default 0)")
    ft.add_argument("--holdout", action="append", metavar="TRACE",
                    help="fit without this trace (repeatable)")
    ft.add_argument("--pi", type=_pi, metavar="KP,KI[,DELAY]",
                    help="stability margins of a PI speed loop (Va from the speed error, "
                    "kp in V·s/rad, ki in V/rad, an optional loop delay in s) at the estimate "
                    "and over the posterior draws")
    ft.add_argument("--compare-friction", action="store_true",
                    help="also fit and sample the other friction model and compare the two "
                    "by PSIS-LOO (ArviZ)")
    ft.add_argument("--max-sampling-seconds", type=_seconds, default=0.0, metavar="S",
                    help="also stop the sampler after S seconds of sampling if it has not "
                    "converged by then, saying how long it would need (default 0: no limit; "
                    "the sampler stops by its step budget, the same on any machine, and a "
                    "wall-time limit makes the result depend on the machine's load); a "
                    "posterior stopped so fails its gates")
    ft.add_argument("--allow-unconverged", action="store_true",
                    help="exit 0 even if the fit or the sampler fails its checks")
    ft.add_argument("--add", action="append", metavar="NUISANCE",
                    choices=tuple(k.replace("_", "-") for k in NUISANCES) + NUISANCES,
                    help="also fit this non-ideality of the rig (repeatable): dead-time (one "
                    "per trace), voltage-drop (brushes and driver), speed-lag or current-lag "
                    "(a first-order sensor or filter lag), unknown-load (a constant and a "
                    "viscous drag of its own on every trace; [model] unknown_load = "
                    "[\"trace\", ...] "
                    "names the traces), speed-gain, speed-offset, current-gain or "
                    "current-offset (a calibration error of the traces' sensor), "
                    "source-resistance (the logged voltage is the supply's), "
                    "current-limit (the driver's, fitted; current_limit = A in [model] "
                    "gives its setting), dead-zone (the driver's, a width each way), "
                    "open-at-zero (the driver opens the armature at a zero command, as an "
                    "L298N with its enable low: the rotor coasts instead of braking), "
                    "coloured-noise (each analogue channel's noise as AR(1), its correlation "
                    "fitted; [model] coloured_noise = [\"trace\", ...] names the traces); "
                    "same as [model] in session.toml")
    ft.add_argument("--compare", action="store_true",
                    help="search for the rig's model from the session's own: add, one at a time,"
                    " the non-idealities the adequacy verdict proposes, then any other of "
                    "+ dead-time, + voltage-drop, + speed-lag, + current-lag, + "
                    "unknown-load, + speed-gain, + speed-offset, + current-gain, + "
                    "current-offset, + source-resistance, + current-limit, + dead-zone, + "
                    "open-at-zero, + "
                    "Coulomb friction, and + coloured-noise last (also where the data do "
                    "not reject the model: an addition the evidence strongly supports is "
                    "taken), remove what the evidence does not "
                    "support, stop when the data no longer reject the model and no addition"
                    " is clearly better (Laplace evidence); then run the chosen model and "
                    "write it as [model] into the run's copy of session.toml.  A plain fit "
                    "of a session without [model] (nor --add or --friction) searches too "
                    "when the ideal model is rejected")
    ft.add_argument("--no-search", action="store_true",
                    help="fit the session's model as it is, even when it declares no [model] "
                    "and the data reject the ideal model")
    ft.add_argument("--allow-inadequate", action="store_true",
                    help="go on (sample the posterior, exit 0) even when the adequacy checks "
                    "reject the model; every value stays labelled as conditional on it")
    ft.add_argument("--no-cache", action="store_true",
                    help="neither read nor store compiled programs in the cache directory")
    _talk(ft, "a line per stage and the sampler's bar")
    ft.set_defaults(func=run)


def _add_report(sub, run) -> None:
    rp = sub.add_parser(
        "report",
        help="regenerate the uncertainty report of a finished run",
        description="Write RUN_DIR/report.html (self-contained), RUN_DIR/report.md, "
        "RUN_DIR/figures/*.png and RUN_DIR/controller.json from RUN_DIR/summary.json, "
        "RUN_DIR/posterior.nc (if present) and the run's own copy of the session "
        "(RUN_DIR/session, checked against the SHA-256 summary.json records; the original "
        "session, checked alike, only when the run holds no intact copy).",
    )
    rp.add_argument("run_dir", metavar="RUN_DIR", help="a directory written by 'pmdc-bayes fit'")
    rp.add_argument("--no-cache", action="store_true",
                    help="neither read nor store compiled programs in the cache directory")
    _talk(rp, "a line per stage")
    rp.set_defaults(func=run)


def _add_lot(sub, run) -> None:
    lt = sub.add_parser(
        "lot",
        help="a production lot: every motor fitted (on a Dask cluster), then the lot as a "
        "population with its outliers",
        description=textwrap.fill("Fit each motor's session on its own, on a local Dask "
        "cluster of one worker per core (--workers N) or an existing one (--scheduler), "
        "then the lot as a log-normal population: its median and spread per parameter, "
        "each motor's values pooled toward it, and the motors the population makes "
        "improbable flagged as outliers (a posterior predictive p-value per motor, "
        "Holm-corrected at 5 % over the lot).  Writes one run per motor and RUNS/lot.csv, "
        "RUNS/lot.json, RUNS/population.nc and RUNS/lot.png.  Exits 0 when every motor "
        "passed and none is an outlier, else the largest of the motors' exit codes, and "
        "at least 1 when a motor is flagged.", 79),
        epilog=EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    lt.add_argument("session", nargs="+", metavar="SESSION",
                    help="session directories, or folders whose subfolders hold them")
    lt.add_argument("--out", metavar="RUNS", type=Path, required=True,
                    help="folder that gets one run per motor and the lot's files")
    lt.add_argument("--workers", type=_workers, metavar="N",
                    help="local Dask workers (default: one per core)")
    lt.add_argument("--scheduler", metavar="ADDRESS",
                    help="an existing Dask scheduler (e.g. tcp://host:8786) in place of a "
                    "local cluster; its workers must reach the sessions and RUNS")
    lt.add_argument("--no-mcmc", action="store_true",
                    help="each motor's MAP and Laplace approximation only (faster; the "
                    "population reads their Gaussians)")
    lt.add_argument("--seed", type=_seed, default=0, metavar="N", help="random seed")
    lt.add_argument("--force", action="store_true",
                    help="replace the lot's earlier runs and files in RUNS")
    _talk(lt, "a line per motor")
    lt.set_defaults(func=run)


def _add_cache(sub, run) -> None:
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
    ch.set_defaults(func=run)
