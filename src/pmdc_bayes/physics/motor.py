"""The motor's equations, written once: every other module calls these.

Equations (1)–(22) of the reference paper (``docs/architecture.md`` lists who uses
what).  Everything is SI: Ra (Ω), La (H), K = Kt = Kb (V·s/rad = N·m/A),
B (N·m·s/rad), J (kg·m²), Tc (N·m), Va (V), TL (N·m), ia (A), ω (rad/s).

The functions are plain arithmetic, so they accept Python floats, NumPy arrays
(e.g. posterior draws) and JAX arrays or tracers alike; where a branch is needed
(Coulomb friction) the array library of the arguments is used.

State order
-----------
The documented state-space order is the paper's, equations (11)–(14):
``x = (ω, ia)``, ``u = (TL, Va)``, ``y = ω`` (:data:`STATE`, :data:`INPUT`).  Functions
returning a pair of signals return them as ``(ia, ω)`` (the order of equations
(5)–(6)) and say so.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "STATE",
    "INPUT",
    "OUTPUT",
    "derivatives",
    "steady_with_drop",
    "driver_output",
    "angle_increment",
    "steady_state",
    "time_constant",
    "electrical_time_constant",
    "gain",
    "tf_full",
    "tf_first_order",
    "tf_normalised",
    "state_space",
]

STATE = ("omega", "ia")
INPUT = ("TL", "Va")
OUTPUT = ("omega",)


def _xp(*args):
    """NumPy, or jax.numpy when any argument is a JAX array (or tracer)."""
    return jnp if any(isinstance(a, jax.Array) for a in args) else np


def derivatives(Ra, La, K, B, J, ia, w, va=0.0, tl=0.0, tc=0.0):
    """``(dia/dt, dω/dt)``, equations (5)–(6), with a friction torque ``tc`` (N·m) opposing
    the motion (pass ``Tc·sign(ω)``; 0 for the viscous model).

    With ``va = tl = tc = 0`` this is the state matrix applied to ``(ia, ω)``.
    """
    return (va - Ra * ia - K * w) / La, (K * ia - B * w - tl - tc) / J


def stuck_current(Ra, La, ia0, va, tau):
    """The current ``tau`` after ``ia0`` with the rotor held at rest (ω = 0 in (5)):
    first order towards ``va/Ra`` with time constant La/Ra."""
    i_inf = va / Ra
    return i_inf + (ia0 - i_inf) * _xp(Ra, La, ia0, va, tau).exp(-Ra / La * tau)


def angle_increment(Ra, La, K, B, J, dv, dt_load, dia, dw):
    """The angle (rad) the rotor turns over an interval, exactly, from the two
    equations (5)–(6) integrated over it: ``dv = ∫Va dt``, ``dt_load = ∫(TL + friction
    torque) dt`` and the changes ``dia``, ``dw`` of the current and speed.

    Integrating La·dia/dt = Va − Ra·ia − K·ω and J·dω/dt = K·ia − B·ω − T and
    eliminating ∫ia: ``∫ω dt = (K·∫Va − Ra·∫T − Ra·J·Δω − K·La·Δia)/(K² + Ra·B)``.
    Exact for any input within the interval; for Coulomb friction only where ω keeps
    one sign (the friction torque is then ``Tc·sign(ω)``).
    """
    return (K * dv - Ra * dt_load - Ra * J * dw - K * La * dia) / (K * K + Ra * B)


def steady_state(Ra, K, B, va, tl=0.0, tc=None):
    """Steady ``(ia, ω)`` under constant Va and TL, equations (15)–(18).

    Parameters
    ----------
    Ra, K, B : motor parameters (SI).
    va, tl : armature voltage (V) and load torque (N·m); arrays broadcast.
    tc : Coulomb friction torque (N·m), or None for the viscous model.

    Notes
    -----
    Solving A·x + Bu·u = 0: ``ω = (K·Va − Ra·TL)/(K² + Ra·B)`` and
    ``ia = (B·Va + K·TL)/(K² + Ra·B)``; with TL = 0 these are (17) and (18).  With
    Coulomb friction the motor turns in the direction of the driving torque
    ``K·Va/Ra − TL`` when it exceeds Tc, and the friction adds ``Tc`` to the load in that
    direction; otherwise it is held at rest, ``ω = 0`` and ``ia = Va/Ra``.
    """
    den = K * K + Ra * B
    if tc is None:
        return (B * va + K * tl) / den, (K * va - Ra * tl) / den
    xp = _xp(Ra, K, B, va, tl, tc)
    drive = K * va / Ra - tl
    t_eff = tl + xp.where(drive >= 0, 1.0, -1.0) * tc
    stuck = xp.abs(drive) <= tc
    ia = xp.where(stuck, va / Ra, (B * va + K * t_eff) / den)
    w = xp.where(stuck, 0.0, (K * va - Ra * t_eff) / den)
    return ia, w


def steady_with_drop(Ra, K, B, va, tl=0.0, tc=None, drop=0.0):
    """Steady ``(ia, ω)`` when a constant ``drop`` (brushes, driver) opposes the current:
    :func:`steady_state` at ``va − drop`` where its current is positive, at ``va + drop``
    where negative; else no current flows and the rotor turns as its load and friction
    leave it (``B·ω = −TL − Tc·sign(ω)``, at rest while ``|TL| ≤ Tc``)."""
    xp = _xp(Ra, K, B, va, tl, drop)
    i_pos, w_pos = steady_state(Ra, K, B, va - drop, tl, tc)
    i_neg, w_neg = steady_state(Ra, K, B, va + drop, tl, tc)
    if tc is None:
        w_open = -tl / B
    else:
        w_open = xp.where(xp.abs(tl) > tc, (-tl + xp.sign(tl) * tc) / B, 0.0)
    pos, neg = i_pos > 0, i_neg < 0
    return (xp.where(pos, i_pos, xp.where(neg, i_neg, 0.0)),
            xp.where(pos, w_pos, xp.where(neg, w_neg, w_open)))


def driver_output(va, forward=0.0, reverse=0.0):
    """The voltage a driver with a dead zone puts out for the command ``va`` (V): a
    positive command less ``forward``, a negative one less ``reverse`` in magnitude, and
    nothing while the command is within the zone (``va − forward`` held at 0 from above,
    ``va + reverse`` from below; a zero command gives 0)."""
    xp = _xp(va, forward, reverse)
    return xp.where(va > 0, xp.maximum(va - forward, 0.0),
                    xp.where(va < 0, xp.minimum(va + reverse, 0.0), 0.0 * va))


def coast_down(B, J, w0, t, tc=0.0):
    """Speed of a rotor coasting with the armature open (no current, no load) from ``w0``
    at ``t = 0``: ``J·dω/dt = −B·ω − Tc·sign(ω)``.

    ``ω(t) = sign(ω0)·max(|ω0|·e^(−x) + (Tc/B)·(e^(−x) − 1), 0)`` with ``x = t·B/J``: an
    exponential decay with the mechanical time constant J/B, shifted down by the
    Coulomb torque, which stops the rotor in finite time and then holds it.  Written
    with ``expm1`` so that it stays exact as B → 0 (a linear run-down ``−Tc·t/J``).
    """
    xp = _xp(B, J, w0, t, tc)
    x = t * B / J
    moving = xp.abs(w0) * xp.exp(-x) + tc * t / J * _expm1_ratio(xp, x)
    return xp.sign(w0) * xp.maximum(moving, 0.0)


def _expm1_ratio(xp, x):
    """``(e^(−x) − 1)/x``, finite at x = 0 (−1 there)."""
    small = xp.abs(x) < 1e-8
    safe = xp.where(small, 1.0, x)
    return xp.where(small, -1.0 + 0.5 * x, xp.expm1(-safe) / safe)


def time_constant(Ra, K, B, J):
    """Mechanical time constant with La neglected, equation (9): ``τ = J·Ra/(B·Ra + K²)`` (s)."""
    return J * Ra / (B * Ra + K * K)


def electrical_time_constant(Ra, La):
    """``τe = La/Ra`` (s)."""
    return La / Ra


def gain(Ra, K, B):
    """Steady-state gain in rad/s per V, equation (10): ``G = Kt/(B·Ra + Kb·Kt)``."""
    return K / (B * Ra + K * K)


def tf_full(Ra, La, K, B, J):
    """Equation (7): ω/Va = K / ((La·s + Ra)(J·s + B) + K²), as (num, den), highest power first."""
    return np.array([K]), np.array([La * J, La * B + Ra * J, Ra * B + K * K])


def tf_first_order(Ra, K, B, J):
    """Equation (8): ω/Va = G / (τ·s + 1), as (num, den)."""
    return np.array([gain(Ra, K, B)]), np.array([time_constant(Ra, K, B, J), 1.0])


def tf_normalised(Ra, La, K, B, J):
    """Equation (22): equation (7) with numerator and denominator divided by J."""
    num, den = tf_full(Ra, La, K, B, J)
    return num / J, den / J


def state_space(Ra, La, K, B, J):
    """State-space matrices (11)–(14) in the documented order: x = (ω, ia), u = (TL, Va),
    y = ω."""
    xp = _xp(Ra, La, K, B, J)
    A = xp.array([[-B / J, K / J], [-K / La, -Ra / La]])
    Bu = xp.array([[-1.0 / J, 0.0], [0.0, 1.0 / La]])
    C = np.array([[1.0, 0.0]])
    D = np.zeros((1, 2))
    return A, Bu, C, D
