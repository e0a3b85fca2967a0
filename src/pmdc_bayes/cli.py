"""Command line: ``pmdc-bayes closed-form | simulate | fit | report``.

User mistakes (a bad session, a bad option) print one line and exit with code 2.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ._data import DEFAULT_SESSION, bundled_session_dir
from ._errors import SessionError, UsageError

__all__ = ["main"]

EXIT_USAGE = 2


def _session_path(arg: str | None) -> Path:
    if arg is None:
        return bundled_session_dir(DEFAULT_SESSION)
    p = Path(arg)
    if not p.exists() and arg in ("paper", "demo"):
        return bundled_session_dir(arg)
    return p


def _cmd_closed_form(args) -> int:
    from .closed_form import closed_form
    from .loader import load_session

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
    from .simulator import simulate_session

    plan = Path(args.plan)
    out = simulate_session(plan, Path(args.out) if args.out else plan.parent, seed=args.seed,
                           force=args.force)
    print(f"wrote a SIMULATED session to {out} (true parameters in {out / 'truth.json'}); "
          f"try: pmdc-bayes closed-form {out}")
    return 0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pmdc-bayes",
        description="Identify a permanent-magnet DC motor's parameters (Ra, La, K, B, J, "
        "Coulomb friction) from bench experiments, with honest uncertainty.",
    )
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
    sim.add_argument("--seed", type=int, metavar="N", help="random seed (default: the plan's "
                     "seed)")
    sim.add_argument("--force", action="store_true", help="replace the generated files of an "
                     "existing session in DIR (other files such as plan.toml are kept)")
    sim.set_defaults(func=_cmd_simulate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (SessionError, UsageError) as exc:
        print(f"pmdc-bayes: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("pmdc-bayes: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
