"""What a lagging sensor reads: a first-order lag (a tachometer, an RC or digital filter
on the speed or current signal) as one more linear state of the exact solution.

The sensor reads ``y`` with ``τs·dy/dt = x − y``, ``μ = −1/τs``.  Within each regime
of the exact solution (:mod:`.solution`, :mod:`.limited`) the true signal has a closed
form, and so has its reading from the reading ``y0`` at the regime's start:

* a constant or first-order signal ``x(τ) = x0 + (x∞ − x0)·(1 − e^(λτ))`` (the current
  held at rest, La/Ra; a clamped current; the speed of a clamped or coasting rotor,
  J/B) reads ``e^(μτ)·y0 + x0·(1 − e^(μτ)) + (x∞ − x0)·(1 − e^(μτ) + μ·E(λ, μ, τ))``,
  ``E = (e^(λτ) − e^(μτ))/(λ − μ)`` written without cancellation, λ = μ included;
* the moving motor ``x(τ) = x_ss + expm(A·τ)·d`` reads ``e^(μτ)·y0 + x_ss·(1 − e^(μτ))
  − μ·(A − μI)⁻¹·(expm(A·τ) − e^(μτ)·I)·d``, with ``expm(A·τ) = α·I + β·A``
  (:mod:`.propagator`).  Where μ is within a part in 10⁵ of one of A's real
  eigenvalues, where that resolvent is singular (and, close to it, loses the digits
  of its derivatives), μ is moved by six parts in 10⁵ (the lag by as much), far
  below what any data resolve.

A reading is carried through a segment's regimes (:func:`phase_starts`), from one
segment to the next and from a trace's start, where the sensor is settled (``y = x``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import motor
from .propagator import apply_alpha_beta, coefficients, coefficients_real
from .regimes import MOVING, STUCK, Phase, phase_voltage

__all__ = ["MIN_LAG", "pole", "lagged_first_order", "reading_in_phase", "phase_starts",
           "reading_in_segment", "coast_down_reading"]

MIN_LAG = 1e-12  # s: shorter than any logged interval, a lag taken as none at all
_NEAR = 1e-5  # relative distance of μ to an eigenvalue within which the resolvent is moved
_SHIFT = 6e-5  # relative shift of μ there (beyond the window, whichever side)


def pole(tau):
    """``μ = −1/τs`` of a sensor of time constant ``tau`` (s), at least :data:`MIN_LAG`."""
    return -1.0 / jnp.maximum(tau, MIN_LAG)


def _expm1_ratio(x):
    """``expm1(x)/x`` (1 at 0), finite with finite tangents everywhere."""
    small = jnp.abs(x) < 1e-8
    xs = jnp.where(small, 1.0, x)
    return jnp.where(small, 1.0 + 0.5 * x, jnp.expm1(xs) / xs)


def _divided_exp(lam, mu, tau):
    """``(e^(λτ) − e^(μτ))/(λ − μ)`` for real λ, μ, without cancellation (λ = μ too)."""
    hi = jnp.maximum(lam, mu)
    return jnp.exp(hi * tau) * tau * _expm1_ratio(-jnp.abs(lam - mu) * tau)


def lagged_first_order(y0, x0, step, lam, mu, tau):
    """Reading ``tau`` after ``y0`` of ``x(τ) = x0 + step·(1 − e^(λτ))`` (broadcasts)."""
    e = jnp.exp(mu * tau)
    rise = -jnp.expm1(mu * tau)
    return e * y0 + x0 * rise + step * (rise + mu * _divided_exp(lam, mu, tau))


def _lagged_moving(p, ss, d, y0, mu, tau, row, fast):
    """Reading of row ``row`` (0 current, 1 speed) of ``x_ss + expm(A·τ)·d``."""
    a11, a12, a21, a22 = -p.Ra / p.La, -p.K / p.La, p.K / p.J, -p.B / p.J
    tr, det = a11 + a22, a11 * a22 - a12 * a21

    def resolvent_det(m):
        return (a11 - m) * (a22 - m) - a12 * a21

    scale = mu * mu + jnp.abs(tr * mu) + jnp.abs(det)
    mu = jnp.where(jnp.abs(resolvent_det(mu)) < _NEAR * scale, mu * (1.0 + _SHIFT), mu)
    alpha, beta = (coefficients_real if fast else coefficients)(p, tau)
    e = jnp.exp(mu * tau)
    vi, vw = apply_alpha_beta(p, alpha - e, beta, d)
    if row == 0:
        f = (a22 - mu) * vi - a12 * vw
    else:
        f = -a21 * vi + (a11 - mu) * vw
    return e * y0 - jnp.expm1(mu * tau) * ss[row] - mu / resolvent_det(mu) * f


def reading_in_phase(p, va, tl, tc, limit, ph: Phase, y0, mu, tau, row: int, fast=False,
                     drop=None):
    """Reading of row ``row`` (0 the current, 1 the speed) ``tau`` after the start of
    phase ``ph`` (:class:`~.limited.Phase`), where it was ``y0`` (broadcasts); ``drop``
    (V), when given, opposes the current."""
    va = phase_voltage(va, drop, ph)
    ss = motor.steady_state(p.Ra, p.K, p.B, va, tl + ph.d * tc)
    moving = _lagged_moving(p, ss, (ph.ia - ss[0], ph.w - ss[1]), y0, mu, tau, row, fast)
    if row == 0:
        stuck = lagged_first_order(y0, ph.ia, va / p.Ra - ph.ia, -p.Ra / p.La, mu, tau)
        clamped = lagged_first_order(y0, ph.s * limit, 0.0, -p.Ra / p.La, mu, tau)
    else:
        stuck = jnp.exp(mu * tau) * y0
        net = jnp.where(ph.d == 0, 0.0, p.K * ph.s * limit - tl - ph.d * tc - p.B * ph.w)
        clamped = lagged_first_order(y0, ph.w, net / p.B, -p.B / p.J, mu, tau)
    return jnp.where(ph.mode == STUCK, stuck, jnp.where(ph.mode == MOVING, moving, clamped))


def _phase(phases: Phase, k):
    return jax.tree_util.tree_map(lambda a: a[k], phases)


def phase_starts(p, va, tl, tc, limit, phases: Phase, y0, mu, row: int, fast=False,
                 drop=None):
    """The reading at the start of each of a segment's phases (leading axis the phases),
    from ``y0`` at the segment's start; an unused phase (``t0`` infinite) repeats the
    last used one's."""
    ys = [jnp.asarray(y0, dtype=float) + jnp.zeros_like(phases.t0[0])]
    for k in range(1, phases.t0.shape[0]):
        prev, q = _phase(phases, k - 1), _phase(phases, k)
        ended = jnp.isfinite(q.t0)
        dur = jnp.where(ended, q.t0 - prev.t0, 0.0)
        y = reading_in_phase(p, va, tl, tc, limit, prev, ys[-1], mu, dur, row, fast, drop)
        ys.append(jnp.where(ended, y, ys[-1]))
    return jnp.stack(ys)


def reading_in_segment(p, va, tl, tc, limit, phases: Phase, starts, mu, tau, row: int,
                       fast=False, drop=None):
    """Reading ``tau`` after the segment's start (broadcasts over samples), from its
    phases and the readings at their starts (:func:`phase_starts`)."""
    ph, y = _phase(phases, 0), starts[0]
    for k in range(1, phases.t0.shape[0]):
        q = _phase(phases, k)
        on = tau >= q.t0
        ph = jax.tree_util.tree_map(lambda a, b, on=on: jnp.where(on, b, a), ph, q)
        y = jnp.where(on, starts[k], y)
    return reading_in_phase(p, va, tl, tc, limit, ph, y, mu, tau - ph.t0, row, fast, drop)


def coast_down_reading(B, J, w0, t, tc, mu):
    """What a lagging speed sensor, settled at ``t = 0``, reads of a coast-down from
    ``w0`` (:func:`~.motor.coast_down`): the decay towards ``−sign(ω0)·Tc/B`` until the
    rotor stops, then the reading's own decay towards 0."""
    lam = -B / J
    t_stop = -jnp.log1p(B * jnp.abs(w0) / jnp.where(tc > 0, tc, 1.0)) / lam
    t_stop = jnp.where(tc > 0, t_stop, jnp.inf)
    moving = jnp.minimum(t, jnp.where(jnp.isfinite(t_stop), t_stop, t))
    step = -w0 - jnp.sign(w0) * tc / B
    y = lagged_first_order(w0, w0, step, lam, mu, moving)
    return y * jnp.exp(mu * (t - moving))
