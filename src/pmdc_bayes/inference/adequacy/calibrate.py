"""Thresholds of the adequacy checks from their statistics' distributions at the MAP.

Where a statistic has a known distribution under the fitted model (Ljung–Box's
χ²(h), a lag-1 autocorrelation's N(−1/n, 1/n), the fitted against the model-free noise
level with that estimator's own uncertainty) the p-value comes from it.  Where none
exists, or where the data are quantised, a **parametric bootstrap at the MAP**
(Gelman, Meng & Stern 1996) gives it: each replicate is the MAP prediction plus white
noise at the channel's fitted level, put through the same sensor path as the data
(rounded to the logged resolution, at a random sub-quantum phase since the true signal
is known only to within a quantum), and the statistic is computed on it exactly as on
the data; no refit.  The observed statistic is placed on a moment-matched fit of the
replicates (a scaled χ² for a positive, right-skewed statistic, a normal otherwise),
so that p-values far below 1/:data:`REPLICATES` are resolved.

The checks of a session form one family: Holm's step-down keeps the chance of any
false "inadequate" at :data:`FAMILY_LEVEL`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter
from scipy.stats import chi2, norm

__all__ = ["FAMILY_LEVEL", "REPLICATES", "Test", "session_rng", "logged_quantum",
           "replicates", "tail_p", "holm", "judged_alone", "ratio_p", "NOISE_LOG_SD"]

FAMILY_LEVEL = 0.01  # chance of a false "inadequate" per session, over all its checks
REPLICATES = 200  # bootstrap replicates per channel
NOISE_LOG_SD = 1.42  # √n × sd of log(noise_scale) for white noise (Monte Carlo, n = 1e2–1e4)
_CHUNK = 2_000_000  # samples of replicates held at once


@dataclass(frozen=True)
class Test:
    """One check's outcome before the family's correction: the finding it reports when
    it rejects, its p-value, and whether the effect is large enough to matter."""

    finding: object
    p_value: float
    material: bool = True


def session_rng(session) -> np.random.Generator:
    """A generator seeded from the session's data, so a verdict is reproducible."""
    h = 0
    for tr in tuple(session.traces) + tuple(session.coast_downs):
        for y in (tr.time, tr.speed, tr.current):
            if y is not None:
                h = zlib.crc32(np.ascontiguousarray(np.asarray(y, float)[:4096]).tobytes(), h)
    return np.random.default_rng(h)


def logged_quantum(y) -> float:
    """The resolution a signal was logged at: its smallest non-zero step when every
    sample lies on that lattice (to 1 % of a step), else 0."""
    y = np.asarray(y, float)
    y = y[np.isfinite(y)]
    if y.size < 3:
        return 0.0
    d = np.abs(np.diff(y))
    d = d[d > 1e-9 * max(1.0, float(np.max(np.abs(y))))]
    if not d.size:
        return 0.0
    q = float(np.min(d))
    k = (y - y[0]) / q
    return q if float(np.max(np.abs(k - np.round(k)))) < 0.01 else 0.0


def replicates(yhat, sigma: float, rng, *, quantum: float = 0.0, origin: float = 0.0,
               n_rep: int = REPLICATES, rho: float = 0.0):
    """Yield blocks of replicate data (rows): ``yhat`` plus white noise whose sd, with
    the rounding's q²/12, makes up ``sigma``, rounded to ``quantum`` on the lattice
    through ``origin`` at a random sub-quantum phase per replicate.  With ``rho``, the
    noise is AR(1) (:mod:`.coloured`): innovations of sd ``sigma``, started from its
    stationary distribution."""
    yhat = np.asarray(yhat, float)
    sn = float(np.sqrt(max(sigma**2 - quantum**2 / 12.0, 0.0))) if quantum > 0 else sigma
    rows = max(1, _CHUNK // max(yhat.size, 1))
    done = 0
    while done < n_rep:
        k = min(rows, n_rep - done)
        e = sn * rng.standard_normal((k, yhat.size))
        if rho != 0.0:
            e[:, 0] /= np.sqrt(1.0 - rho * rho)
            e = lfilter([1.0], [1.0, -rho], e, axis=1)
        x = yhat + e
        if quantum > 0:
            phase = rng.uniform(-0.5, 0.5, (k, 1)) * quantum
            x = origin + quantum * np.round((x + phase - origin) / quantum)
        done += k
        yield x


def tail_p(observed: float, reps, *, side: str = "upper", floor: float = 0.0) -> float:
    """Where ``observed`` falls among the replicates' statistic ``reps``: on a scaled χ²
    matched to their mean and variance for ``side="chi2"`` (upper tail), else on a
    normal of their mean and sd (``floor`` added in quadrature: a resolution the
    replicates do not show), ``"upper"``, ``"lower"`` or ``"two"``-sided."""
    reps = np.asarray(reps, float)
    reps = reps[np.isfinite(reps)]
    if not np.isfinite(observed) or reps.size < 10:
        return 1.0
    m, v = float(np.mean(reps)), float(np.var(reps, ddof=1))
    if side == "chi2":
        if m <= 0 or v <= 0:
            return 1.0 if observed <= m else 0.0
        scale, dof = v / (2 * m), 2 * m * m / v
        return float(chi2.sf(observed / scale, dof))
    s = float(np.hypot(np.sqrt(v), floor))
    if s == 0:
        return 1.0 if observed == m else 0.0
    z = (observed - m) / s
    return float({"upper": norm.sf(z), "lower": norm.cdf(z),
                  "two": 2 * norm.sf(abs(z))}[side])


def ratio_p(fitted: float, model_free: float, n: int) -> float:
    """Upper-tail p-value of a fitted noise sd against the model-free one from the same
    ``n`` samples: log of their ratio normal, sd √(1.42² + ½)/√n (the second-difference
    estimate's and the fitted sd's own uncertainties)."""
    if not (fitted > 0 and model_free > 0 and n > 0):
        return 1.0
    sd = np.sqrt(NOISE_LOG_SD**2 + 0.5) / np.sqrt(n)
    return float(norm.sf(np.log(fitted / model_free) / sd))


def holm(p_values, level: float = FAMILY_LEVEL) -> np.ndarray:
    """Holm's step-down: which hypotheses the family rejects at ``level``."""
    p = np.asarray(p_values, float)
    out = np.zeros(p.size, bool)
    for rank, k in enumerate(np.argsort(p, kind="stable")):
        if not p[k] <= level / (p.size - rank):
            break
        out[k] = True
    return out


def judged_alone(tests: list) -> list:
    """The findings of ``tests`` judged as a family of their own (a check run alone)."""
    reject = holm([t.p_value for t in tests], FAMILY_LEVEL)
    return [type(t.finding)(**{**t.finding.__dict__, "p_value": t.p_value})
            for t, r in zip(tests, reject, strict=True) if r and t.material]
