"""The zero-command rule (``inference/adequacy/zero_command.py``) on fuzzed sessions: how
often it proposes ``open_at_zero`` where the driver brakes (in-class sessions, a false
proposal) and where it opens the armature (the fuzzer's "open at zero": every driven
trace stopped halfway through its last level, the rotor coasting).

The rule is model-free (it reads the logged speed and command only), so no fit runs:
each session is drawn by :func:`pmdc_bayes.simulate.fuzz.fuzz_session`, written and
loaded, and the rule asked of every trace.  The in-class sessions are stopped as the
misspecified ones are (``stopped=True``: a zero command halfway through every trace's
last level, where the driver brakes), so that the rule has a fall to read in each.  A
session counts where some trace holds both a rise and a fall the rule can read.  Prints
the table and replaces the section ``## The zero-command rule on fuzzed sessions`` of
``reports/benchmarks.md`` (``--no-report`` to print only).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from datetime import UTC, datetime
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from _common import REPORT, rate, replace_section

from pmdc_bayes.inference.adequacy.zero_command import COAST_RATIO, coast_rules, time_constants
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import fuzz_session

TITLE = "The zero-command rule on fuzzed sessions"


def judge(seed: int, key: str | None, root: Path) -> dict:
    """Whether the rule can read session ``seed`` and whether it proposes, with the
    rig's coast-to-braking time ratio (``1/damping``) and its Coulomb share."""
    f = fuzz_session(seed, misspecified=key, out=root / f"s{seed}", stopped=True)
    try:
        session = load_session(f.path)
    except Exception as exc:  # noqa: BLE001 - a refused session is a row of its own
        return {"seed": seed, "read": False, "why": str(exc)[:120]}
    t = f.truth
    ratio = (t["K"] ** 2 + t["Ra"] * t["B"]) / (t["Ra"] * t["B"])
    model = SimpleNamespace(session=session)
    said = [s for tr in session.traces for s in coast_rules(model, tr)]
    readable = any(_readable(tr) for tr in session.traces)
    return {"seed": seed, "read": True, "readable": readable, "proposed": bool(said),
            "ratio": ratio, "coulomb": t.get("Tc", 0.0) > 0}


def _readable(tr) -> bool:
    if tr.speed is None:
        return False
    rises, falls = time_constants(tr)
    return bool(rises and falls)


def report(inc, mis, argv) -> str:
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines = [f"## {TITLE}", "",
             f"Measured {when} by `python benchmarks/coast_rule.py {' '.join(argv)}` "
             f"(see the script's docstring; threshold COAST_RATIO = {COAST_RATIO:g}).", ""]
    for label, rs in (("in-class (the driver brakes)", inc),
                      ("open at zero (the driver opens the armature)", mis)):
        read = [r for r in rs if r["read"]]
        able = [r for r in read if r["readable"]]
        lines.append(f"- {label}: {len(rs)} sessions, {len(read)} loaded, {len(able)} with "
                     f"a rise and a fall the rule reads; proposed in "
                     f"{rate(sum(r['proposed'] for r in able), len(able), 1)}")
    able = [r for r in mis if r["read"] and r["readable"]]
    if able:
        lines += ["", "Detection by the rig's coast-to-braking time ratio (J/B over the "
                  "mechanical time constant, 1/damping) and its friction:", "",
                  "| ratio | viscous | Coulomb |", "|---|---:|---:|"]
        edges = [3.0, 5.0, 10.0, 20.0, np.inf]
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            cells = []
            for coulomb in (False, True):
                sub = [r for r in able if lo <= r["ratio"] < hi and r["coulomb"] == coulomb]
                k = sum(r["proposed"] for r in sub)
                cells.append(f"{k}/{len(sub)}" if sub else "—")
            lines.append(f"| {lo:g}–{hi:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--n", type=int, default=300, help="in-class sessions")
    ap.add_argument("--misspecified", type=int, default=300, help="open-at-zero sessions")
    ap.add_argument("--start", type=int, default=0, help="first seed")
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    inc, mis = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(max(args.n, args.misspecified)):
            seed = args.start + k
            if k < args.n:
                inc.append(judge(seed, None, Path(tmp) / "in"))
            if k < args.misspecified:
                mis.append(judge(seed, "open at zero", Path(tmp) / "open"))
            print(seed, inc[-1] if k < args.n else "", mis[-1] if k < args.misspecified
                  else "", flush=True)
    section = report(inc, mis, sys.argv[1:] if argv is None else argv)
    print(section)
    if not args.no_report:
        replace_section(REPORT, TITLE, section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
