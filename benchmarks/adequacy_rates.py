"""Detection and false-alarm rates of the adequacy checks, per case and per check.

Fits the ideal motor (MAP with the global search, then every adequacy check) to

* each misspecified bench of ``pmdc_bayes.simulate.cases.CASES`` under several noise
  seeds: how often the verdict is "inadequate" (detection) and how often the diagnosis
  names the cause (diagnosis);
* the same benches with no current anywhere (speed only);
* motors drawn by ``random_motor`` that the ideal model describes exactly (two steps;
  with Coulomb friction; speed only with a steady table): how often
  the verdict is "inadequate" (false alarm), and which checks raise the failures and
  warnings.

Prints the tables and replaces the section ``## Adequacy checks`` of
``reports/benchmarks.md`` (``--no-report`` to print only).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from collections import Counter
from datetime import UTC, datetime

import numpy as np
from _common import REPORT, replace_section

from pmdc_bayes.inference.adequacy import assess
from pmdc_bayes.inference.fit import fit_map
from pmdc_bayes.inference.objective import build_model
from pmdc_bayes.inference.seed import fit_seed
from pmdc_bayes.simulate.bench import bench_session
from pmdc_bayes.simulate.cases import CASES, SPEED_ONLY, case_session, random_motor


def _assess(session, seed):
    t0 = time.perf_counter()
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=seed)
    a = assess(model, fit, cf)
    return a, time.perf_counter() - t0


def _says(a, words):
    text = " ".join(a.diagnosis).lower()
    return all(w in text for w in words)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--seeds", type=int, default=5, help="noise seeds per case")
    ap.add_argument("--motors", type=int, default=60, help="in-class random motors")
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)

    rows, times = [], []
    for speed_only in (False, True):
        for case in [None, *CASES]:
            hits = named = 0
            for seed in range(args.seeds):
                session = case_session(case, seed=seed, speed_only=speed_only,
                                       steady_current=not speed_only)
                a, dt = _assess(session, seed)
                times.append(dt)
                flagged = a.verdict == "inadequate"
                hits += flagged
                words = (SPEED_ONLY if speed_only else {k: v[1] for k, v in CASES.items()}
                         ).get(case)
                named += flagged and words is not None and _says(a, words)
            label = (case or "ideal (false alarm)") + (", speed only" if speed_only else "")
            rows.append((label, hits, named if words else None))
            print(f"{label:36s} inadequate {hits}/{args.seeds}"
                  + (f", diagnosis named {named}/{args.seeds}" if case else ""), flush=True)

    rng = np.random.default_rng(2026)
    variants = {"two steps, viscous": args.motors, "two steps, Coulomb friction": args.motors // 3,
                "speed only, steady table without current": args.motors // 3}
    in_class = []
    fails, warns = Counter(), Counter()
    for variant, n in variants.items():
        alarms = 0
        for k in range(n):
            motor, steps = random_motor(rng)
            kw = {}
            if "Coulomb" in variant:
                w_final = motor.K * 12.0 / (motor.Ra * motor.B + motor.K**2)
                motor = dataclasses.replace(motor, Tc=float(rng.uniform(0.05, 0.3)) * motor.B
                                            * w_final)
                kw = dict(friction="coulomb")
            if "speed only" in variant:
                steps = tuple(dataclasses.replace(s, log_current=False) for s in steps)
                kw = dict(steady_voltages=(3.0, 6.0, 9.0, 12.0))
            session = bench_session(motor, steps, seed=k, **kw)
            if "speed only" in variant:
                session = dataclasses.replace(session, steady_tables=tuple(
                    dataclasses.replace(t, current=None) for t in session.steady_tables))
            a, dt = _assess(session, k)
            times.append(dt)
            alarms += a.verdict != "adequate"
            for f in a.findings:
                (fails if f.severity == "fail" else warns)[f.check] += 1
        in_class.append((variant, alarms, n))
        print(f"in-class motors, {variant}: {alarms}/{n} inadequate", flush=True)
    n = sum(v for v in variants.values())
    alarms = sum(a for _, a, _ in in_class)
    print(f"failures by check {dict(fails)}; warnings by check {dict(warns)}")

    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines = ["## Adequacy checks", "",
             f"Measured {when} by `python benchmarks/adequacy_rates.py --seeds {args.seeds} "
             f"--motors {args.motors}`.  Each row fits the ideal motor (MAP, global "
             "search) and runs every adequacy check; the benches come from "
             "`pmdc_bayes.simulate.cases`.", "",
             "| bench | verdict inadequate | diagnosis names the cause |", "|---|---:|---:|"]
    for label, hits, named in rows:
        lines.append(f"| {label} | {hits}/{args.seeds} | "
                     f"{'' if named is None else f'{named}/{args.seeds}'} |")
    lines += ["", "A blank diagnosis cell: nothing to name (the ideal bench), or nothing the "
              "data can show (a supply source resistance on a speed-only bench adds to Ra, "
              "which speed alone does not separate from J: 'adequate' is the right verdict "
              "there).", "", "In-class motors (`random_motor`, the ideal model is right):", "",
              "| motors | inadequate (false alarm) |", "|---|---:|"]
    for variant, a_k, n_k in in_class:
        lines.append(f"| {variant} | {a_k}/{n_k} |")
    lines += [f"| **all** | **{alarms}/{n} ({100 * alarms / n:.1f} %)** |", "",
              "| check | motors failing it | motors warned by it |", "|---|---:|---:|"]
    for check in sorted(set(fails) | set(warns)):
        lines.append(f"| {check} | {fails[check]}/{n} | {warns[check]}/{n} |")
    lines += ["", f"Fit + checks per session: median {np.median(times):.2f} s, "
              f"max {np.max(times):.1f} s (the first includes compilation)."]
    section = "\n".join(lines) + "\n"
    print(section)
    if not args.no_report:
        replace_section(REPORT, "Adequacy checks", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
