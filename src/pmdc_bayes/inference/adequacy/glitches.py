"""The outlying reading check: a glitch in one trace channel (a logger's sentinel such
as 65535, a dropped or doubled byte, a spike of interference), one reading or a short
run of them that jumps off its neighbours and back, found in the residuals at the MAP
with its p-value under the fitted noise."""

from __future__ import annotations

import numpy as np
from scipy.stats import t as student_t

from .calibrate import Test
from .findings import MATERIAL_FRACTION, Check, Finding, Severity

__all__ = ["outlier_test", "EDGE_FRACTION", "OUTLIER_WINDOW", "BURST"]

EDGE_FRACTION = 0.05  # an input change this share of the input's range is a step edge
OUTLIER_WINDOW = 100  # contrasts each side that give a reading's noise scale
BURST = 3  # the longest run of readings read as one glitch


def _run_contrasts(r, ok, near, length):
    """For every run of ``length`` readings (indexed by its first): its mean less the
    mean of the reading either side; whether the contrast is read (every reading it uses
    finite, none of the run's near an input step); its size over the root mean square of
    the read contrasts around it (:data:`OUTLIER_WINDOW` each side, those sharing a
    reading with the run left out, so that a bad run does not set its own yardstick);
    and that yardstick's degrees of freedom (the window's contrasts, about one in
    ``length + 1`` of them independent)."""
    n = r.size
    k = np.arange(1, n - length)
    run = sum(np.nan_to_num(r[k + j]) for j in range(length)) / length
    c = run - 0.5 * (np.nan_to_num(r[k - 1]) + np.nan_to_num(r[k + length]))
    use = ok[k - 1] & ok[k + length]
    for j in range(length):
        use &= ok[k + j] & ~near[k + j]
    sq, one = np.where(use, c, 0.0) ** 2, use.astype(float)
    h, size = OUTLIER_WINDOW, c.size
    idx = np.arange(size)
    lo, hi = np.clip(idx - h, 0, size), np.clip(idx + h + 1, 0, size)
    own_lo, own_hi = np.clip(idx - length, 0, size), np.clip(idx + length + 1, 0, size)
    total, count = (
        (s[hi] - s[lo]) - (s[own_hi] - s[own_lo])
        for s in (np.concatenate([[0.0], np.cumsum(x)]) for x in (sq, one)))
    scale = np.sqrt(np.where(count > 0, total / np.maximum(count, 1.0), 0.0))
    a = np.abs(c)
    # a jump where the contrasts around it do not move at all is beyond any noise
    z = np.where(use, np.where(scale > 0, a / np.where(scale > 0, scale, 1.0),
                               np.where(a > 0, np.inf, 0.0)), 0.0)
    return c, use, z, np.maximum(3.0, count / (length + 1.0))


def outlier_test(channel, r, span, *, u=None, time=None, unit="", quantum=0.0) -> Test | None:
    """Whether a reading, or a run of up to :data:`BURST` readings, jumps off its
    neighbours and back more than the noise allows.

    The statistic is each run's mean less the mean of the reading either side (for one
    reading, half the residual's second difference ``r[i−1] − 2·r[i] + r[i+1]``), which
    a slow misfit barely moves and a bad run carries whole, over the root mean square of
    the same contrast around it (:func:`_run_contrasts`): for stationary Gaussian noise,
    white, correlated or dithered by a quantiser, Student's t.  The smallest p is read
    with Bonferroni's ``m·p`` over the ``m`` contrasts of every run length.  Runs among
    the few readings around a step of the input ``u`` (by :data:`EDGE_FRACTION` of its
    range) are left out: there the timing of a switch between samples, or a delay the
    model lacks, moves the readings, not a fault.  Material when the run stands off its
    neighbours by :data:`~.findings.MATERIAL_FRACTION` of ``span`` and those two
    neighbours agree with each other within half that jump (bad readings among good
    ones, not a step of the residual, a response that starts later or jumps where the
    model's does not, which the systematic misfit and the step start read as the
    model's); and, on a channel logged at a resolution ``quantum``, by more than two
    quanta (a quantiser whose noise seldom moves it flickers by one, and its quiet
    stretches are no yardstick).  None with fewer than 20 readings."""

    r = np.asarray(r, float)
    n = r.size
    if n < 20:
        return None
    ok = np.isfinite(r)
    near = np.zeros(n, bool)
    if u is not None:
        u = np.asarray(u, float)
        rng = float(np.nanmax(u) - np.nanmin(u))
        steps = np.flatnonzero(np.abs(np.diff(u)) > EDGE_FRACTION * rng) + 1 if rng > 0 \
            else np.zeros(0, int)
        for off in (-1, 0, 1, 2):
            near[np.clip(steps + off, 0, n - 1)] = True
    best, m = None, 0
    for length in range(1, BURST + 1):
        if n < length + 2:
            break
        c, use, z, dof = _run_contrasts(r, ok, near, length)
        m += int(np.count_nonzero(use))
        if not use.any():
            continue
        p_each = np.where(z > 0, 2.0 * student_t.sf(z, dof), 1.0)
        j = int(np.argmin(p_each))
        i = j + 1
        jump = float(c[j])
        lone = abs(r[i + length] - r[i - 1]) <= 0.5 * abs(jump)
        material = lone and abs(jump) > max(MATERIAL_FRACTION * span, 2.0 * quantum)
        key = (float(p_each[j]), not material, -abs(jump))
        if best is None or key < best[0]:
            best = (key, i, length, jump, float(z[j]), material)
    if best is None or m < 10:
        return None
    (p_min, _, _), i, length, jump, times, material = best
    p = float(min(1.0, m * p_min))
    off = f"{jump:+.3g} {unit}".rstrip()
    if length == 1:
        where = f"at t = {time[i]:.6g} s" if time is not None else f"number {i + 1}"
        what = f"the reading {where} stands {off} off its neighbours"
        fix = "leave that cell empty (a missed reading) and fit again"
    else:
        where = (f"from t = {time[i]:.6g} s to {time[i + length - 1]:.6g} s"
                 if time is not None else f"numbers {i + 1} to {i + length}")
        what = f"the {length} readings {where} stand {off} off their neighbours"
        fix = "leave those cells empty (missed readings) and fit again"
    how = (f"{times:.2g} times the sd of such a jump in the noise around it"
           if np.isfinite(times) else "where the readings around it do not move at all")
    return Test(Finding(Check.OUTLYING_READING, channel, Severity.FAIL,
                        f"{off}, {times:.2g} noise sd" if np.isfinite(times) else off,
                        f"{what}, {how} (a glitch: a dropped, saturated or corrupted "
                        f"reading); {fix}"), p, material)
