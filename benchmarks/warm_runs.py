"""A warm ``pmdc-bayes fit data/demo``, repeated: its wall time and stages, and the same
for another source tree (an earlier commit's ``src``), alternated run by run so that a
change in the machine's speed falls on both.

    python benchmarks/warm_runs.py --runs 5 [--against /path/to/other/src]

Each tree gets its own fresh compilation cache, filled by one run first (not counted).
Printed: per tree the median whole-process wall time, the median of each stage
(``summary.json``'s ``diagnostics.wall_s``) and of the seconds spent making JAX
programs (``compile_s``), and the ratio of the medians.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(src: Path, cache: Path, out: Path) -> dict:
    env = dict(os.environ, PMDC_BAYES_CACHE=str(cache), PYTHONPATH=str(src))
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pmdc_bayes", "fit", str(ROOT / "data/demo"),
                           "--out", str(out), "--force"], env=env, capture_output=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{src}: exit {done.returncode}: {done.stderr.decode()[-400:]}")
    diag = json.loads((out / "summary.json").read_text())["diagnostics"]
    return {"wall": wall, **{f"{k} (s)": v for k, v in diag["wall_s"].items()},
            "compile (s)": diag["compile_s"]["total"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--against", type=Path, default=None, help="another tree's src")
    args = ap.parse_args(argv)
    trees = {"this tree": ROOT / "src"}
    if args.against is not None:
        trees["against"] = args.against.resolve()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for k, src in enumerate(trees.values()):
            _run(src, tmp / f"cache{k}", tmp / "out")
        runs = {name: [] for name in trees}
        for _ in range(args.runs):
            for k, (name, src) in enumerate(trees.items()):
                runs[name].append(_run(src, tmp / f"cache{k}", tmp / "out"))
    keys = list(runs["this tree"][0])
    print("| tree | " + " | ".join(keys) + " |")
    print("|---|" + "---:|" * len(keys))
    med = {name: {k: statistics.median(r[k] for r in rs) for k in keys}
           for name, rs in runs.items()}
    for name, m in med.items():
        print(f"| {name} | " + " | ".join(f"{m[k]:.2f}" for k in keys) + " |")
    if "against" in med:
        print(f"wall, this tree / against: {med['this tree']['wall'] / med['against']['wall']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
