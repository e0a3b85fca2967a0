"""A lot of motors in one ``pmdc-bayes fit``: motors per minute.

Simulates a lot of demo-shaped sessions (the demo's plan: four traces, 10,204 samples,
Coulomb friction; each motor's true Ra, K, B, J and Tc drawn ±10 % around the demo's,
its own noise seed) and fits the whole folder with one command, from an empty
compilation cache (cold) and again with the cache the first run filled (warm), with
MCMC and with ``--no-mcmc``.  Prints the table and replaces the section
``## A lot of motors`` of ``reports/benchmarks.md`` (``--no-report`` to print only).

    python benchmarks/lot.py              # 10 motors (~15 min on 2 cores)
    python benchmarks/lot.py --motors 3 --no-report
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import ROOT, cli_command, run_measured, write_table_section

from pmdc_bayes.simulate.session import simulate_session

SECTION = "A lot of motors"
SCALED = ("Ra", "K", "B", "J", "Tc")


def make_lot(folder: Path, n: int, seed: int = 7) -> None:
    """``n`` demo-shaped sessions under ``folder``, each motor's parameters drawn
    ±10 % (uniform) around the demo's."""
    plan = (ROOT / "data" / "demo" / "plan.toml").read_text(encoding="utf-8")
    rng = np.random.default_rng(seed)
    for k in range(n):
        text = plan
        for name in SCALED:
            factor = rng.uniform(0.9, 1.1)
            text = re.sub(rf"(?m)^({name} = )([0-9.eE+-]+)",
                          lambda m, f=factor: f"{m.group(1)}{float(m.group(2)) * f:.6g}",
                          text, count=1)
        session = folder / f"motor{k + 1:02d}"
        session.mkdir(parents=True)
        (session / "plan.toml").write_text(text, encoding="utf-8")
        simulate_session(session / "plan.toml", session, seed=1000 + k)


def run(lot: Path, out: Path, cache: Path, mcmc: bool, log: Path) -> dict:
    cmd = [*cli_command(), "fit", str(lot), "--out", str(out), "--quiet",
           "--allow-inadequate", "--allow-unconverged"] + ([] if mcmc else ["--no-mcmc"])
    m = run_measured(cmd, env={"PMDC_BAYES_CACHE": str(cache)}, log=log)
    with (out / "lot.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    walls = [json.loads((Path(r["run"]) / "summary.json").read_text())["diagnostics"]
             ["wall_s"]["total"] for r in rows if r["run"]]
    m.update(n=len(rows), ok=sum(r["status"] == "ok" for r in rows),
             per_motor=walls, per_minute=60.0 * len(rows) / m["wall"])
    return m


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--motors", type=int, default=10)
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        make_lot(tmp / "lot", args.motors)
        for mcmc in (True, False):
            cache = tmp / f"cache-{mcmc}"
            for state in ("cold", "warm"):
                name = f"{state}, {'MCMC' if mcmc else '--no-mcmc'}"
                m = run(tmp / "lot", tmp / f"runs-{mcmc}-{state}", cache, mcmc,
                        tmp / f"{mcmc}-{state}.log")
                if m["returncode"] not in (0, 1, 3):
                    print((tmp / f"{mcmc}-{state}.log").read_text()[-3000:], file=sys.stderr)
                    raise SystemExit(f"{name}: exit {m['returncode']}")
                rows.append((name, m))
                per = m["per_motor"]
                print(f"{name:<18} {m['wall']:7.1f} s for {m['n']} motors: "
                      f"{m['per_minute']:5.2f} motors/min; per motor first "
                      f"{per[0]:.1f} s, later median {np.median(per[1:]):.1f} s; "
                      f"{m['ok']} ok; peak {m['peak_mib']:.0f} MiB", flush=True)
    if args.no_report:
        return 0
    intro = (f"`python benchmarks/lot.py` ({{stamp}}): `pmdc-bayes fit LOT --out RUNS` on a "
             f"folder of {args.motors} simulated demo-shaped motors (four traces, 10,204 "
             "samples, Coulomb friction; Ra, K, B, J, Tc each ±10 % around the demo's), "
             "in one process, reports written. Cold: an empty compilation cache; warm: the "
             "cache the cold run filled. Wall time of the whole command; per motor, the "
             "run's own `wall_s.total` (the first motor of a process pays the loading and "
             "compiling). Goal (issue 14): ≥ 10 motors per minute with MCMC.")
    header = ("run", "wall (s)", "motors/min", "first motor (s)", "later motors, median (s)",
              "ok", "peak memory (MiB)")
    table = [(name, f"{m['wall']:.1f}", f"{m['per_minute']:.2f}", f"{m['per_motor'][0]:.1f}",
              f"{np.median(m['per_motor'][1:]):.1f}", f"{m['ok']} of {m['n']}",
              f"{m['peak_mib']:.0f}") for name, m in rows]
    write_table_section(SECTION, intro, header, ["---"] * len(header), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
