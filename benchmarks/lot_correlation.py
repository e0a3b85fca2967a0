"""The population stage on simulated lots whose truth is known: coverage of the
population's median, spread and correlation, how often the correlation is fitted, and
outliers.

Each lot: ``--motors`` motors, 4 parameters (K, B, J, Ra) drawn log-normal about a
median with a spread per parameter, each motor's own posterior the exact Gaussian of its
measurement (sd 0.5–25 % per parameter) under a wide log-normal prior, as
``tests/inference/test_population.py`` draws them.  Correlated lots: K and B with
correlation 0.85, J and Ra with −0.5.  Prints the table; ``python
benchmarks/lot_correlation.py --lots 20``.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from pmdc_bayes.inference.population.evidence import motor_evidence
from pmdc_bayes.inference.population.pooling import analyse_lot

NAMES = ("K", "B", "J", "Ra")
MU = np.log([0.05, 2e-5, 2e-5, 2.0])
SIGMA = np.array([0.03, 0.2, 0.05, 0.04])
SD = np.array([0.005, 0.05, 0.01, 0.01])
PRIOR_SD = np.log(10.0)


def correlated() -> np.ndarray:
    r = np.eye(4)
    r[0, 1] = r[1, 0] = 0.85
    r[2, 3] = r[3, 2] = -0.5
    return r


def lot(seed: int, n: int, corr: np.ndarray):
    rng = np.random.default_rng(seed)
    chol = np.linalg.cholesky(corr)
    motors = []
    for k in range(n):
        x = MU + SIGMA * (chol @ rng.standard_normal(4))
        est = x + SD * rng.standard_normal(4)
        centre = est + 0.5
        prec = 1.0 / SD**2 + 1.0 / PRIOR_SD**2
        mean = (est / SD**2 + centre / PRIOR_SD**2) / prec
        priors = [("lognormal", float(np.exp(c)), float(PRIOR_SD)) for c in centre]
        motors.append(motor_evidence(f"m{k}", NAMES, priors, theta=mean,
                                     cov=np.diag(1.0 / prec)))
    return motors


def covered(draws, value, level=0.9) -> bool:
    lo, hi = np.quantile(draws, [(1 - level) / 2, (1 + level) / 2])
    return bool(lo <= value <= hi)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lots", type=int, default=20)
    ap.add_argument("--motors", type=int, default=24)
    args = ap.parse_args(argv)
    from pmdc_bayes.inference.model.correlation import correlations

    for label, corr in (("independent", np.eye(4)), ("correlated", correlated())):
        fitted = flagged = 0
        hits = {"median": 0, "spread": 0, "correlation": 0}
        totals = {"median": 0, "spread": 0, "correlation": 0}
        t0 = time.perf_counter()
        for seed in range(args.lots):
            record, pop = analyse_lot(lot(1000 + seed, args.motors, corr), seed=seed)
            flagged += sum(m["outlier"] for m in record["motors"])
            for k in range(4):
                hits["median"] += covered(pop.mu[:, k], MU[k])
                hits["spread"] += covered(pop.sigma[:, k], SIGMA[k])
                totals["median"] += 1
                totals["spread"] += 1
            if pop.correlated:
                fitted += 1
                r = correlations(pop.chol)
                for i in range(4):
                    for j in range(i):
                        hits["correlation"] += covered(r[:, i, j], corr[i, j])
                        totals["correlation"] += 1
            print(f"{label} lot {seed}: correlation "
                  f"{'fitted' if pop.correlated else 'not fitted'} "
                  f"(gain {record['correlation'].get('elpd_gain', float('nan')):.1f} ± "
                  f"{record['correlation'].get('se', float('nan')):.1f})", flush=True)
        wall = time.perf_counter() - t0
        print(f"| {label} | {args.lots} | {fitted}/{args.lots} | "
              + " | ".join(f"{hits[k]}/{totals[k]}" + (f" ({100 * hits[k] / totals[k]:.0f} %)"
                                                       if totals[k] else "")
                           for k in ("median", "spread", "correlation"))
              + f" | {flagged} | {wall / args.lots:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
