"""The model search on rigs carrying two or three non-idealities at once: does the
model it chooses hold every one of them, and do the data accept it?

Each session is drawn by :func:`pmdc_bayes.simulate.fuzz.fuzz_session` (random motors
and plans over the session format, the bench simulator's LSODA, written and read back
by the loader) with a random combination of 2–3 of :data:`COMBINED` (the non-idealities
the search can name: a speed gain is left out, exactly unidentifiable without a bench
K, J or B, and so is an encoder's differenced speed, a way of logging rather than a
term), and searched as ``fit --compare`` searches (:func:`pmdc_bayes.search.run_search`;
a plain ``fit`` searches the same way where the data reject the session's model).  A
session counts as recovered when every non-ideality it carries is among the chosen
terms and the chosen model's verdict is adequate.  Where one is missing, the model of
what the rig carries is fitted alone, to tell a miss of the search (its evidence clearly
higher than every candidate's) from data that cannot tell it from what was chosen.
``--carry`` gives every session the same non-idealities instead (one alone, or "open at
zero", which a random combination never draws).  ``--in-class`` sessions (no
non-ideality) count when the search adds none (the friction, viscous or Coulomb,
aside).  Each result is one JSON line in ``--log``
(resumable); the section ``## Model search on combined non-idealities`` of
``reports/benchmarks.md`` is replaced.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from _common import REPORT, rate, replace_section

from pmdc_bayes.candidate import Candidate
from pmdc_bayes.io.lattice import analogue_channels
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.search import ADD_MARGIN, run_search
from pmdc_bayes.simulate.fuzz import fuzz_session
from pmdc_bayes.terms import LOAD, NOISE, SHARED, label, nuisance_of

TITLE = "Model search on combined non-idealities"
TERM = {"dead time": "dead_time", "speed lag": "speed_lag", "voltage drop": "voltage_drop",
        "source resistance": "source_resistance", "current limit": "current_limit",
        "unknown load": "unknown_load", "speed offset": "speed_offset",
        "dead zone": "dead_zone", "coloured noise": "coloured_noise",
        "open at zero": "open_at_zero"}
COMBINED = tuple(TERM)[:9]  # the random combinations' pool (as first drawn, seed for seed)


def combination(seed: int) -> tuple[str, ...]:
    """The 2–3 non-idealities of session ``seed`` (its own stream, apart from the
    session's draw)."""
    rng = np.random.default_rng([seed, 33])
    k = int(rng.integers(2, 4))
    return tuple(sorted(str(x) for x in rng.choice(COMBINED, size=k, replace=False)))


def true_terms(session, truth: dict, keys) -> frozenset:
    """The search's terms for what the rig carries: its dead time shared by the traces,
    its unknown loads on the traces the simulator loaded, coloured noise on every trace
    with an analogue channel, Coulomb friction where the motor has it."""
    out = set()
    for key in keys or ():
        term = TERM[key]
        if term == "dead_time":
            out.add(SHARED if len(session.traces) > 1 else term)
        elif term == "unknown_load":
            out.update(LOAD + n[len("load_"):] for n in truth if n.startswith("load_"))
        elif term == "coloured_noise":
            out.update(NOISE + t for t in set(analogue_channels(session).values()))
        else:
            out.add(term)
    if truth.get("Tc", 0.0) > 0:
        out.add("coulomb")
    return frozenset(out)


def fit_terms(session, terms, seed: int) -> Candidate:
    """The model ``terms`` fitted in its own programs, scored as the search scores one."""
    cand = Candidate.of(session, terms, move="truth")
    cand.run(seed)
    return cand


def run_one(seed: int, keys: tuple[str, ...] | None, root: Path) -> dict:
    t0 = time.perf_counter()
    f = fuzz_session(seed, misspecified=keys, out=root / f"s{seed}")
    rec = {"seed": seed, "keys": list(keys or ()), "shapes": list(f.shapes),
           "features": sorted(f.features)}
    try:
        session = load_session(f.path)
        found = run_search(session, seed=seed)
        chosen = found.chosen
        terms = sorted(found.record["terms"])
        held = {nuisance_of(t) for t in terms}
        rec.update(outcome="searched", terms=terms, verdict=chosen.adequacy.verdict,
                   missing=[k for k in keys or () if TERM[k] not in held],
                   fits=found.record["fits"], search_seconds=time.perf_counter() - t0,
                   equivalent=[c["terms"] for c in found.record["candidates"]
                               if c["name"] in found.record["equivalent"]])
        truth = true_terms(session, f.truth, keys)
        if rec["missing"] and truth != frozenset(found.record["terms"]):
            best = max(found.record["candidates"], key=lambda c: (math.isfinite(c["log_evidence"]),
                                                                 c["log_evidence"]))
            row = {frozenset(c["terms"]): c for c in found.record["candidates"]}.get(truth)
            if row is not None and row["verdict"] != "not checked":  # the search fitted it
                verdict, log_z = row["verdict"], row["log_evidence"]
            else:
                own = fit_terms(session, truth, seed)
                verdict, log_z = own.adequacy.verdict, own.log_evidence
            rec.update(truth=label(truth), truth_verdict=verdict,
                       truth_gain=log_z - best["log_evidence"])
    except Exception as exc:  # noqa: BLE001 - every failure is a row of the table
        rec.update(outcome="error", why=f"{type(exc).__name__}: {exc}"[:300])
    return dict(rec, seconds=time.perf_counter() - t0)


def report(records, argv) -> str:
    now = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    cmd = f"python benchmarks/combinations.py {' '.join(argv)}"
    mis = [r for r in records if r["keys"]]
    ok = [r for r in mis if r["outcome"] == "searched"]
    found = [r for r in ok if not r["missing"] and r["verdict"] == "adequate"]
    lines = [f"## {TITLE}", "", f"Measured {now} by `{cmd}` (see the script's docstring).",
             "", f"- recovered (every non-ideality chosen, verdict adequate): "
             f"{rate(len(found), len(mis))}; errors {len(mis) - len(ok)}",
             f"- every non-ideality chosen, whatever the verdict: "
             f"{rate(sum(not r['missing'] for r in ok), len(mis))}",
             "- chosen model adequate: "
             f"{rate(sum(r['verdict'] == 'adequate' for r in ok), len(mis))}"]
    beside = [r for r in ok if r["missing"] and r["verdict"] == "adequate" and any(
        {TERM[k] for k in r["keys"]} <= {nuisance_of(t) for t in eq}
        for eq in r.get("equivalent", ()))]
    lines.append("- recovered, or every non-ideality in a model reported beside the chosen "
                 f"one as equally good: {rate(len(found) + len(beside), len(mis))}")
    for k in (2, 3):
        sub = [r for r in mis if len(r["keys"]) == k]
        rec = [r for r in sub if r["outcome"] == "searched" and not r["missing"]
               and r["verdict"] == "adequate"]
        lines.append(f"- {k} at once: {rate(len(rec), len(sub))}")
    inclass = [r for r in records if not r["keys"]]
    if inclass:
        ideal = [r for r in inclass if r["outcome"] == "searched"
                 and set(r["terms"]) <= {"coulomb"}]
        lines.append(f"- in-class sessions that add no non-ideality (the friction aside): "
                     f"{rate(len(ideal), len(inclass))}")
    lines += ["", "| non-ideality | sessions carrying it | chosen |", "|---|---:|---:|"]
    for key in TERM:
        sub = [r for r in ok if key in r["keys"]]
        lines.append(f"| {key} | {len(sub)} | {sum(key not in r['missing'] for r in sub)} |")
    misses = [r for r in ok if r["missing"] or r["verdict"] != "adequate"]
    if misses:
        lines += ["", "Not recovered (the rig's own model, fitted alone: its verdict and "
                  "log Z against the best candidate the search fitted; above "
                  f"+{ADD_MARGIN:g} the search missed a model the evidence clearly prefers):",
                  "", "| seed | carries | chosen | verdict | the rig's model | log Z gain |",
                  "|---:|---|---|---|---|---:|"]
        lines += [f"| {r['seed']} | {', '.join(r['keys'])} | {' + '.join(r['terms']) or 'ideal'}"
                  f" | {r['verdict']} | {r.get('truth_verdict', '–')} | "
                  f"{_gain(r.get('truth_gain'))} |" for r in misses]
        gains = [r["truth_gain"] for r in misses if r.get("truth_gain") is not None]
        if gains:
            lines += ["", f"Of the {len(gains)} misses whose rig's model was fitted, the "
                      f"evidence clearly prefers it over every candidate of the search in "
                      f"{sum(g > ADD_MARGIN for g in gains)}: misses of the search; in the "
                      f"others the data do not tell the rig's model from what was chosen."]
    extra = Counter(t for r in ok for t in r["terms"]
                    if nuisance_of(t) not in {TERM[k] for k in r["keys"]})
    if extra:
        lines += ["", "Terms chosen beyond what the rig carries: "
                  + ", ".join(f"{t} {n}×" for t, n in extra.most_common()) + "."]
    secs = sorted(r.get("search_seconds", r["seconds"]) for r in records)
    if secs:
        lines += ["", f"Per session (the whole search, compilation included, 2 processes "
                  f"side by side): median {secs[len(secs) // 2]:.0f} s, max {secs[-1]:.0f} s."]
    return "\n".join(lines) + "\n"


def _gain(g) -> str:
    return "–" if g is None else f"{g:+.1f}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--n", type=int, default=30, help="sessions with a combination")
    ap.add_argument("--in-class", type=int, default=0, help="in-class sessions too")
    ap.add_argument("--carry", default=None,
                    help="every session carries these non-idealities (comma-separated) "
                         "instead of a random combination")
    ap.add_argument("--start", type=int, default=0, help="first seed")
    ap.add_argument("--part", type=str, default="0/1",
                    help="K/N: run only every N-th session from the K-th (side by side)")
    ap.add_argument("--log", type=Path, nargs="+", default=[],
                    help="JSON lines of results (resumed; new results go to the first)")
    ap.add_argument("--no-report", action="store_true")
    ap.add_argument("--logged-only", action="store_true",
                    help="report the sessions already in --log (several logs: one per part, "
                         "joined); run none")
    args = ap.parse_args(argv)
    part, parts = (int(x) for x in args.part.split("/"))
    seeds = range(args.start, args.start + args.n)
    carry = tuple(sorted(x.strip() for x in args.carry.split(","))) if args.carry else None
    for key in carry or ():
        if key not in TERM:
            ap.error(f"--carry: unknown non-ideality {key!r}; use some of {tuple(TERM)}")
    jobs = [(s, carry or combination(s)) for s in seeds] + [
        (s, None) for s in range(args.start, args.start + args.in_class)]
    jobs = jobs[part::parts]
    done = {}
    for log in args.log:
        for line in log.read_text().splitlines() if log.exists() else ():
            r = json.loads(line)
            done[(r["seed"], tuple(r["keys"]))] = r
    if args.logged_only:
        jobs = [j for j in jobs if (j[0], tuple(j[1] or ())) in done]
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed, keys in jobs:
            r = done.get((seed, tuple(keys or ()))) or run_one(seed, keys, Path(tmp))
            if (seed, tuple(keys or ())) not in done and args.log:
                with args.log[0].open("a") as fh:
                    fh.write(json.dumps(r) + "\n")
            records.append(r)
            print(seed, keys, r["outcome"], r.get("terms"), r.get("verdict"), r.get("missing"),
                  f"{r['seconds']:.0f} s", flush=True)
    section = report(records, sys.argv[1:] if argv is None else argv)
    print(section)
    if not args.no_report:
        replace_section(REPORT, TITLE, section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
