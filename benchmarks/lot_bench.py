"""Lots from the independent bench simulator, each motor on its own rig: is the
population recovered?

Each lot: ``--motors`` motors whose K, B, J and Ra are drawn from a log-normal
population (the truth), each simulated on a rig of its own (a dead time of 0.3–1.5 ms
and a voltage drop of 0.2–0.8 V, drawn per motor, declared in its ``[model]``): a 12 V
step from rest with speed and current logged at 5 kHz, a steady table at four
voltages, a bench Ra.  ``pmdc-bayes lot`` fits them on 2 Dask workers (``--no-mcmc``:
each motor's Laplace posterior) and pools them; the population's 90 % intervals are
checked against the truth.  With ``--outlier K:5`` the last motor of each lot has
its K drawn 5 spreads above the median (a weak magnet reads the other way: ``K:-5``),
and the table says whether it was flagged and how many others were.  Prints the table;
``python benchmarks/lot_bench.py --lots 10 --motors 12``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _common import cli_command

from pmdc_bayes.simulate.session import simulate_session

NAMES = ("K", "B", "J", "Ra")
MEDIAN = {"K": 0.05, "B": 2e-5, "J": 2e-5, "Ra": 2.0}
SPREAD = {"K": 0.05, "B": 0.2, "J": 0.08, "Ra": 0.05}

PLAN = """seed = {seed}
[motor]
name = "lot motor {k}"
friction = "viscous"
[truth]
Ra = {Ra:.8g}
La = 1e-3
K = {K:.8g}
B = {B:.8g}
J = {J:.8g}
[bench.Ra]
sd = {ra_sd:.4g}
unit = "ohm"
[[steady_table]]
name = "steady"
voltages = [3.0, 6.0, 9.0, 12.0]
speed_sd = {steady_speed:.4g}
current_sd = {steady_current:.4g}
[[trace]]
name = "step"
kind = "step"
duration = 0.12
rate = 5000.0
voltage = [[0.0, 0.0], [0.01, 12.0]]
initial = "rest"
speed_unit = "rad/s"
record_current = true
speed_noise = {speed_noise:.4g}
current_noise = {current_noise:.4g}
[rig]
dead_time = {dead_time:.4g}
voltage_drop = {drop:.4g}
"""


NOISE = {"ra_sd": 0.05, "steady_speed": 0.5, "steady_current": 0.005, "speed_noise": 1.0,
         "current_noise": 0.01}
POOR = 15.0  # a poor session's noise, in multiples of an ordinary one's


def make_lot(folder: Path, seed: int, n: int, outlier: tuple[str, float] | None = None,
             poor: int = 0) -> dict:
    """``n`` motors from the population, the last one ``outlier[1]`` spreads off in
    ``outlier[0]`` where given, the first ``poor`` measured with :data:`POOR` times the
    noise (their bench reading of Ra too); returns each motor's truth."""
    rng = np.random.default_rng(seed)
    truth = {}
    for k in range(n):
        values = {p: MEDIAN[p] * float(np.exp(SPREAD[p] * rng.standard_normal()))
                  for p in NAMES}
        if outlier is not None and k == n - 1:
            name, spreads = outlier
            values[name] = MEDIAN[name] * float(np.exp(SPREAD[name] * spreads))
        session = folder / f"motor{k + 1:02d}"
        session.mkdir(parents=True)
        noise = {key: v * (POOR if k < poor else 1.0) for key, v in NOISE.items()}
        plan = PLAN.format(seed=seed * 100 + k, k=k + 1, dead_time=rng.uniform(3e-4, 1.5e-3),
                           drop=rng.uniform(0.2, 0.8), **values, **noise)
        (session / "plan.toml").write_text(plan, encoding="utf-8")
        simulate_session(session / "plan.toml", session, seed=seed * 100 + k)
        with (session / "session.toml").open("a", encoding="utf-8") as f:
            f.write("\n[model]\ndead_time = true\nvoltage_drop = true\n")
        truth[session.name] = values
    return truth


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lots", type=int, default=10)
    ap.add_argument("--motors", type=int, default=12)
    ap.add_argument("--outlier", metavar="PARAM:SPREADS", type=_outlier,
                    help="the last motor of each lot this many spreads off in PARAM")
    ap.add_argument("--poor", type=int, default=0,
                    help=f"the first N motors of each lot measured with {POOR:g}× the noise")
    args = ap.parse_args(argv)
    caught, others, clean = 0, 0, 0
    hits = {"median": 0, "spread": 0}
    total, failed, flagged, walls = 0, 0, 0, []
    pooled = {"n": 0, "narrower": 0, "covered": 0, "own_covered": 0, "left_out": 0}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env_cache = {"PMDC_BAYES_CACHE": str(tmp / "cache")}
        for lot in range(args.lots):
            folder = tmp / f"lot{lot}"
            truth = make_lot(folder, 500 + lot, args.motors, args.outlier, args.poor)
            out = tmp / f"runs{lot}"
            t0 = time.perf_counter()
            proc = subprocess.run([*cli_command(), "lot", str(folder), "--out", str(out),
                                   "--no-mcmc", "--workers", "2", "--quiet"],
                                  env={**os.environ, **env_cache},
                                  capture_output=True, text=True)
            walls.append(time.perf_counter() - t0)
            doc = json.loads((out / "lot.json").read_text())
            failed += sum(s["status"] != "ok" for s in doc["status"])
            if doc["population"] is None:
                print(f"lot {lot}: no population (exit {proc.returncode}): "
                      f"{proc.stderr.strip()[-500:]}", flush=True)
                continue
            flagged += sum(m["outlier"] for m in doc["motors"])
            if args.outlier is not None:
                odd = sorted(truth)[-1]
                hit = [m["motor"] for m in doc["motors"] if m["outlier"]]
                caught += odd in hit
                others += sum(h != odd for h in hit)
                clean += all(h == odd for h in hit)
            for motor in doc["motors"]:
                if motor["motor"] in sorted(truth)[:args.poor]:
                    _count_pooled(pooled, motor, truth[motor["motor"]])
            line = []
            for p in NAMES:
                pop = doc["population"][p]
                lo, hi = pop["median_interval"]
                slo, shi = pop["spread_interval"]
                hits["median"] += lo <= MEDIAN[p] <= hi
                hits["spread"] += slo <= SPREAD[p] <= shi
                total += 1
                line.append(f"{p} {pop['median']:.4g} [{lo:.4g}, {hi:.4g}] spread "
                            f"{pop['spread']:.3g} [{slo:.3g}, {shi:.3g}]")
            print(f"lot {lot} ({walls[-1]:.0f} s, exit {proc.returncode}): "
                  + "; ".join(line), flush=True)
    print("\n| lots | motors each | motors failed | flagged | median covered | "
          "spread covered | s per lot |")
    print(f"| {args.lots} | {args.motors} | {failed} | {flagged} | "
          f"{hits['median']}/{total} | {hits['spread']}/{total} | "
          f"{np.median(walls):.0f} (first {walls[0]:.0f}) |")
    if args.outlier is not None:
        print(f"\nthe {args.outlier[0]} outlier ({args.outlier[1]:+g} spreads) flagged in "
              f"{caught}/{args.lots} lots; other motors flagged: {others}; lots with no "
              f"other motor flagged: {clean}/{args.lots}")
    if args.poor:
        n = pooled["n"]
        print(f"\npoorly measured motors' parameters: pooled 90 % interval narrower than "
              f"the motor's own in {pooled['narrower']}/{n}; covering the truth "
              f"{pooled['covered']}/{n} (its own: {pooled['own_covered']}/{n}); "
              f"left out of the population: {pooled['left_out']}")
    return 0


def _count_pooled(counts: dict, motor: dict, truth: dict) -> None:
    """A poorly measured motor's pooled and own 90 % intervals against its truth."""
    for p in NAMES:
        v = motor["values"][p]
        if v["pooled_interval"] is None:  # left out of the population
            counts["left_out"] += 1
            continue
        lo, hi = v["pooled_interval"]
        olo, ohi = v["own_interval"]
        counts["n"] += 1
        counts["narrower"] += (hi / lo) < (ohi / olo)
        counts["covered"] += lo <= truth[p] <= hi
        counts["own_covered"] += olo <= truth[p] <= ohi


def _outlier(text: str) -> tuple[str, float]:
    name, _, spreads = text.partition(":")
    if name not in NAMES:
        raise argparse.ArgumentTypeError(f"{name!r}: one of {', '.join(NAMES)}")
    return name, float(spreads)


if __name__ == "__main__":
    sys.exit(main())
