"""A production lot with ``pmdc-bayes lot``: motors per minute on 1 and 2 Dask workers,
and the population stage's cost as the lot grows.

1. ``pmdc-bayes lot`` on a folder of demo-shaped simulated motors (``benchmarks/lot.py``'s
   ``make_lot``), ``--no-mcmc`` or with MCMC, with 1 and then 2 local workers, the cache
   warm (a first run fills it): wall time, motors per minute, the ratio, peak memory;
   with ``--sizes``, lots of other sizes (the first motors of the same folder) on 2
   workers, warm: the whole command's cost per motor as the lot grows.
2. The population stage alone (``inference.population.pooling.analyse_lot``) on simulated lots of
   50, 100 and 200 motors whose evidence is draws (reweighted) or Gaussians: seconds,
   seconds per motor.

Prints the tables and replaces the section ``## A production lot`` of
``reports/benchmarks.md`` (``--no-report`` to print only).

    python benchmarks/lot_population.py --motors 10
    python benchmarks/lot_population.py --motors 100 --sizes 50
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import cli_command, run_measured, write_table_section
from lot import make_lot

from pmdc_bayes.inference.population.evidence import motor_evidence
from pmdc_bayes.inference.population.pooling import analyse_lot

SECTION = "A production lot"
NAMES = ("K", "B", "J", "Ra")
MU = np.log([0.05, 2e-5, 2e-5, 2.0])
SIGMA = np.array([0.03, 0.2, 0.05, 0.04])


def _evidence(n: int, draws: bool, seed: int = 0):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        x = MU + SIGMA * rng.standard_normal(4)
        sd = np.array([0.005, 0.05, 0.01, 0.01])
        est = x + sd * rng.standard_normal(4)
        priors = [("lognormal", float(np.exp(e + 0.5)), float(np.log(10))) for e in est]
        if draws:
            out.append(motor_evidence(f"m{k}", NAMES, priors,
                                      draws=est + sd * rng.standard_normal((4000, 4))))
        else:
            out.append(motor_evidence(f"m{k}", NAMES, priors, theta=est, cov=np.diag(sd**2)))
    return out


def stage_two() -> list[tuple]:
    rows = []
    for n in (50, 100, 200):
        for draws in (False, True):
            motors = _evidence(n, draws)
            t0 = time.perf_counter()
            record, pop = analyse_lot(motors)
            wall = time.perf_counter() - t0
            rows.append((n, "draws, reweighted" if draws else "Gaussians", f"{wall:.1f}",
                         f"{1000 * wall / n:.0f}", sum(not g for g in pop.gaussian)))
            print(rows[-1], flush=True)
    return rows


def _first(folder: Path, lot: Path, k: int) -> Path:
    """A lot of the first ``k`` motors of ``folder`` (links to their sessions)."""
    lot.mkdir()
    for session in sorted(folder.iterdir())[:k]:
        (lot / session.name).symlink_to(session, target_is_directory=True)
    return lot


def stage_one(n: int, mcmc: bool, sizes=()) -> list[tuple]:
    """The lot of ``n`` motors on 2 workers (filling the cache), 1 and 2 workers warm;
    then the first ``k`` of them for each of ``sizes`` on 2 workers, warm."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        make_lot(tmp / "lot", n)
        env = {"PMDC_BAYES_CACHE": str(tmp / "cache")}
        flags = [] if mcmc else ["--no-mcmc"]
        walls = {}

        def measure(workers, lot, key):
            out = tmp / f"runs-{workers}-{len(walls)}"
            cmd = [*cli_command(), "lot", str(lot), "--out", str(out), "--quiet",
                   "--workers", str(workers), *flags]
            m = run_measured(cmd, env=env, log=tmp / "log.txt")
            if m["returncode"] not in (0, 1, 3):
                print((tmp / "log.txt").read_text()[-3000:], file=sys.stderr)
                raise SystemExit(f"lot: exit {m['returncode']}")
            walls[key] = m
            print(key, f"{m['wall']:.1f} s", flush=True)

        for workers in (2, 1, 2):  # the first fills the cache
            measure(workers, tmp / "lot", (workers, len(walls)))
        for key, label in (((2, 0), "2 workers, cache cold"), ((1, 1), "1 worker, warm"),
                           ((2, 2), "2 workers, warm")):
            m = walls[key]
            rows.append((label, "MCMC" if mcmc else "--no-mcmc", n, f"{m['wall']:.1f}",
                         f"{60 * n / m['wall']:.2f}", f"{m['peak_mib']:.0f}"))
            print(rows[-1], flush=True)
        ratio = walls[(1, 1)]["wall"] / walls[(2, 2)]["wall"]
        rows.append(("ratio 1 / 2 workers, warm", "", n, f"{ratio:.2f}", "", ""))
        for k in sorted(set(sizes) - {n}):
            lot = _first(tmp / "lot", tmp / f"lot{k}", k) if k < n else None
            if lot is None:
                make_lot(lot := tmp / f"lot{k}", k)
            measure(2, lot, ("size", k))
        for k in sorted(set(sizes) | {n}):
            m = walls[("size", k)] if k != n else walls[(2, 2)]
            rows.append((f"lot of {k}, 2 workers, warm", "MCMC" if mcmc else "--no-mcmc", k,
                         f"{m['wall']:.1f}", f"{60 * k / m['wall']:.2f}",
                         f"{m['peak_mib']:.0f}"))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--motors", type=int, default=10)
    ap.add_argument("--mcmc", action="store_true", help="each motor with its posterior")
    ap.add_argument("--sizes", default="",
                    help="also lots of these sizes (comma-separated) on 2 workers, warm")
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    sizes = [int(k) for k in args.sizes.split(",") if k]
    first = stage_one(args.motors, args.mcmc, sizes)
    second = stage_two()
    if args.no_report:
        return 0
    command = " ".join(["python benchmarks/lot_population.py", *(argv or sys.argv[1:])])
    intro = (f"`{command}` ({{stamp}}). First table: `pmdc-bayes lot` "
             f"on {args.motors} demo-shaped simulated motors (four traces, 10,204 samples, "
             "Coulomb friction; Ra, K, B, J and Tc each ±10 % around the demo's), a local "
             "Dask cluster of 1 or 2 workers on this 2-core machine, wall time of the whole "
             "command (cluster start, fits, population stage, files) and the peak resident "
             "memory GNU time reports for it (the largest of the command and the processes "
             "it waited for).  Second table: the population stage alone "
             "(`inference.population.pooling.analyse_lot`: the independent and the correlated "
             "population sampled and compared, outliers tested, pooled values) on "
             "simulated lots of 4 parameters, each motor's evidence "
             "4,000 posterior draws (thinned to 200 and reweighted) or its Gaussian.")
    header = ("run", "fits", "motors", "wall (s)", "motors/min", "peak memory (MiB)")
    table = [tuple(str(x) for x in r) for r in first]
    table += [("**population stage**", "evidence", "motors", "seconds", "ms per motor",
               "motors reweighted")]
    table += [(f"lot of {n}", kind, str(n), wall, per, str(rew))
              for n, kind, wall, per, rew in second]
    write_table_section(SECTION, intro, header, ["---"] * len(header), table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
