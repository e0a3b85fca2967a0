"""Bad readings in fuzzed sessions: how often the verdict finds one, and by which check.

Draws in-class sessions with :func:`pmdc_bayes.simulate.fuzz.fuzz_session` (the
independent bench simulator, every session shape and sensor), and writes into one
logged speed column of one driven trace (a random reading, away from the first and
last) either a logger's sentinel (65535 in the file's own unit; with ``--run L``, on
``L`` readings in a row) or a spike of ``--size`` times the column's own noise (its
model-free level, in the file's unit); then loads, fits
(``fit_seed``, ``build_model``, ``fit_map``) and checks (``assess``) as the command
does.  Prints, per kind of fault, the sessions whose verdict names the outlying reading,
those it fails on another check, and those it passes.  Each result is one JSON line in
``--log`` (resumed).

    python benchmarks/glitches.py --n 20 --log glitches.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.noise import noise_scale
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import fuzz_plan, fuzz_session


def _speed_trace(root: Path, plan: dict, rng) -> tuple[Path, str, float] | None:
    """A driven trace's CSV with a logged speed column, that column and its noise sd
    (model-free, in the file's unit)."""
    choices = []
    for tr in plan["trace"]:
        csv = root / f"{tr['name']}.csv"
        if tr["kind"] == "coast-down" or not csv.exists():
            continue
        lines = csv.read_text().splitlines()
        header = lines[0].split(",")
        if "speed" in header:
            j = header.index("speed")
            y = np.array([float(x.split(",")[j]) for x in lines[1:]])
            choices.append((csv, "speed", noise_scale(y)))
    return choices[rng.integers(len(choices))] if choices else None


def inject(root: Path, plan: dict, kind: str, size: float, rng, run: int = 1) -> dict | None:
    """Write the fault into the session at ``root``; where it went (None: no speed
    column to write it in)."""
    found = _speed_trace(root, plan, rng)
    if found is None:
        return None
    csv, column, noise = found
    lines = csv.read_text().splitlines()
    j = lines[0].split(",").index(column)
    k = int(rng.integers(max(2, len(lines) // 10), len(lines) - max(2, len(lines) // 10)))
    cells = lines[k].split(",")
    was = float(cells[j])
    spike = size * max(noise, 1e-9) * float(rng.choice([-1.0, 1.0]))
    now = "65535" if kind == "sentinel" else repr(was + spike)
    for line in range(k, k + (run if kind == "sentinel" else 1)):
        cells = lines[line].split(",")
        cells[j] = now
        lines[line] = ",".join(cells)
    csv.write_text("\n".join(lines) + "\n")
    return {"file": csv.name, "line": k + 1, "was": was, "now": now, "noise": noise}


def run_one(seed: int, kind: str, size: float, run: int = 1) -> dict:
    rng = np.random.default_rng(10_000 + seed)
    with tempfile.TemporaryDirectory() as d:
        root = Path(d) / "s"
        fuzz_session(seed, out=root)
        plan, _ = fuzz_plan(seed)
        where = inject(root, plan, kind, size, rng, run)
        if where is None:
            return {"seed": seed, "kind": kind, "outcome": "no logged speed"}
        try:
            session = load_session(root)
            cf = fit_seed(session)
            model = build_model(session, cf)
            fit = fit_map(model, seed=seed)
            a = assess(model, fit, cf)
        except Exception as exc:  # noqa: BLE001 - every failure is a row
            return {"seed": seed, "kind": kind, "outcome": "error",
                    "why": f"{type(exc).__name__}: {exc}"[:300], **where}
    fails = sorted({str(f.check) for f in a.findings if f.failed})
    return {"seed": seed, "kind": kind, "outcome": a.verdict, "fails": fails,
            "faulty_data": a.faulty_data, **where}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20, help="sessions per kind of fault")
    ap.add_argument("--start", type=int, default=0, help="first seed")
    ap.add_argument("--size", type=float, default=30.0, help="a spike, in noise sd")
    ap.add_argument("--run", type=int, default=1, help="sentinels written in a row")
    ap.add_argument("--log", type=Path, default=None)
    args = ap.parse_args(argv)
    done = []
    if args.log is not None and args.log.exists():
        done = [json.loads(x) for x in args.log.read_text().splitlines() if x.strip()]
    seen = {(r["seed"], r["kind"]) for r in done}
    sentinel = "sentinel" if args.run == 1 else f"sentinel x{args.run}"
    for kind in (sentinel, f"spike {args.size:g} sd"):
        for seed in range(args.start, args.start + args.n):
            if (seed, kind) in seen:
                continue
            rec = run_one(seed, "sentinel" if kind == sentinel else "spike", args.size,
                          args.run)
            rec["kind"] = kind
            done.append(rec)
            print(json.dumps(rec), flush=True)
            if args.log is not None:
                with args.log.open("a") as f:
                    f.write(json.dumps(rec) + "\n")
    for kind in sorted({r["kind"] for r in done}):
        rows = [r for r in done if r["kind"] == kind]
        tally = Counter("found (outlying reading)" if "outlying reading" in r.get("fails", ())
                        else "failed on another check" if r["outcome"] == "inadequate"
                        else r["outcome"] for r in rows)
        print(f"{kind}: {len(rows)} sessions: " + ", ".join(f"{v} {k}" for k, v in
                                                             tally.most_common()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
