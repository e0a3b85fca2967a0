"""Coloured noise on fuzzed sessions: what the verdict, the search and the intervals do
when a sensor's noise is correlated from sample to sample.

Draws sessions with :func:`pmdc_bayes.simulate.fuzz.fuzz_session` with the non-ideality
``"coloured noise"`` (every analogue speed AR(1), lag-1 correlation 0.8–0.97, sd 1–3 %
of the no-load speed; the bench simulator, written and read back by the loader) and
reports, per session: the ideal model's verdict and its Laplace z-scores (the intervals
a white-noise model gives), then the model search's chosen terms, its verdict and its
z-scores.  With ``--in-class``, the same draws without the non-ideality too, where the
search should keep the ideal model.  Each result is one JSON line in ``--log``
(resumable); the section ``## Coloured noise`` of ``reports/benchmarks.md`` is replaced.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

from _common import REPORT, replace_section
from calibration import coverage_rows, laplace_z

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.search import run_search
from pmdc_bayes.simulate.fuzz import fuzz_session

KEY = "coloured noise"


def run_one(seed: int, key: str | None, root: Path) -> dict:
    t0 = time.perf_counter()
    f = fuzz_session(seed, misspecified=key, out=root / f"s{seed}_{key is not None}")
    rec = {"seed": seed, "misspecified": key, "shapes": list(f.shapes),
           "features": sorted(f.features)}
    try:
        session = load_session(f.path)
        cf = fit_seed(session)
        model = build_model(session, cf)
        fit = fit_map(model, seed=seed)
        ideal = assess(model, fit, cf)
        rec.update(ideal=ideal.verdict, z_ideal=laplace_z(model, fit, f.truth),
                   proposed=sorted({p.nuisance for p in ideal.proposals}))
        found = run_search(session, seed=seed)
        chosen = found.chosen
        rec.update(terms=found.record["terms"], verdict=chosen.adequacy.verdict,
                   z=laplace_z(chosen.model, chosen.fit, f.truth), outcome="fitted")
    except Exception as exc:  # noqa: BLE001 - every failure is a row of the table
        rec.update(outcome="error", why=f"{type(exc).__name__}: {exc}"[:300])
    return dict(rec, seconds=time.perf_counter() - t0)


def report(records, argv) -> str:
    now = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    cmd = f"python benchmarks/coloured_noise.py {' '.join(argv)}"
    lines = ["## Coloured noise", "", f"Measured {now} by `{cmd}`. "
             "Sessions from `pmdc_bayes.simulate.fuzz` with every analogue speed read "
             "through a sensor whose noise is AR(1) (lag-1 correlation 0.8–0.97, sd 1–3 % "
             "of the no-load speed), fitted with the ideal model (`fit_map`, `assess`) and "
             "then searched (`run_search`, as a plain `fit` of a session without `[model]` "
             "does).", ""]
    for key, title in ((KEY, "coloured noise"), (None, "in-class (white noise)")):
        sub = [r for r in records if r["misspecified"] == key and r["outcome"] == "fitted"]
        if not sub:
            continue
        errors = sum(1 for r in records if r["misspecified"] == key and r["outcome"] != "fitted")
        coloured = [r for r in sub if any(t.startswith("coloured_noise") for t in r["terms"])]
        terms = Counter(" + ".join(r["terms"]) or "ideal" for r in sub)
        lines += [f"### {title.capitalize()}: {len(sub)} sessions ({errors} errors)", "",
                  f"- ideal model rejected: {sum(r['ideal'] == 'inadequate' for r in sub)}"
                  f"/{len(sub)}; coloured noise proposed by its diagnosis: "
                  f"{sum('coloured_noise' in r['proposed'] for r in sub)}/{len(sub)}",
                  f"- the search's choice holds coloured noise: {len(coloured)}/{len(sub)}; "
                  f"its verdict adequate: {sum(r['verdict'] == 'adequate' for r in sub)}"
                  f"/{len(sub)}",
                  "- chosen models: " + "; ".join(f"{n}× {t}" for t, n in terms.most_common()),
                  "", "Laplace intervals of the ideal model (white noise assumed):", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows(sub, "z_ideal")
        lines += ["", "Laplace intervals of the model the search chose:", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows(sub, "z")
        lines.append("")
    secs = sorted(r["seconds"] for r in records)
    if secs:
        lines.append(f"Per session (ideal fit and search, compilation included): median "
                     f"{secs[len(secs) // 2]:.0f} s, max {secs[-1]:.0f} s.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--n", type=int, default=20, help="sessions with coloured noise")
    ap.add_argument("--in-class", type=int, default=0, help="in-class sessions too")
    ap.add_argument("--start", type=int, default=0, help="first seed")
    ap.add_argument("--log", type=Path, default=None, help="JSON lines of results (resumed)")
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    jobs = [(s, KEY) for s in range(args.start, args.start + args.n)]
    jobs += [(s, None) for s in range(args.start, args.start + args.in_class)]
    done = {}
    if args.log and args.log.exists():
        for line in args.log.read_text().splitlines():
            r = json.loads(line)
            done[(r["seed"], r["misspecified"])] = r
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed, key in jobs:
            r = done.get((seed, key)) or run_one(seed, key, Path(tmp))
            if (seed, key) not in done and args.log:
                with args.log.open("a") as fh:
                    fh.write(json.dumps(r) + "\n")
            records.append(r)
            print(seed, key, r["outcome"], r.get("ideal"), r.get("terms"), r.get("verdict"),
                  {k: round(v, 2) for k, v in (r.get("z") or {}).items()}, flush=True)
    section = report(records, sys.argv[1:] if argv is None else argv)
    print(section)
    if not args.no_report:
        replace_section(REPORT, "Coloured noise", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
