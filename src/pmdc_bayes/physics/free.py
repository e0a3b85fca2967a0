"""The exact solution within a constant segment without a current limit: the viscous
motor, or Coulomb friction's stick and slip.

Between input changes the viscous model is linear and time-invariant, so its state is
``x_ss + expm(A·τ)·(x0 − x_ss)`` (:mod:`.propagator`).  Coulomb friction is a constant
torque ``Tc·sign(ω)`` while the motor turns, with the rotor held at rest while the
driving torque cannot overcome it; the breakaway (in closed form) and the stop (bracketed
by bisection, then Newton steps that carry its dependence on the parameters) are
located inside each segment, so the solution stays exact.  :func:`phases` gives the
segment's regimes in the form of :mod:`.limited`, for a sensor's reading
(:mod:`.sensor`).  Parameters are any record with fields Ra, La, K, B, J, Tc.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import motor
from .propagator import apply_alpha_beta, coefficients, coefficients_real
from .regimes import MOVING, STUCK, Phase

__all__ = ["Segment", "moving", "segment_info", "state_in_segment", "angle_in_segment",
           "phases"]


def _steady_coulomb(p, va, tl, direction):
    """Steady state of the moving phase, friction ``Tc`` opposing ``direction``."""
    return motor.steady_state(p.Ra, p.K, p.B, va, tl + direction * p.Tc)


def _stuck_current(p, ia0, va, tau):
    """Current with the rotor held at rest: first order with time constant La/Ra."""
    return motor.stuck_current(p.Ra, p.La, ia0, va, tau)


class Segment(NamedTuple):
    """One segment's regimes, located from its starting state."""

    ia0: jax.Array       # current at the segment start
    t_move: jax.Array    # breakaway time after the start (0 if moving, inf if never)
    xm_i: jax.Array      # state when motion starts
    xm_w: jax.Array
    ss_i: jax.Array      # steady state of the moving phase
    ss_w: jax.Array
    t_stop: jax.Array    # stop time after breakaway (inf if it does not stop)
    i_stop: jax.Array    # current at the stop
    w0: jax.Array        # speed at the segment start
    d: jax.Array         # direction friction opposes while moving (0 without friction)


def moving(p, seg, tau_m, fast=False):
    """``(ia, ω)`` ``tau_m`` into the segment's moving phase."""
    alpha, beta = (coefficients_real if fast else coefficients)(p, tau_m)
    di, dw = apply_alpha_beta(p, alpha, beta, (seg.xm_i - seg.ss_i, seg.xm_w - seg.ss_w))
    return seg.ss_i + di, seg.ss_w + dw


def segment_info(p, x, va, tl, length, coulomb: bool, fast: bool) -> Segment:
    ia0, w0 = x
    inf = jnp.inf
    if not coulomb:
        ss_i, ss_w = motor.steady_state(p.Ra, p.K, p.B, va, tl)
        zero = jnp.zeros_like(ia0)
        return Segment(ia0, zero, ia0, w0, ss_i, ss_w, zero + inf, zero, w0, zero)
    at_rest = w0 == 0.0
    drive = p.K * va / p.Ra - tl
    now = p.K * ia0 - tl  # a torque past the friction already moves the rotor its way
    already = jnp.abs(now) > p.Tc
    toward = jnp.where(already, now, drive)
    direction = jnp.where(at_rest, jnp.where(toward >= 0, 1.0, -1.0),
                          jnp.where(w0 >= 0, 1.0, -1.0))
    # Breakaway from rest: K·ia − TL reaches ±Tc while ia rises towards Va/Ra.
    i_star = (tl + direction * p.Tc) / p.K
    i_inf = va / p.Ra
    possible = direction * drive > p.Tc
    breaks = possible & ~already
    ratio = jnp.where(breaks, (i_inf - i_star) / jnp.where(breaks, i_inf - ia0, 1.0), 1.0)
    t_break = -p.La / p.Ra * jnp.log(jnp.clip(ratio, 1e-300, 1.0))
    t_move = jnp.where(at_rest, jnp.where(already, 0.0, jnp.where(possible, t_break, inf)), 0.0)
    xm_i = jnp.where(at_rest & ~already, i_star, ia0)
    ss_i, ss_w = _steady_coulomb(p, va, tl, direction)
    seg = Segment(ia0, t_move, xm_i, w0, ss_i, ss_w, jnp.zeros_like(ia0) + inf, ia0, w0,
                   direction)
    # Stop: the moving phase crosses ω = 0 before the segment ends.
    span = jnp.clip(length - jnp.where(jnp.isfinite(t_move), t_move, length), 0.0, None)
    _, w_end = moving(p, seg, span, fast)
    stops = jnp.isfinite(t_move) & (direction * w_end < 0)

    # Bisection brackets the root without derivatives (no tangents flow through the
    # loop); the Newton steps below carry its dependence on the parameters.
    p_c, seg_c, dir_c = jax.lax.stop_gradient((p, seg, direction))

    def bisect(_, lohi):
        lo, hi = lohi
        mid = 0.5 * (lo + hi)
        _, wm = moving(p_c, seg_c, mid, fast)
        pos = dir_c * wm > 0
        return jnp.where(pos, mid, lo), jnp.where(pos, hi, mid)

    span_c = jax.lax.stop_gradient(span)
    lo, hi = jax.lax.fori_loop(0, 60, bisect, (jnp.zeros_like(span_c), span_c))
    t_root = jax.lax.stop_gradient(jnp.where(stops, 0.5 * (lo + hi), 0.0))
    for _ in range(2):  # Newton steps carry the root's dependence on the parameters
        i_r, w_r = moving(p, seg, t_root, fast)
        _, dw_dt = motor.derivatives(p.Ra, p.La, p.K, p.B, p.J, i_r, w_r, tl=tl,
                                     tc=direction * p.Tc)
        # Only where the motor stops: elsewhere the step would run off to huge times,
        # whose overflowing exponentials poison reverse-mode derivatives.
        t_root = jnp.where(stops, t_root - w_r / jnp.where(dw_dt == 0, 1.0, dw_dt), 0.0)
    i_stop, _ = moving(p, seg, t_root, fast)
    return seg._replace(t_stop=jnp.where(stops, t_root, inf),
                        i_stop=jnp.where(stops, i_stop, ia0))


def state_in_segment(p, seg: Segment, va, tau, coulomb: bool, fast: bool):
    """State at ``tau`` after the segment start (broadcasts over samples)."""
    if not coulomb:
        return moving(p, seg, tau, fast)
    t_move = jnp.where(jnp.isfinite(seg.t_move), seg.t_move, 0.0)
    tau_m = jnp.clip(tau - t_move, 0.0, None)
    t_end = jnp.where(jnp.isfinite(seg.t_stop), seg.t_stop, tau_m)
    i_m, w_m = moving(p, seg, jnp.minimum(tau_m, t_end), fast)
    i_pre = _stuck_current(p, seg.ia0, va, tau)
    t_stop = jnp.where(jnp.isfinite(seg.t_stop), seg.t_stop, 0.0)
    i_post = _stuck_current(p, seg.i_stop, va, jnp.clip(tau_m - t_stop, 0.0, None))
    before = tau < seg.t_move
    after = jnp.isfinite(seg.t_stop) & (tau_m >= seg.t_stop)
    ia = jnp.where(before, i_pre, jnp.where(after, i_post, i_m))
    w = jnp.where(before | after, 0.0, w_m)
    return ia, w


def angle_in_segment(p, seg: Segment, va, tl, tau, ia, w):
    """Angle turned from the segment's start to ``tau`` after it, where the state is
    ``(ia, w)``: the moving phase's, exactly (:func:`~.motor.angle_increment`), nothing
    while the rotor is held at rest."""
    t_move = jnp.where(jnp.isfinite(seg.t_move), seg.t_move, 0.0)
    moves = jnp.isfinite(seg.t_move) & (tau >= t_move)
    dt = jnp.clip(tau - t_move, 0.0, None)
    stopped = jnp.isfinite(seg.t_stop) & (dt >= seg.t_stop)
    dt = jnp.where(stopped, jnp.where(jnp.isfinite(seg.t_stop), seg.t_stop, 0.0), dt)
    i_end, w_end = jnp.where(stopped, seg.i_stop, ia), jnp.where(stopped, 0.0, w)
    a = motor.angle_increment(p.Ra, p.La, p.K, p.B, p.J, va * dt, (tl + seg.d * p.Tc) * dt,
                              i_end - seg.xm_i, w_end - seg.xm_w)
    return jnp.where(moves, a, 0.0)


def phases(seg: Segment, coulomb: bool) -> Phase:
    """The segment's regimes as :class:`~.limited.Phase` records (leading axis the
    phases): moving throughout for the viscous model; with Coulomb friction, held at
    rest until the breakaway, moving, then held again after a stop (a phase that never
    starts has an infinite ``t0``)."""
    zero = jnp.zeros_like(seg.ia0)
    one = zero + 1.0  # the current's sign matters only to a voltage drop (not here)
    if not coulomb:
        return jax.tree_util.tree_map(
            lambda a: a[None], Phase(zero, zero + MOVING, seg.d, zero, seg.xm_i, seg.xm_w, one))
    stops = jnp.isfinite(seg.t_move) & jnp.isfinite(seg.t_stop)
    t_stop = jnp.where(stops, jnp.where(stops, seg.t_move, 0.0) + seg.t_stop, jnp.inf)
    held = Phase(zero, zero + STUCK, zero, zero, seg.ia0, zero, one)
    move = Phase(seg.t_move, zero + MOVING, seg.d, zero, seg.xm_i, seg.xm_w, one)
    after = Phase(t_stop, zero + STUCK, zero, zero, seg.i_stop, zero, one)
    return jax.tree_util.tree_map(lambda *a: jnp.stack(a), held, move, after)
