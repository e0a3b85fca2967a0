"""The regimes of the regime-switching solution (:mod:`.limited`) and each one's closed
form.

* ``STUCK`` — at rest held by Coulomb friction, the current first order in La/Ra;
* ``MOVING`` — the two-state linear model (:mod:`.propagator`), friction opposing
  the motion;
* ``CLAMPED`` — the current held at ``±I`` by a current-limited driver, or at zero
  where a voltage drop lets none flow (``s = 0``), the speed first order in J/B (or
  held at rest when the torque cannot overcome the friction).

A :class:`Phase` is one such regime from its start; a segment is a stack of them
(leading axis the phases).  The free solution's segments (:mod:`.free`) are written in
the same form, so that a sensor's reading (:mod:`.sensor`) and the angle
(:mod:`.angle`) follow any of them alike.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import motor
from .propagator import apply_alpha_beta, coefficients, coefficients_real

__all__ = ["STUCK", "MOVING", "CLAMPED", "NO_LIMIT", "Phase", "phase_voltage", "sign",
           "moving", "clamped_rate", "drop_at", "state_at", "held_direction", "select",
           "clamped_steady"]

STUCK, MOVING, CLAMPED = 0, 1, 2
NO_LIMIT = 1e200  # A: a limit never reached (finite, so that no tangent meets infinity)


class Phase(NamedTuple):
    """One regime of a segment: its start ``t0`` after the segment's start (``inf``
    when unused), ``mode``, the direction ``d`` of motion (±1, 0 held at rest), the
    clamp's sign ``s`` (0 with ``mode`` CLAMPED: no current flows), the state
    ``(ia, w)`` at its start and the sign ``c`` of its current, which a voltage drop
    opposes (0 when none flows)."""

    t0: jax.Array
    mode: jax.Array
    d: jax.Array
    s: jax.Array
    ia: jax.Array
    w: jax.Array
    c: jax.Array


def phase_voltage(va, drop, ph: Phase):
    """The voltage that drives the armature in phase ``ph``: ``va − c·drop``."""
    return va if drop is None else va - ph.c * drop


def drop_at(drop, open_volts, va):
    """The drop opposing the armature's current under the command ``va``: ``drop``, or,
    where the driver opens the armature at a zero command (``open_volts`` given: an
    H-bridge whose enable is low, PWM in coast mode), ``open_volts`` there: the voltage
    the current's freewheel path (diodes back into the supply) sets against it, which
    ends the current within a fraction of La/Ra and lets none flow again while the
    back-emf stays below it; the rotor then coasts on its friction and load."""
    return drop if open_volts is None else jnp.where(va == 0, open_volts, drop)


def sign(x):
    """±1, +1 at 0."""
    return jnp.where(x >= 0, 1.0, -1.0)


def moving(p, va, tl, tc, ph, tau, fast):
    """``(ia, ω)`` ``tau`` into a moving phase driven by ``va``, friction opposing its
    direction."""
    ss_i, ss_w = motor.steady_state(p.Ra, p.K, p.B, va, tl + ph.d * tc)
    alpha, beta = (coefficients_real if fast else coefficients)(p, tau)
    di, dw = apply_alpha_beta(p, alpha, beta, (ph.ia - ss_i, ph.w - ss_w))
    return ss_i + di, ss_w + dw


def clamped_rate(p, tl, tc, limit, ph):
    """The net torque ``a`` at the clamped phase's start (``J·dω/dt``), so that
    ``ω(τ) = w + a·(1 − exp(−B·τ/J))/B``; 0 when held at rest."""
    a = p.K * ph.s * limit - tl - ph.d * tc - p.B * ph.w
    return jnp.where(ph.d == 0, 0.0, a)


def state_at(p, va, tl, tc, limit, ph: Phase, tau, fast=False, drop=None):
    """``(ia, ω)`` at ``tau`` after the phase's start, in its regime (broadcasts)."""
    v = phase_voltage(va, drop, ph)
    i_s = motor.stuck_current(p.Ra, p.La, ph.ia, v, tau)
    i_m, w_m = moving(p, v, tl, tc, ph, tau, fast)
    a = clamped_rate(p, tl, tc, limit, ph)
    w_c = ph.w + a * -jnp.expm1(-p.B * tau / p.J) / p.B
    ia = jnp.where(ph.mode == STUCK, i_s, jnp.where(ph.mode == MOVING, i_m, ph.s * limit))
    w = jnp.where(ph.mode == STUCK, 0.0, jnp.where(ph.mode == MOVING, w_m, w_c))
    return ia, w


def held_direction(p, tl, tc, s, limit):
    """Direction a clamped rotor at rest takes: that of its torque, 0 if friction holds."""
    net = p.K * s * limit - tl
    return jnp.where(jnp.abs(net) > tc, sign(net), 0.0)


def select(phases: Phase, tau) -> Phase:
    """The phase each ``tau`` lies in."""
    ph = jax.tree_util.tree_map(lambda a: a[0], phases)
    for k in range(1, phases.t0.shape[0]):
        q = jax.tree_util.tree_map(lambda a, k=k: a[k], phases)
        on = tau >= q.t0
        ph = jax.tree_util.tree_map(lambda a, b, on=on: jnp.where(on, b, a), ph, q)
    return ph


def clamped_steady(p, va, tl, tc, limit, ia, w):
    """A steady state ``(ia, w)`` with the limit applied: a current beyond ``±limit`` is
    held there, the speed from the torque balance (at rest if friction holds it)."""
    s = sign(ia)
    over = jnp.abs(ia) > limit
    net = p.K * s * limit - tl
    w_c = jnp.where(jnp.abs(net) > tc, (net - sign(net) * tc) / p.B, 0.0)
    return jnp.where(over, s * limit, ia), jnp.where(over, w_c, w)
