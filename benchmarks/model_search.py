"""What the model search (``fit --compare``) costs: the whole search on a 2-trace bench
session, in a fresh process with an empty compile cache (cold) and again in a fresh
process with that cache filled (warm), and each candidate's share (MAP fit, adequacy
checks, evidence) in the warm run.

Sessions: the catalogue's bench with a 3 ms dead time (2 steps, currents and speeds,
1,202 samples), the same bench with a 3 ms dead time and a 1 V brush drop at once, and
the bundled demo (4 traces, 10,204 samples, Coulomb friction).

Prints the table and replaces the section ``## Model search`` of
``reports/benchmarks.md`` (``--no-report`` to print only).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime

SESSIONS = {
    "dead time (2 steps, speed and current, 1,202 samples)": "dead time",
    "dead time + brush drop (2 steps, speed and current, 1,202 samples)": "combination",
    "the bundled demo (4 traces, speed and current, 10,204 samples, Coulomb)": "demo",
}


def _session(which):
    from pmdc_bayes.simulate.bench import BenchMotor, bench_session
    from pmdc_bayes.simulate.cases import MOTOR, STEADY_VOLTAGES, STEPS, case_session

    if which == "demo":
        from pmdc_bayes.io.bundled import session_path
        from pmdc_bayes.io.loader import load_session

        return load_session(session_path("demo"))
    if which != "combination":
        return case_session(which, seed=2)
    return bench_session(BenchMotor(**MOTOR, dead_time=3e-3, voltage_drop=1.0), STEPS, seed=3,
                         steady_voltages=STEADY_VOLTAGES)


def child(which: str, cache: str) -> None:
    """One search in this process, the cache at ``cache``; its record on stdout as JSON."""
    from pmdc_bayes.cachedir import use_cache
    from pmdc_bayes.search import search_model

    use_cache(cache)
    session = _session(which)
    stamps = []
    t0 = time.perf_counter()
    sel = search_model(session, say=lambda text: stamps.append(time.perf_counter()))
    wall = time.perf_counter() - t0
    steps = [b - a for a, b in zip([t0, *stamps[:-1]], stamps, strict=True)]
    print(json.dumps({"wall": wall, "fits": sel["fits"], "chosen": sel["recommended"],
                      "verdict": next(r["verdict"] for r in sel["candidates"]
                                      if r["decision"] == "chosen"),
                      "per_candidate": steps}))


def _run(which: str, cache: str) -> dict:
    env = dict(os.environ, PMDC_BAYES_CACHE=cache)
    proc = subprocess.run([sys.executable, __file__, "--child", which, cache], env=env,
                          capture_output=True, text=True, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--no-report", action="store_true")
    parser.add_argument("--only", choices=sorted(SESSIONS.values()), action="append",
                        help="run only this session (repeatable; prints, leaves the "
                        "report as it is)")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(*args.child)
        return
    rows = []
    for title, which in SESSIONS.items():
        if args.only and which not in args.only:
            continue
        with tempfile.TemporaryDirectory() as cache:
            cold = _run(which, cache)
            warm = _run(which, cache)
        per = warm["per_candidate"]
        rows.append(f"| {title} | {cold['fits']} | {cold['chosen']} ({cold['verdict']}) | "
                    f"{cold['wall']:.1f} | {warm['wall']:.1f} | "
                    f"{min(per):.2f}–{max(per):.2f} (median {sorted(per)[len(per) // 2]:.2f}) |")
        print(rows[-1], flush=True)
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    section = "\n".join([
        "## Model search", "",
        f"Measured {stamp} by `python benchmarks/model_search.py` on the shared 2-core "
        "machine (other jobs running): the whole search (`search.search_model`, as `fit "
        "--compare --no-mcmc` runs it before the chosen model's own fit) in a fresh process "
        "with an empty compile cache (cold), then in another with that cache (warm); per "
        "candidate, the warm run's seconds from one candidate's line to the next (model "
        "built, MAP from the usual starts and the nested one, adequacy checks, evidence).",
        "", "| session | fits | chosen (verdict) | cold (s) | warm (s) | "
        "per candidate, warm (s) |", "|---|---:|---|---:|---:|---|", *rows, ""])
    if not args.no_report and not args.only:
        sys.path.insert(0, os.path.dirname(__file__))
        from _common import REPORT, replace_section

        replace_section(REPORT, "Model search", section)
    print(section)


if __name__ == "__main__":
    main()
