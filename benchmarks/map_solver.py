"""The MAP fit's optimiser on three sessions: compile time, warm time per fit, steps, and
the MAP itself, written as JSON so that two versions of the optimiser can be compared.

Each session is measured in a fresh process (so the first fit's compilation is its
own): ``data/demo``, ``data/bench`` and the simulated 3 × 10,000 session of
``run.py``.  ``--compare A.json B.json`` prints the table of ``reports/benchmarks.md``:
the second run's figures against the first's, and how far its MAP lies from the first
one in the first one's Laplace standard deviations.

    python benchmarks/map_solver.py --out after.json
    python benchmarks/map_solver.py --compare before.json after.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SESSIONS = ("data/demo", "SIMULATED", "data/bench")
WARM_REPS = 3


def _one(path: str) -> dict:
    import numpy as np

    from pmdc_bayes.inference import _runtime as cache
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.io.loader import load_session

    session = load_session(path)
    model = build_model(session, fit_seed(session))
    c0 = cache.compile_seconds()  # starts the count
    t0 = time.perf_counter()
    fit = fit_map(model)
    first = time.perf_counter() - t0
    compile_s = cache.compile_seconds() - c0
    warm = []
    for _ in range(WARM_REPS):
        t0 = time.perf_counter()
        fit_map(model)
        warm.append(time.perf_counter() - t0)
    return {"names": list(fit.names), "theta": [float(x) for x in fit.theta],
            "sd_log": [float(x) for x in np.sqrt(np.diag(fit.cov_log))],
            "log_posterior": fit.log_posterior, "status": fit.status,
            "best_steps": fit.iterations, "all_steps": sum(s["steps"] for s in fit.starts),
            "first_s": first, "compile_s": compile_s, "warm_s": statistics.median(warm)}


def _simulated(tmp: Path) -> str:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import run

    return str(run.simulate_viscous(tmp, run.FULL["duration"]))


def measure(out: Path) -> None:
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in SESSIONS:
            path = _simulated(Path(tmp)) if name == "SIMULATED" else str(ROOT / name)
            code = (f"import json, sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); "
                    f"import map_solver; print(json.dumps(map_solver._one({path!r})))")
            done = subprocess.run([sys.executable, "-c", code], check=True,
                                  capture_output=True, text=True)
            rows[name] = json.loads(done.stdout.strip().splitlines()[-1])
            print(name, {k: v for k, v in rows[name].items()
                         if k not in ("theta", "sd_log", "names")}, flush=True)
    out.write_text(json.dumps(rows, indent=1), encoding="utf-8")


def compare(before: Path, after: Path) -> None:
    a, b = (json.loads(p.read_text(encoding="utf-8")) for p in (before, after))
    label = {"data/demo": "`data/demo`", "SIMULATED": "simulated 3 × 10,000",
             "data/bench": "`data/bench`"}
    print("| session | compile s | first fit s | warm fit s | steps (best / all) | "
          "Δ log-posterior | largest MAP shift (Laplace sd) |")
    print("|---|---|---|---|---|---|---|")
    for name in SESSIONS:
        x, y = a[name], b[name]
        shift = max(abs(p - q) / s for p, q, s in zip(y["theta"], x["theta"], x["sd_log"],
                                                      strict=True))
        print(f"| {label[name]} | {x['compile_s']:.1f} → {y['compile_s']:.1f} | "
              f"{x['first_s']:.1f} → {y['first_s']:.1f} | {x['warm_s']:.2f} → "
              f"{y['warm_s']:.2f} | {x['best_steps']} / {x['all_steps']} → "
              f"{y['best_steps']} / {y['all_steps']} | "
              f"{y['log_posterior'] - x['log_posterior']:+.2g} | {shift:.2g} |")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path)
    p.add_argument("--compare", nargs=2, type=Path)
    args = p.parse_args(argv)
    if args.compare:
        compare(*args.compare)
    else:
        measure(args.out or Path("map_solver.json"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
