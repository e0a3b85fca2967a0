"""The sampler on posteriors that are not Gaussian: its wall time and gate result.

Each case is a whole ``pmdc-bayes fit`` (MAP, adequacy, MCMC, report), with a limit of
60 s of sampling (``--max-sampling-seconds 60``; by default the sampler stops by its own
step budget, whatever the wall time) run twice with one compilation cache so that the second,
measured, run does not compile:

* ``data/bench`` with its declared model (one dead time shared by the traces, a
  voltage drop, a current limit, an eddy-current brake's viscous drag on one trace;
  encoder counts, no current): B, Tc and the voltage drop trade along a direction
  where the posterior is about twice as wide as the Laplace approximation and has
  heavier tails than a Gaussian;
* the same without a time limit (``--max-sampling-seconds 0``, measured once, on the
  cache of the first case): how long the gates take;
* a demo-shaped motor with a small Coulomb torque (a tenth of the demo's) against
  its viscous friction.

Per case: the exit code, the sampling wall time, steps, the largest autocorrelation
time and its parameter, whether the gates passed (and why not), the widest direction
of the posterior beyond the Laplace approximation, and whether each parameter with a
known truth (the motor's and the rig's) lies in its 94 % HDI.  Prints the table and
replaces the section ``## The sampler on hard posteriors`` of ``reports/benchmarks.md``
(``--no-report`` to print only).

    python benchmarks/hard_posteriors.py      # ~12 min on 2 cores
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

from _common import ROOT, cli_command, run_measured, write_table_section

from pmdc_bayes.simulate.session import simulate_session

SECTION = "The sampler on hard posteriors"
SAMPLING_LIMIT = 60  # s of sampling the timed cases allow (the default is no time limit)


def small_coulomb(folder: Path, factor: float = 0.1) -> Path:
    """The demo's plan with its Coulomb torque scaled by ``factor``, simulated."""
    text = (ROOT / "data" / "demo" / "plan.toml").read_text(encoding="utf-8")
    text = re.sub(r"(?m)^(Tc = )([0-9.eE+-]+)",
                  lambda m: f"{m.group(1)}{float(m.group(2)) * factor:.6g}", text, count=1)
    folder.mkdir(parents=True)
    (folder / "plan.toml").write_text(text, encoding="utf-8")
    simulate_session(folder / "plan.toml", folder, seed=11)
    return folder


def case(session: str, tmp: Path, label: str, *, extra=(), cache: str | None = None,
         runs: int = 2) -> dict:
    """One case: ``runs`` runs sharing the compilation cache ``cache`` (by default the
    case's own); the last is measured."""
    cache = tmp / f"cache-{cache or label}"
    for k in range(runs):  # the first run fills the cache; the last is measured
        out = tmp / f"run-{label}-{k}"
        m = run_measured([*cli_command(), "fit", session, "--out", str(out), "--quiet",
                          *extra],
                         env={"PMDC_BAYES_CACHE": str(cache)}, log=tmp / f"{label}-{k}.log")
    if m["returncode"] not in (0, 1):
        print((tmp / f"{label}-{runs - 1}.log").read_text()[-3000:], file=sys.stderr)
        raise SystemExit(f"{label}: exit {m['returncode']}")
    s = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    diag, truth = s["diagnostics"], s.get("truth") or {}
    tau = diag.get("autocorrelation_time", {})
    worst = max(tau, key=tau.get) if tau else None
    tried = [name for name, value in truth.items()
             if value is not None and "hdi_3%" in s["parameters"].get(name, {})]
    covered = [name for name in tried
               if s["parameters"][name]["hdi_3%"] <= truth[name]
               <= s["parameters"][name]["hdi_97%"]]
    return {"label": label, "exit": m["returncode"], "wall": m["wall"],
            "mcmc_s": diag["wall_s"]["mcmc"], "steps": diag.get("n_steps"),
            "tau": tau.get(worst), "worst": worst, "passed": diag.get("gates_passed"),
            "failures": len(diag.get("failures", [])), "wide": diag.get("widest_direction"),
            "covered": covered, "tried": tried, "n_params": len(s["parameters"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        limit = {"extra": ("--max-sampling-seconds", str(SAMPLING_LIMIT))}
        sessions = (("data/bench, declared model", "bench", limit),
                    ("data/bench, no time limit", "bench",
                     {"extra": ("--max-sampling-seconds", "0"),
                      "cache": "data-bench-declared-model", "runs": 1}),
                    ("small Coulomb torque (demo × 0.1)", str(small_coulomb(tmp / "small")),
                     limit))
        for label, session, how in sessions:
            r = case(session, tmp, re.sub(r"[^A-Za-z0-9]+", "-", label), **how)
            r["label"] = label
            rows.append(r)
            wide = r["wide"] or {}
            print(f"{label}: exit {r['exit']}, sampling {r['mcmc_s']:.1f} s, {r['steps']} "
                  f"steps, τ_max {r['tau']:.0f} ({r['worst']}), gates "
                  f"{'passed' if r['passed'] else 'failed'}; widest direction "
                  f"{wide.get('ratio', float('nan')):.1f}× along "
                  f"{', '.join(wide.get('parameters', [])[:4])}; truth in the 94 % HDI: "
                  f"{len(r['covered'])} of {len(r['tried'])}", flush=True)
    if args.no_report:
        return 0
    intro = ("`python benchmarks/hard_posteriors.py` ({stamp}): a whole `pmdc-bayes fit` "
             "per case with a limit of 60 s of sampling (`--max-sampling-seconds 60`; but "
             "where the case says "
             "otherwise), measured on a run whose programs are already in the compilation "
             "cache. Goal (issue 14): the posterior passes its gates or stops with a reason "
             "within 60 s of sampling; issue 13: on data/bench the gates pass with the "
             "truth in the 94 % HDIs. 'Truth in 94 % HDI' counts every parameter with a "
             "known truth, the rig's included.")
    header = ("case", "exit", "sampling (s)", "steps", "τ_max (steps)", "gates",
              "posterior sd / Laplace sd, widest direction", "truth in 94 % HDI")
    table = []
    for r in rows:
        wide = r["wide"] or {}
        along = ", ".join(wide.get("parameters", [])[:4])
        gates = "passed" if r["passed"] else f"failed ({r['failures']} findings)"
        table.append((r["label"], str(r["exit"]), f"{r['mcmc_s']:.1f}", str(r["steps"]),
                      f"{r['tau']:.0f} ({r['worst']})", gates,
                      f"{wide.get('ratio', float('nan')):.1f} along {along}",
                      f"{len(r['covered'])} of {len(r['tried'])}"))
    write_table_section(SECTION, intro, header,
                        ["---", "---:", "---:", "---:", "---", "---", "---", "---"], table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
