"""The steady readings against the fitted model: a test of the miss, calibrated.

A steady table, operating points and step readings' final speeds are read with an
instrument of their own (a tachometer, a meter, a stopwatch), so they show what the
traces alone cannot: a trace sensor whose calibration is off scales K, B and J
together and still fits every trace, but not the steady readings.

Every steady law the model knows is affine in the driven voltage and the load within
one regime (the current's direction sets the drop's sign, the rotation's the Coulomb
torque's), and a reading with the rotor held or no current flowing is set by its
regime alone.  A least-squares line over those columns (:func:`line_columns`) holds
the model's prediction whatever θ; its residual is the readings' own scatter, free of
the model.  The miss's part in the line's span is what the model gets wrong; tested
against that scatter it is an F statistic (:func:`line_test`), with the prediction's
own uncertainty at the MAP (the Laplace covariance through the prediction's Jacobian)
added, so that a prediction the rest of the session fixes only loosely is not
rejected for the readings' noise.  Readings too few to show a scatter about the line
(a lone operating point) are read on the channel's noise prior instead
(:func:`prior_test`): only a miss far beyond any plausible instrument's fails.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np
from scipy.stats import f as f_dist

from ...io.channel import STEADY, ChannelId
from ..model.noise import NU0
from .calibrate import Test, logged_quantum
from .findings import MATERIAL_FRACTION, Check, Finding, Severity

__all__ = ["MissTest", "Noise", "line_columns", "line_test", "prior_test", "reading_quantum",
           "steady_tests", "PRIOR_MATERIAL"]

PRIOR_MATERIAL = 0.03  # a miss read on the noise prior that warns (rms, of the largest reading)
RANK_TOL = 1e-9  # a column direction below this share of the largest is not in the span


class Noise(enum.StrEnum):
    """What a steady channel's miss is measured against."""

    SCATTER = "scatter"  # the readings' own scatter about the line
    PRIOR = "prior"  # the channel's noise prior: too few readings to show a scatter


@dataclass(frozen=True)
class MissTest:
    """A steady channel's miss, tested: ``stat`` ~ F(``dof``) for an exact prediction,
    its ``p_value``, and ``excess`` the miss tested (its part in the line's span, or the
    whole miss where read on the noise prior) as an rms share of the largest reading or
    prediction."""

    stat: float
    dof: tuple[int, float]
    p_value: float
    excess: float


def line_columns(v, tl, i_model, w_model) -> np.ndarray:
    """The columns of the model-free line over steady readings at driven voltages ``v``
    and loads ``tl`` whose predicted regime is read from ``i_model`` and ``w_model``:
    over the readings with current flowing and the rotor turning, the voltage, the load
    and an intercept per (current, rotation) direction pair; a column of its own for
    each reading with the rotor held or no current."""
    v, tl = np.asarray(v, float), np.asarray(tl, float)
    si, sw = np.sign(np.asarray(i_model, float)), np.sign(np.asarray(w_model, float))
    moving = (si != 0) & (sw != 0)
    cols = []
    if moving.any():
        cols += [np.where(moving, v, 0.0), np.where(moving, tl, 0.0)]
        for a in (-1.0, 1.0):
            for b in (-1.0, 1.0):
                cols.append((moving & (si == a) & (sw == b)).astype(float))
    cols += [np.arange(v.size) == k for k in np.flatnonzero(~moving)]
    return np.column_stack(cols).astype(float) if cols else np.zeros((v.size, 0))


def line_test(y, yhat, x, cov=None, quantum: float = 0.0) -> MissTest | None:
    """The F test of the prediction ``yhat`` against the readings ``y`` within the span of
    the columns ``x``, with ``cov`` the prediction's covariance and the scatter floored at
    a logged lattice's ``quantum²/12``; None where the line leaves no degree of freedom
    for the scatter or spans nothing, or a value is not finite.  A prediction fitted to
    these readings meets them more closely than an exact one, and its covariance counts
    their information a second time: the test is then conservative (at most its level
    under the model)."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    x = np.asarray(x, float)
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(yhat)) and x.shape[1]):
        return None
    norms = np.linalg.norm(x, axis=0)
    x = x[:, norms > 0] / norms[norms > 0]
    if not x.shape[1]:
        return None
    basis, s, _ = np.linalg.svd(x, full_matrices=False)
    q = basis[:, s > RANK_TOL * s[0]]
    n, p = y.size, q.shape[1]
    if n - p < 1:
        return None
    u = q.T @ (y - yhat)
    scale = _scale(y, yhat)
    rss = float(np.sum((y - q @ (q.T @ y)) ** 2))
    s2 = max(rss / (n - p), quantum**2 / 12.0, (1e-12 * scale) ** 2)
    c = None if cov is None else q.T @ np.asarray(cov, float) @ q
    return _miss(u, s2, c, (p, n - p), float(np.sqrt(u @ u / n)) / scale)


def prior_test(y, yhat, s0: float, cov=None) -> MissTest | None:
    """The miss of readings too few to measure their own scatter, read on the steady
    channel's noise prior (the likelihood's: an inverse-gamma of ``NU0``
    pseudo-observations at the scale ``s0``), under which their mean square over
    ``s0²`` plus the prediction's covariance ``cov`` is F(n, ``NU0``): a heavy tail, so
    that only a miss far beyond any plausible instrument's is rejected."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    r = y - yhat
    if not (r.size and np.all(np.isfinite(r)) and s0 > 0):
        return None
    excess = float(np.sqrt(np.mean(r**2))) / _scale(y, yhat)
    return _miss(r, s0**2, cov, (r.size, NU0), excess)


def _miss(u, s2: float, cov, dof: tuple[int, float], excess: float) -> MissTest | None:
    """The test of the miss ``u`` against white noise of variance ``s2`` plus the
    prediction's covariance ``cov`` (where finite): ``uᵀM⁻¹u / dof[0]`` ~ F(``dof``);
    None where that is not finite."""
    m = s2 * np.eye(u.size)
    if cov is not None and np.all(np.isfinite(cov)):
        m = m + np.asarray(cov, float)
    stat = float(u @ np.linalg.solve(m, u)) / dof[0]
    if not np.isfinite(stat):
        return None
    return MissTest(stat, dof, float(f_dist.sf(stat, *dof)), excess)


def _scale(y, yhat) -> float:
    """What a miss is a share of: the largest reading or prediction (1 where all are 0)."""
    return float(max(np.max(np.abs(y)), np.max(np.abs(yhat)))) or 1.0


def reading_quantum(y) -> float:
    """The lattice steady readings were logged on (:func:`~.calibrate.logged_quantum`),
    0 unless it is fine against their range (at least two steps per reading): readings
    evenly spaced, as a table at evenly spaced voltages gives, are not a lattice of
    that spacing."""
    q = logged_quantum(y)
    return q if q > 0 and float(np.ptp(y)) >= 2 * np.size(y) * q else 0.0


def _prediction(model, fit):
    """The steady ``(ia, ω)`` at the MAP, the driven voltages, and their covariance
    from the Laplace curvature (the MAP's own where ``cov_log`` spans several optima);
    None for the covariance where it is not finite."""
    pred, jac, v = model.steady_with_jacobian(fit.theta)
    cov = fit.cov_map if fit.cov_map is not None else fit.cov_log
    if cov is None or not np.all(np.isfinite(cov)):
        return pred, v, None
    return pred, v, np.einsum("knp,pq,kmq->knm", jac, np.asarray(cov), jac)


def steady_tests(model, fit) -> tuple[dict, list, list]:
    """Per steady channel its row for the verdict's table, the tests that join the
    verdict's family (a material miss fails: beyond the readings' scatter about the
    line, or, for readings too few to show one, beyond their noise prior) and the
    findings outside it: a warning of a miss above :data:`PRIOR_MATERIAL` of the largest
    reading where the readings show no scatter of their own, a failure where the
    prediction is not finite."""
    st = model.steady
    if not (st["w_mask"].any() or st["i_mask"].any()):
        return {}, [], []
    pred, v, cov = _prediction(model, fit)
    by_id = {c.id: c for c in model.channels}
    rows, tests, found = {}, [], []
    for k, signal, mask in ((1, "speed", st["w_mask"]), (0, "current", st["i_mask"])):
        if not mask.any():
            continue
        cid = ChannelId(STEADY, signal)
        y, yhat = np.asarray(st["w" if k else "i"])[mask], pred[k][mask]
        if not np.all(np.isfinite(pred[:, mask])):
            found.append(Finding(Check.STEADY_MISS, cid, Severity.FAIL, "not finite",
                                 f"the model's steady {signal}s are not finite at the MAP"))
            continue
        x = line_columns(v[mask], np.asarray(st["tl"])[mask], pred[0][mask], pred[1][mask])
        c = None if cov is None else cov[k][np.ix_(mask, mask)]
        scale = _scale(y, yhat)
        t, noise = line_test(y, yhat, x, c, reading_quantum(y)), Noise.SCATTER
        if t is None:
            s0 = max(by_id[cid].s0, 1e-9 * scale)
            t, noise = prior_test(y, yhat, s0, c), Noise.PRIOR
        rel = np.abs(y - yhat) / scale
        rms = float(np.sqrt(np.mean(rel**2)))
        rows[str(cid)] = {"trace": cid.trace, "signal": signal, "unit": by_id[cid].unit,
                          "n": int(y.size), "rms_miss_fraction": rms,
                          "largest_miss_fraction": float(np.max(rel)),
                          "noise": str(noise), "p_value": None if t is None else t.p_value}
        if noise is Noise.PRIOR and rms > PRIOR_MATERIAL:
            found.append(Finding(
                Check.STEADY_MISS, cid, Severity.WARN,
                f"rms miss {100 * rms:.2g} % of the largest reading",
                f"the model misses the steady readings by {100 * rms:.2g} % of the "
                "largest reading (rms; too few readings to show their own scatter, "
                "so read only on their noise prior)"))
        if t is None:
            continue
        against = ("their own scatter" if noise is Noise.SCATTER
                   else "any plausible instrument's noise")
        tests.append(Test(Finding(
            Check.STEADY_MISS, cid, Severity.FAIL,
            f"{100 * t.excess:.2g} % of the largest reading",
            f"the steady {signal}s miss the model by more than {against} (rms "
            f"{100 * t.excess:.2g} % of the largest reading)"), t.p_value,
            material=t.excess > MATERIAL_FRACTION))
    return rows, tests, found
