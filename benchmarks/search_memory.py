"""What a model search holds in memory: ``pmdc-bayes fit SESSION --compare --no-mcmc`` in
a fresh process with an empty compile cache, its wall time, peak resident memory, the
fits it made and the model chosen; for this tree and, with ``--against``, another
source tree (an earlier commit's ``src``), one after the other.

    python benchmarks/search_memory.py [SESSION] [--against /path/to/other/src]

SESSION defaults to the red team's undeclared tacho lag
(``tests/scenarios/sessions/tacho_lag_column``: Coulomb friction declared, so every
candidate needs the stick-slip solution, the costliest to compile and to hold).
Peak memory is GNU ``time -v``'s where present (see ``_common.run_measured``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import ROOT, run_measured  # noqa: E402

DEFAULT = ROOT / "tests" / "scenarios" / "sessions" / "tacho_lag_column"


def measure(src: Path, session: Path, work: Path) -> dict:
    """One search from an empty cache with the package of ``src``."""
    out = work / "run"
    env = {"PMDC_BAYES_CACHE": str(work / "cache"), "PYTHONPATH": str(src)}
    got = run_measured([sys.executable, "-m", "pmdc_bayes", "fit", str(session), "--compare",
                        "--no-mcmc", "--out", str(out)], env=env, log=work / "log.txt")
    if (out / "summary.json").exists():
        sel = json.loads((out / "summary.json").read_text())["model_selection"]
        got.update(fits=sel["fits"], chosen=sel["recommended"])
    return got


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("session", nargs="?", type=Path, default=DEFAULT)
    parser.add_argument("--against", type=Path, help="another tree's src, measured after")
    args = parser.parse_args()
    trees = [("this tree", ROOT / "src")] + ([("against", args.against)] if args.against else [])
    print(f"fit {args.session} --compare --no-mcmc, empty compile cache")
    print(f"{'tree':<10}{'wall (s)':>10}{'peak (GiB)':>12}{'fits':>6}{'exit':>6}  chosen")
    for name, src in trees:
        with tempfile.TemporaryDirectory() as tmp:
            r = measure(src, args.session, Path(tmp))
        print(f"{name:<10}{r['wall']:>10.0f}{r['peak_mib'] / 1024:>12.2f}{r.get('fits', '—'):>6}"
              f"{r['returncode']:>6}  {r.get('chosen', '—')}")


if __name__ == "__main__":
    main()
