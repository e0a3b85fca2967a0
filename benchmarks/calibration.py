"""Calibration on fuzzed sessions: false alarms, detection and interval coverage.

Draws sessions with :func:`pmdc_bayes.simulate.fuzz.fuzz_session` (random motors and
plans over the session format, on the independent bench simulator, written to disk and
read back by the loader) and fits each with the library: ``fit_seed``,
``build_model``, ``fit_map`` (global search) and ``assess``.  Reported:

* in-class sessions (the ideal model is right): the session-level false-alarm rate
  (verdict "inadequate") and the sessions each check fails;
* the same draws with one non-ideality each (``--misspecified``): the detection rate
  per non-ideality;
* coverage of the central 50/90/94 % Laplace intervals of the motor parameters (in
  the fit's log space, a fraction of a second per session), against the central 99 %
  binomial band of the nominal level, with the rms of the z-scores; with ``--mcmc``,
  also of the posterior draws of ``sample_posterior`` (the intervals the command
  reports; about a minute per session), which differ from the Laplace intervals where
  the posterior is far from Gaussian;
* a row per failure kind: the seed refused the session, the fit failed, an error.

``--quick`` fits 12 in-class and 9 misspecified sessions; the full run is
``--n 300``.  ``--between-samples`` draws the same sessions with the voltage their
columns log switched between samples (a rig whose switching the logger does not time).
Each result is one JSON line in ``--log`` (resumable), and the section
``## Calibration on fuzzed sessions`` of ``reports/benchmarks.md`` is replaced.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

import jax.numpy as jnp
import numpy as np
from _common import REPORT, replace_section
from scipy import stats

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map, laplace
from pmdc_bayes.inference.fit.optimiser import Stepper
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import NON_IDEALITIES, fuzz_session

LEVELS = (0.50, 0.90, 0.94)
MOTOR = ("Ra", "La", "K", "B", "J", "Tc")


def laplace_z(model, fit, truth: dict) -> dict[str, float]:
    """Per motor parameter, (truth − MAP) / Laplace sd in the fit's θ space."""
    names = list(fit.names)
    known = {k: v for k, v in truth.items() if k in names}
    t = np.asarray(model.theta(known))
    sd = np.sqrt(np.clip(np.diag(fit.cov_log), 0.0, None))
    out = {}
    for k in MOTOR:
        if k in names and k in truth and (k != "Tc" or truth[k] > 0):
            i = names.index(k)
            out[k] = float((t[i] - fit.theta[i]) / sd[i]) if sd[i] > 0 else float("inf")
    return out


@x64
def per_reading_z(model, fit, truth: dict) -> dict[str, float] | None:
    """The z-scores of the Laplace interval at the same MAP had every quantised reading
    counted as an independent error (the likelihood before ``effective_fraction``);
    None when no channel is quantised so."""
    alpha = np.array([c.alpha for c in model.channels])
    if np.all(alpha == 1.0):
        return None
    data = dict(model.data, n_obs=jnp.asarray(model.n_obs), s0=jnp.asarray(model.s0))
    saved, model.data = model.data, data
    try:
        terms = Stepper.of(model).terms(fit.theta)
    finally:
        model.data = saved
    cov, _ = laplace(model, fit.theta, terms)
    return laplace_z(model, dataclasses.replace(fit, cov_log=cov), truth)


def mcmc_z(model, fit, truth: dict, seed: int) -> tuple[dict[str, float], bool]:
    """Per motor parameter, where the truth falls among the posterior draws of
    ``sample_posterior`` (the intervals the command reports), as a normal score
    ``Φ⁻¹(share of draws below the truth)``, so that a central interval of level L covers
    the truth when |z| ≤ Φ⁻¹(½ + L/2) as for the Laplace z; and whether the sampler's
    gates passed."""
    from pmdc_bayes.inference.sampling.posterior import gates, sample_posterior, summarize

    post = sample_posterior(model, fit, seed=seed, progress=False)
    draws = post.draws_si()
    out = {}
    for k in MOTOR:
        if k in draws and k in truth and (k != "Tc" or truth[k] > 0):
            d = np.asarray(draws[k]).ravel()
            share = (np.sum(d < truth[k]) + 0.5) / (d.size + 1.0)
            out[k] = float(stats.norm.ppf(share))
    return out, bool(gates(summarize(post), posterior=post)[0])


def run_one(seed: int, misspecified: str | None, root: Path, mcmc: bool = False,
            **kw) -> dict:
    """Fuzz, write, load, fit and check one session; a JSON-able record (with ``mcmc``,
    an adequate session's truth placed among its posterior draws too)."""
    t0 = time.perf_counter()
    f = fuzz_session(seed, misspecified=misspecified, out=root / f"s{seed}", **kw)
    rec = {"seed": seed, "misspecified": misspecified, "shapes": list(f.shapes),
           "features": sorted(f.features)}
    try:
        session = load_session(f.path)
        cf = fit_seed(session)
    except Exception as exc:  # noqa: BLE001 - every failure is a row of the table
        return dict(rec, outcome="seed refused", why=f"{type(exc).__name__}: {exc}"[:300])
    try:
        model = build_model(session, cf)
        fit = fit_map(model, seed=seed)
        if not fit.ok:
            return dict(rec, outcome="fit failed", why=fit.message[:300])
        a = assess(model, fit, cf)
    except Exception as exc:  # noqa: BLE001
        return dict(rec, outcome="error", why=f"{type(exc).__name__}: {exc}"[:300])
    fails = sorted({str(x.check) for x in a.findings if x.failed})
    rec = dict(rec, outcome="fitted", verdict=a.verdict, fails=fails,
               z=laplace_z(model, fit, f.truth), z_per_reading=per_reading_z(model, fit, f.truth))
    if mcmc and a.verdict == "adequate":
        try:
            rec["z_mcmc"], rec["gates_passed"] = mcmc_z(model, fit, f.truth, seed)
        except Exception as exc:  # noqa: BLE001
            rec["mcmc_error"] = f"{type(exc).__name__}: {exc}"[:300]
    return dict(rec, seconds=time.perf_counter() - t0)


def band(n: int, p: float, mass: float = 0.99) -> tuple[int, int]:
    tail = (1 - mass) / 2
    return int(stats.binom.ppf(tail, n, p)), int(stats.binom.ppf(1 - tail, n, p))


def coverage_rows(records, key: str = "z") -> list[str]:
    zs: dict[str, list] = {}
    for r in records:
        for k, z in (r.get(key) or {}).items():
            zs.setdefault(k, []).append(z)
    zs["all"] = [z for k in MOTOR for z in zs.get(k, [])]
    rows = []
    for k in (*MOTOR, "all"):
        z = np.asarray(zs.get(k, []))
        if not z.size:
            continue
        cells = []
        for level in LEVELS:
            half = stats.norm.ppf(0.5 + level / 2)
            hit = int(np.sum(np.abs(z) <= half))
            lo, hi = band(z.size, level)
            mark = "" if lo <= hit <= hi else " ✗"
            cells.append(f"{hit}/{z.size} ({100 * hit / z.size:.0f} %; band {lo}–{hi}){mark}")
        rms = float(np.sqrt(np.mean(np.minimum(z, 1e6) ** 2)))
        rows.append(f"| {k} | " + " | ".join(cells) + f" | {rms:.2f} |")
    return rows


def report(records, args) -> str:
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    inc = [r for r in records if r["misspecified"] is None]
    lines = ["## Calibration on fuzzed sessions", "",
             f"Measured {when} by `python benchmarks/calibration.py {' '.join(args)}`. "
             "Sessions from `pmdc_bayes.simulate.fuzz` (the bench simulator, written and "
             "loaded), fitted by `fit_seed`, `build_model`, `fit_map`, `assess`; intervals "
             "are the MAP's Laplace intervals in the fit's log space.", "",
             "| sessions | n | fitted | seed refused | fit failed | error | inadequate |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    groups = [("in-class", inc)] + [(k, [r for r in records if r["misspecified"] == k])
                                    for k in NON_IDEALITIES]
    for label, rs in groups:
        if not rs:
            continue
        c = Counter(r["outcome"] for r in rs)
        bad = sum(r.get("verdict") == "inadequate" for r in rs)
        lines.append(f"| {label} | {len(rs)} | {c['fitted']} | {c['seed refused']} | "
                     f"{c['fit failed']} | {c['error']} | {bad}/{c['fitted']} |")
    fitted = [r for r in inc if r["outcome"] == "fitted"]
    checks = Counter(x for r in fitted for x in r["fails"])
    lines += ["", "In-class: the 'inadequate' column is the false-alarm rate; elsewhere "
              "the detection rate. Checks failing in-class sessions:", "",
              "| check | in-class sessions failing it |", "|---|---:|"]
    lines += [f"| {k} | {v}/{len(fitted)} |" for k, v in checks.most_common()] or ["| none | |"]
    lines += ["", "Coverage of the central intervals of the motor parameters (in-class, "
              "fitted; band: central 99 % of Binomial(n, level); parameter-replicates of "
              "one session are correlated, so the band is if anything narrow):", "",
              "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
    lines += coverage_rows(fitted)
    sampled = [r for r in fitted if r.get("z_mcmc")]
    if sampled:
        passed = sum(bool(r.get("gates_passed")) for r in sampled)
        lines += ["", f"The same sessions' posterior draws (`sample_posterior`, the intervals "
                  f"`pmdc-bayes fit` reports; {len(sampled)} adequate sessions sampled, the "
                  f"sampler's gates passed in {passed}): the central interval of level L "
                  "covers the truth when the share of draws below it lies within ½ ± L/2 "
                  "(z: its normal score):", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows(sampled, "z_mcmc")
        lines += ["", f"Laplace intervals of the same {len(sampled)} sessions:", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows(sampled)
        lines += ["", "The intervals the headline gives for the same sessions: the draws' where "
                  "they passed their gates, the MAP's Laplace interval where they failed:", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows([{"z": r["z_mcmc"] if r.get("gates_passed") else r["z"]}
                                for r in sampled])
    quant = [r for r in fitted if r.get("z_per_reading")]
    if quant:
        lines += ["", f"Sessions with a quantised channel that its noise does not dither "
                  f"({len(quant)}, an encoder's counts among them): as fitted (one "
                  "independent error per quantum the signal passes), then at the same MAP "
                  "with every reading counted as one:", "",
                  "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
        lines += coverage_rows(quant)
        lines += ["", "| before: parameter | 50 % | 90 % | 94 % | z rms |",
                  "|---|---|---|---|---:|"]
        lines += coverage_rows([{"z": r["z_per_reading"]} for r in quant])
    for feature in ("no trace current", "quantised speed", "voltage column"):
        sub = [r for r in fitted if feature in r["features"]]
        if sub:
            lines += ["", f"Of which with {feature} ({len(sub)} sessions):", "",
                      "| parameter | 50 % | 90 % | 94 % | z rms |", "|---|---|---|---|---:|"]
            lines += coverage_rows(sub)
    why = Counter(r["why"].split(";")[0][:90] for r in records if "why" in r)
    if why:
        lines += ["", "Refusals and failures, by message:", ""]
        lines += [f"- {n}× {w}" for w, n in why.most_common(8)]
    secs = [r["seconds"] for r in records if "seconds" in r]
    if secs:
        lines += ["", f"Per fitted session: median {np.median(secs):.1f} s, max "
                  f"{np.max(secs):.0f} s (each session's own compilation included)."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--n", type=int, default=300, help="in-class sessions")
    ap.add_argument("--misspecified", type=int, default=10,
                    help="sessions per non-ideality")
    ap.add_argument("--keys", default=None,
                    help="non-idealities to draw, comma-separated (default: every one)")
    ap.add_argument("--quick", action="store_true", help="12 in-class, 1 per non-ideality")
    ap.add_argument("--start", type=int, default=0, help="first seed")
    ap.add_argument("--log", type=Path, default=None, help="JSON lines of results (resumed)")
    ap.add_argument("--no-report", action="store_true")
    ap.add_argument("--mcmc", action="store_true",
                    help="also sample each adequate in-class session's posterior")
    ap.add_argument("--between-samples", action="store_true",
                    help="logged voltage columns from a rig that switches between samples")
    ap.add_argument("--coarse-clock", action="store_true",
                    help="every trace stamped as a microcontroller logs it (millis() "
                         "at up to 500 Hz, else micros() on a 4 us tick)")
    ap.add_argument("--stopped", action="store_true",
                    help="every driven trace commanded to zero halfway through its last "
                         "level (the driver braking, or opening the armature for 'open at "
                         "zero')")
    ap.add_argument("--shapes", default=None,
                    help="trace shapes to draw from, comma-separated (default: the "
                         "fuzzer's TRACE_SHAPES; EXCITATION_SHAPES on request)")
    args = ap.parse_args(argv)
    shapes = tuple(x.strip() for x in args.shapes.split(",")) if args.shapes else None
    n, m = (12, 1) if args.quick else (args.n, args.misspecified)
    jobs = [(s, None) for s in range(args.start, args.start + n)]
    keys = tuple(x.strip() for x in args.keys.split(",")) if args.keys else NON_IDEALITIES
    for key in keys:
        if key not in NON_IDEALITIES:
            ap.error(f"--keys: unknown non-ideality {key!r}; use some of {NON_IDEALITIES}")
    jobs += [(args.start + k, key) for k in range(m) for key in keys]
    done = {}
    if args.log and args.log.exists():
        for line in args.log.read_text().splitlines():
            r = json.loads(line)
            done[(r["seed"], r["misspecified"])] = r
    records = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed, key in jobs:
            r = done.get((seed, key)) or run_one(
                seed, key, Path(tmp), mcmc=args.mcmc and key is None,
                between_samples=args.between_samples, shapes=shapes,
                coarse_clock=args.coarse_clock, stopped=args.stopped)
            if (seed, key) not in done and args.log:
                with args.log.open("a") as fh:
                    fh.write(json.dumps(r) + "\n")
            records.append(r)
            print(seed, key, r["outcome"], r.get("verdict", r.get("why", "")),
                  r.get("fails", ""), {k: round(v, 2) for k, v in r.get("z", {}).items()},
                  flush=True)
    section = report(records, sys.argv[1:] if argv is None else argv)
    print(section)
    if not args.no_report:
        replace_section(REPORT, "Calibration on fuzzed sessions", section)
    return 0


if __name__ == "__main__":
    sys.exit(main())
