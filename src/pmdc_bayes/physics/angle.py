"""The rotor's angle: what a position sensor or an encoder reads.

The exact piecewise solution gives ``(ia, ω)`` at the samples; the angle between two
samples follows from them and the inputs' integrals by
:func:`~pmdc_bayes.physics.motor.angle_increment`, exactly for any piecewise-constant
input (the input integrals are summed per segment), with no quadrature of ω.  Where
Coulomb friction acts and ω stops or changes sign inside an interval, the friction
torque is not ``Tc·sign(ω)`` throughout and the interval is taken by the trapezoid
rule instead (the motor is then at or near rest, so the angle it misses is small).
With a current-limited driver, the intervals where the current is held at its limit
are taken as ``rotor_angle`` describes.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import motor
from .experiment import INITIAL_MODES, Experiment

__all__ = ["rotor_angle"]


def _input_integral(exp: Experiment, values, tau_pre):
    """``∫ u dt`` from each trace's start to each sample (padded layout), for the
    piecewise-constant segment values ``values``.  Before a trace's first segment the
    input is the one that keeps its initial state: 0 for a trace starting at rest, the
    first segment's for any other."""
    n = values.shape[0]
    idx = jnp.arange(n)
    whole = values * exp.seg_len
    before = jnp.cumsum(whole) - whole
    first = jax.lax.cummax(jnp.where(exp.seg_first, idx, 0))
    at_start = before - before[first]
    rest = exp.seg_mode == INITIAL_MODES["rest"]
    earlier = jnp.where(exp.seg_first, jnp.where(rest, 0.0, values),
                        jnp.concatenate([values[:1], values[:-1]]))
    s = exp.chunk_seg
    return at_start[s][:, None] + values[s][:, None] * exp.tau + earlier[s][:, None] * tau_pre


def rotor_angle(p, exp: Experiment, ia, w, t, start, *, coulomb: bool = False,
                limit=None):
    """The angle turned since each trace's first sample (rad), per sample in time order.

    Parameters
    ----------
    p : the motor's parameters (``Params``).
    exp : the experiment as the motor sees it (voltages less any drop, delayed samples,
        a trace's unknown drag in ``seg_b``/``seg_tc``).
    ia, w : the exact current and speed in the padded layout (no sensor applied).
    t, start : sample times and the first-sample flags, traces one after another.
    coulomb : whether friction (the motor's Tc or a trace's constant drag) acts.
    limit : the driver's current limit (A), or None.  While the current is held at it
        the driver lowers the voltage, so the logged voltage's integral no longer
        applies: an interval clamped at both ends takes the mechanical equation alone
        (``B·∫ω = K·∫ia − ∫T − J·Δω`` with ``∫ia = ±limit·h``, exact), one entering or
        leaving the clamp the trapezoid rule.
    """
    tau_pre = exp.tau_pre if exp.tau_pre is not None else jnp.zeros_like(exp.tau)
    cv = exp.unpad(_input_integral(exp, exp.seg_va, tau_pre))
    cl = exp.unpad(_input_integral(exp, exp.seg_tl, tau_pre))
    ia, w = exp.unpad(ia), exp.unpad(w)
    seg = exp.unpad(jnp.broadcast_to(exp.chunk_seg[:, None], exp.tau.shape))
    drag = exp.seg_b is not None
    b = p.B + (exp.seg_b[seg] if drag else 0.0)
    tc = (p.Tc + (exp.seg_tc[seg] if drag else 0.0)) if coulomb else jnp.zeros_like(w)

    def prev(x):
        return jnp.concatenate([x[:1], x[:-1]])

    h = t - prev(t)
    w0 = prev(w)
    exact = motor.angle_increment(p.Ra, p.La, p.K, b, p.J, cv - prev(cv),
                                  cl - prev(cl) + tc * jnp.sign(w) * h, ia - prev(ia), w - w0)
    one_sign = (tc == 0.0) | (w0 * w > 0.0)
    trapezoid = 0.5 * (w0 + w) * h
    d = jnp.where(one_sign, exact, trapezoid)
    if limit is not None:
        at = jnp.abs(ia) >= limit * (1.0 - 1e-9)
        held = at & prev(at) & (ia * prev(ia) > 0)
        dl = cl - prev(cl) + tc * jnp.sign(w) * h
        clamped = (p.K * ia * h - dl - p.J * (w - w0)) / b
        d = jnp.where(held & one_sign, clamped, jnp.where(at | prev(at), trapezoid, d))
    d = jnp.where(start, 0.0, d)
    total = jnp.cumsum(d)
    first = jax.lax.cummax(jnp.where(start, jnp.arange(t.shape[0]), 0))
    return total - total[first]
