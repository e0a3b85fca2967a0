"""Joint MAP fit of a session (optimistix's Levenberg–Marquardt), with Laplace
uncertainty.

The MAP maximises :meth:`SessionModel.log_posterior`.  With each channel's noise
integrated out, its stationary point is a weighted least-squares problem whose
weights ``(n_c + ν0)/(ν0·s0_c² + SS_c)`` depend on the residuals themselves; every
step of :mod:`.optimiser` takes the curvature with the weights at its own point and is
accepted only when the exact log-posterior rises, so the fixed point is the exact
MAP.  Several starts (the seed, other seeds, copies near it and copies over the
prior's range) are moved side by side, so a poor seed cannot leave the fit in a local
minimum unnoticed, and the distinct optima they reach are counted.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

from ..._x64 import x64
from ..model.noise import noise_weights
from ..model.objective import SessionModel
from .box import scan_start, settled
from .curvature import Terms, invert_curvature, transform_curvature
from .multistart import MAX_STEPS, WINDOW, Outcome, maximise
from .optima import distinct_optima
from .optimiser import Stepper

__all__ = ["FitStatus", "FitResult", "fit_map", "laplace"]

N_STARTS = 8
START_SPREAD = 0.3
ABANDON_AFTER = 20  # accepted steps after which a start far below the best stops
RELEVANT = 10.0
MODE_SHARE = 0.01  # a distinct optimum this dense relative to the MAP joins its spread
WIDE_SPREAD = 1.0  # least log spread of the starts over the prior's range


class FitStatus(enum.StrEnum):
    """Whether the MAP fit found an optimum it can stand by."""

    CONVERGED = "converged"
    FAILED = "failed"


@dataclass(frozen=True)
class FitResult:
    """The MAP and its Laplace approximation.

    Attributes
    ----------
    theta : MAP in log space.
    values, sd : MAP and Laplace standard deviation per parameter (SI).
    cov_log : Laplace covariance in log space; ``corr`` its correlation matrix.
    status : :class:`FitStatus`; ``message`` says why in words.
    starts : per start, where it began, its final log-posterior and whether it agreed
        with the best.
    n_modes : how many distinct optima the starts reached (the best is the MAP);
        ``mode_gaps`` how far below the MAP's log-posterior each of the others is.
    weights : per-channel 1/σ² at the MAP; ``noise_sd`` the matching σ by
        :class:`~pmdc_bayes.io.channel.ChannelId`.
    iterations : optimistix steps (evaluations) of the best start.
    cov_map : the Laplace covariance of the MAP's own curvature, when ``cov_log`` spans
        several optima of nearly equal density (their mixture's); None otherwise.
    log_mass : the log of those optima's Laplace mass relative to the MAP's (0 for one).
    outcome : how the best start ended (:class:`~pmdc_bayes.inference.fit.multistart.Outcome`); at
        its step limit (``Outcome.MAX_STEPS``) the fit has ``status`` ``FitStatus.FAILED`` and
        its ``message`` says so first.
    """

    names: tuple
    theta: np.ndarray
    values: dict
    sd: dict
    cov_log: np.ndarray
    corr: np.ndarray
    log_posterior: float
    status: FitStatus
    message: str
    starts: list = field(default_factory=list)
    weights: np.ndarray | None = None
    noise_sd: dict = field(default_factory=dict)
    iterations: int = 0
    n_modes: int = 1
    mode_gaps: tuple = ()
    outcome: Outcome = Outcome.CONVERGED
    cov_map: np.ndarray | None = None
    log_mass: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status is FitStatus.CONVERGED

    @property
    def overflows(self) -> bool:
        """The Laplace covariance is not finite: the model's predictions overflow near
        the MAP, so neither its curvature nor any evidence from it can be read."""
        return not np.all(np.isfinite(self.cov_log))


def _starts(model: SessionModel, theta0, n: int, rng: np.random.Generator, alternatives=()):
    """``(starts, origins)``: ``theta0``; the ``alternatives`` (other seeds); then half of
    the rest within ``START_SPREAD`` (log) of ``theta0`` and half drawn over the prior's
    plausible range (its centre ± one prior width, at least ``WIDE_SPREAD`` in log, clipped
    at two), so that a better
    optimum away from the seed is found rather than assumed away."""
    theta0 = np.asarray(theta0, dtype=float)
    rows, origins = [theta0], ["seed"]
    for alt in alternatives:
        if len(rows) < n:
            rows.append(np.asarray(alt, dtype=float))
            origins.append("alternative seed")
    rest = n - len(rows)
    n_near = rest - rest // 2
    width = np.asarray(model.prior_sd, dtype=float)
    is_log = model.registry.is_log()  # untransformed parameters spread by their prior sd
    near_sd = np.where(is_log, np.minimum(width, START_SPREAD), START_SPREAD * width)
    wide_sd = np.where(is_log, np.maximum(width, WIDE_SPREAD), width)
    near = theta0 + rng.standard_normal((n_near, theta0.size)) * near_sd
    centre = np.asarray(model.registry.seed_theta(), dtype=float)
    wide = centre + np.clip(rng.standard_normal((rest - n_near, theta0.size)), -2.0, 2.0) \
        * wide_sd
    rows += list(near) + list(wide)
    origins += ["near the seed"] * n_near + ["over the prior's range"] * (rest - n_near)
    return np.asarray(rows), origins


def _far_below(start, best: float) -> bool:
    """A start that, after :data:`ABANDON_AFTER` accepted steps, lies far below the best
    (more than :data:`RELEVANT` log-posterior units and 1 % of its size): a poor local
    optimum or a slow crawl, not worth finishing.  Accepted steps, not evaluations: a
    rejected trial costs one forward pass of the model, and a start whose trust region
    shrinks and grows again is not slower for it."""
    return len(start.history) >= ABANDON_AFTER and np.isfinite(best) and (
        start.lp < best - max(RELEVANT, 1e-2 * abs(best)))


@x64
def laplace(model: SessionModel, theta, terms: Terms | None = None):
    """Covariance in log space from the Gauss–Newton Hessian at ``theta`` and the
    curvature of the log transforms (:func:`.curvature.transform_curvature`), inverted
    in the scale of its diagonal (:func:`.curvature.invert_curvature`); ``(cov, H)``.

    Notes
    -----
    A channel contributes ``(n_c + ν0)/2 · log(A_c)`` with ``A_c = ν0·s0_c² + SS_c`` to the
    negative log-posterior (its noise integrated out).  With the Gauss–Newton
    approximation ``∇²SS_c ≈ 2·J_cᵀJ_c`` its Hessian is
    ``w_c·J_cᵀJ_c − w_c²/(2(n_c + ν0)) · g_c g_cᵀ``, ``w_c = (n_c + ν0)/A_c``,
    ``g_c = ∇SS_c``: the second term is the curvature given up by not knowing the
    noise level, which matters for channels with few observations.
    """
    if terms is None:
        terms = Stepper.of(model).terms(theta)
    H = np.asarray(terms.H_noise) + np.diag(transform_curvature(model))
    if not np.all(np.isfinite(H)):  # the model overflows near θ: no curvature to invert
        return np.full(H.shape, np.nan), H
    cov = invert_curvature(H)
    return cov, H


@x64
def fit_map(model: SessionModel, *, theta0=None, n_starts: int = N_STARTS, seed: int = 0,
            alternatives=()) -> FitResult:
    """Maximise the log-posterior from the closed-form seed and perturbed copies of it.

    Parameters
    ----------
    model : the session objective.
    theta0 : starting point in log space (default: the closed-form seed).
    n_starts : number of starts (the first is ``theta0`` itself).
    seed : seed of the perturbations.
    alternatives : other starting points in θ space (e.g. a seed from the data when
        ``theta0`` is the closed form's), solved together with the rest.
    """
    theta0 = np.asarray(model.theta_seed() if theta0 is None else theta0, dtype=float)
    stepper = Stepper.of(model)
    scanned = scan_start(model, stepper, theta0)
    moved = scanned != theta0  # the leads the scan set: every seed starts them there
    alternatives = [np.where(moved, scanned, a) for a in alternatives]
    rng = np.random.default_rng(seed)
    starts, origins = _starts(model, scanned, n_starts, rng, alternatives)
    states = maximise(stepper, starts, abandon=_far_below)
    best = int(np.argmax([st.lp if np.isfinite(st.lp) else -np.inf for st in states]))
    states[best] = settled(model, stepper, states[best])
    return _finish(model, states, origins, stepper.terms)


def _mixture(model, states, spanned, logp, best, cov) -> tuple[np.ndarray, float]:
    """The covariance of the mixture of the Laplace approximations at the distinct optima
    ``spanned``, each weighted by its Laplace mass ``exp(Δ log p)·√(det Σ_k / det Σ_MAP)``,
    and the log of their total mass relative to the MAP's: the starts found optima of
    nearly equal density that the MAP's curvature alone (``cov``) does not reach, so the
    posterior spreads over all of them (a ridge the data do not resolve, or several
    modes).  An optimum whose own curvature is not finite is left out."""
    sign, logdet_map = np.linalg.slogdet(cov)
    if sign <= 0:
        return cov, 0.0
    parts = []
    for i in spanned:
        c = cov if i == best else laplace(model, states[i].theta, states[i].terms)[0]
        sign, logdet = np.linalg.slogdet(c) if np.all(np.isfinite(c)) else (0.0, 0.0)
        if sign > 0:
            parts.append((logp[i] - logp[best] + 0.5 * (logdet - logdet_map),
                          np.asarray(states[i].theta), c))
    if len(parts) < 2:
        return cov, 0.0
    log_w = np.array([p[0] for p in parts])
    log_mass = float(np.logaddexp.reduce(log_w))
    w = np.exp(log_w - log_mass)
    mean = sum(wk * th for wk, (_, th, _) in zip(w, parts, strict=True))
    mix = sum(wk * (c + np.outer(th - mean, th - mean))
              for wk, (_, th, c) in zip(w, parts, strict=True))
    return mix, log_mass


def _finish(model, states, origins, evaluate) -> FitResult:
    thetas = np.array([st.theta for st in states])
    logp = np.array([st.lp if np.isfinite(st.lp) else -np.inf for st in states])
    ok = np.array([st.converged for st in states])
    best = int(np.argmax(logp))
    theta = thetas[best]
    terms = states[best].terms
    cov, _ = laplace(model, theta, terms)
    modes, label = distinct_optima(thetas, logp, ok, cov, evaluate)
    spanned = [i for i in modes if logp[best] - logp[i] <= -np.log(MODE_SHARE)]
    cov_map, log_mass = None, 0.0
    if len(spanned) > 1 and best in spanned:
        cov_map = cov
        cov, log_mass = _mixture(model, states, spanned, logp, best, cov)
    agree = np.array([lab == best for lab in label]) | (np.arange(len(states)) == best)
    starts = [{"start": i, "origin": origins[i], "log_posterior": float(logp[i]),
               "agrees": bool(agree[i]), "solver_ok": bool(ok[i]), "steps": st.steps,
               "stopped": st.stopped, "outcome": st.outcome.name}
              for i, st in enumerate(states)]
    w = noise_weights(np.asarray(terms.ss), np.asarray(model.n_obs), np.asarray(model.s0))
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    corr = cov / np.outer(sd_log, sd_log)
    vals = model.registry.to_values(theta)
    values = dict(zip(model.names, map(float, vals), strict=True))
    sd = dict(zip(model.names, map(float, model.registry.sd_values(theta, sd_log)),
                  strict=True))
    noise = {c.id: float(1.0 / np.sqrt(w[k])) for k, c in enumerate(model.channels) if c.n > 0}
    reasons = []
    if not np.isfinite(logp[best]):
        reasons.append("no start reached a finite log-posterior (the model cannot "
                       "reproduce the data with positive parameters)")
    elif states[best].outcome is Outcome.MAX_STEPS:
        reasons.append(_at_step_limit(states[best]))
    elif not ok[best]:
        reasons.append(f"Levenberg–Marquardt stopped before the optimum at the best start "
                       f"({states[best].stopped} after {states[best].steps} steps)")
    if not np.all(np.isfinite(cov)):
        reasons.append("the curvature at the optimum is not finite: the model's predictions "
                       "overflow near it (check the magnitudes the session gives, such as a "
                       "known load's coefficients and curve)")

    status = FitStatus.FAILED if reasons else FitStatus.CONVERGED
    n_agree = int(agree.sum())
    n_wide = sum(o == "over the prior's range" for o in origins)
    found = (f"{len(modes)} distinct optimum" if len(modes) == 1
             else f"{len(modes)} distinct optima, the best chosen")
    if len(spanned) > 1 and best in spanned:
        found += (f"; the uncertainty spans the {len(spanned)} of nearly equal density (within "
                  f"{-np.log(MODE_SHARE):.1f} log-posterior units: a ridge or modes the data "
                  "do not resolve)")
    message = "; ".join(reasons) if reasons else (
        f"converged in {states[best].steps} Levenberg–Marquardt steps; {n_agree} of "
        f"{len(logp)} starts agree ({n_wide} started over the prior's range; {found})")
    return FitResult(tuple(model.names), theta, values, sd, cov, corr, float(logp[best]),
                     status, message, starts, w, noise, states[best].steps, len(modes),
                     tuple(float(logp[best] - logp[i]) for i in modes[1:]),
                     states[best].outcome, cov_map, log_mass)


def _at_step_limit(start) -> str:
    """Why a MAP whose start ended at its step limit is no optimum, in words."""
    h = start.history
    gain = h[-1] - h[max(0, len(h) - 1 - WINDOW)] if len(h) > 1 else 0.0
    raised = f", raised from {MAX_STEPS} while it improved" if start.limit > MAX_STEPS else ""
    return (f"the MAP is not an optimum: its Levenberg–Marquardt start stopped at its step "
            f"limit ({start.steps} steps{raised}) with the log-posterior still rising "
            f"({gain:.3g} over its last {min(WINDOW, max(len(h) - 1, 0))} accepted steps): "
            "a badly scaled or nearly unidentified direction; the values are where it "
            "stopped")
