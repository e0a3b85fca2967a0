"""What a sensor makes of the motor's state: a first-order lag (a tachometer, an RC or
digital filter on the speed or current signal).

The sensor reads ``y`` with ``τs·dy/dt = x − y``.  Over each sample interval
``[t_{k−1}, t_k]`` of length ``h`` the true signal ``x`` is taken as the parabola
through ``x_{k−1}, x_k, x_{k+1}`` (at a trace's last interval, through
``x_{k−2}, x_{k−1}, x_k``), for which the update is exact:

    y_k = a·y_{k−1} + x_{k−1}·I0 + d1·I1 + d2·I2,   a = e^(−h/τs),

where ``x(s) = x_{k−1} + d1·s + d2·s²`` and ``I_n = ∫_0^h e^(−(h−s)/τs) s^n ds/τs``
(``I0 = 1 − a``, ``I_n = h^n − n·τs·I_{n−1}``).  For a signal that bends between
samples the error is third order in ``h``.  Each trace starts with the sensor settled
(``y_0 = x_0``: the trace starts at rest or steady).  The recurrence is linear, so it
runs as a parallel prefix scan (``jax.lax.associative_scan``) over all the samples of
all traces at once.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["first_order_lag"]


def first_order_lag(x, t, start, tau):
    """The reading of a first-order sensor of time constant ``tau`` (s) following ``x``.

    Parameters
    ----------
    x, t : the true signal and its sample times, traces one after another in time order.
    start : True at the first sample of each trace (the sensor settled there).
    tau : the sensor's time constant (s), > 0.
    """
    h = jnp.where(start, 1.0, jnp.diff(t, prepend=t[:1]))
    # the interval after each sample, and whether it lies in the same trace
    g = jnp.concatenate([h[1:], jnp.ones(1)])
    follows = jnp.concatenate([~start[1:], jnp.zeros(1, bool)])
    x_prev = jnp.concatenate([x[:1], x[:-1]])
    x_next = jnp.concatenate([x[1:], x[-1:]])
    f01 = (x - x_prev) / h
    # at a trace's last interval the parabola through the two samples before instead
    f01_prev = jnp.concatenate([f01[:1], f01[:-1]])
    h_prev = jnp.concatenate([h[:1], h[:-1]])
    backward = ~start & ~jnp.concatenate([jnp.ones(1, bool), start[:-1]])
    f012 = jnp.where(follows, ((x_next - x) / g - f01) / (h + g),
                     jnp.where(backward, (f01 - f01_prev) / (h + h_prev), 0.0))
    d1, d2 = f01 - h * f012, f012
    tau = jnp.maximum(tau, 1e-12)  # shorter than any logged interval: no lag at all
    u = h / tau
    i0 = -jnp.expm1(-u)
    # I1, I2 by the recursion for a short lag (u ≥ 1); for a long one in powers of u,
    # where the recursion would cancel (both branches finite, for the gradients)
    i1_short = h - tau * i0
    i2_short = h * h - 2.0 * tau * i1_short
    us = jnp.minimum(u, 1.0)
    i0s = -jnp.expm1(-us)
    i1_long = tau * (us - i0s)
    i2_long = tau * tau * (us * us - 2.0 * (us - i0s))
    i1 = jnp.where(u >= 1.0, i1_short, i1_long)
    i2 = jnp.where(u >= 1.0, i2_short, i2_long)
    a = jnp.where(start, 0.0, 1.0 - i0)
    c = jnp.where(start, x, x_prev * i0 + d1 * i1 + d2 * i2)

    def combine(first, second):
        a1, c1 = first
        a2, c2 = second
        return a1 * a2, a2 * c1 + c2

    _, y = jax.lax.associative_scan(combine, (a, c))
    return y
