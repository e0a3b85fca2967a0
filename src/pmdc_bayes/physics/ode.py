"""The general solution path: equations (5)–(6) integrated by diffrax.

For irregular sampling, inputs that are not piecewise constant on the sample grid,
and as an independent check of the exact path in :mod:`pmdc_bayes.physics.solution`.  The
solver is stiff-capable (Kvaerno5, an implicit ESDIRK method) because the electrical
time constant La/Ra is about a thousand times shorter than the mechanical one; the
input breakpoints are given to the step-size controller so that no step straddles
a discontinuity.
"""

from __future__ import annotations

import diffrax
import jax.numpy as jnp
import numpy as np

from . import motor
from .solution import Experiment, Params, initial_state

__all__ = ["vector_field", "simulate_ode"]


def _held(times, values, t):
    idx = jnp.clip(jnp.searchsorted(times, t, side="right") - 1, 0, values.shape[0] - 1)
    return values[idx]


def vector_field(t, y, args):
    """dy/dt for ``y = (ia, ω)``: equations (5)–(6) with Coulomb friction.

    ``args = (params, seg_t0, seg_va, seg_tl, coulomb)``.  With Coulomb friction the
    rotor, when at rest, stays at rest while ``|K·ia − TL| ≤ Tc``.
    """
    p, seg_t0, seg_va, seg_tl, coulomb = args
    ia, w = y
    va = _held(seg_t0, seg_va, t)
    tl = _held(seg_t0, seg_tl, t)
    friction = 0.0
    if coulomb:
        net = p.K * ia - tl - p.B * w  # the torque friction must hold while at rest
        friction = jnp.where(w != 0.0, p.Tc * jnp.sign(w), jnp.clip(net, -p.Tc, p.Tc))
    dia, dw = motor.derivatives(p.Ra, p.La, p.K, p.B, p.J, ia, w, va, tl, friction)
    return jnp.stack([dia, dw])


def simulate_ode(p: Params, exp: Experiment, *, coulomb: bool = False, rtol: float = 1e-8,
                 atol: float = 1e-10, max_steps: int = 200_000):
    """``(ia, ω)`` at the experiment's sample times, by adaptive stiff integration.

    ``exp`` must be concrete (its sample times are read with NumPy); ``p`` may be
    traced, so ``jax.jit(lambda p: simulate_ode(p, exp))`` compiles once per
    experiment.
    """
    ts = np.asarray(exp.time)
    jumps = np.asarray(exp.seg_t0)[1:]
    y0 = jnp.stack(initial_state(p, exp, coulomb))
    term = diffrax.ODETerm(vector_field)
    controller = diffrax.ClipStepSizeController(
        diffrax.PIDController(rtol=rtol, atol=atol),
        jump_ts=jnp.asarray(jumps) if jumps.size else None,
    )
    sol = diffrax.diffeqsolve(
        term, diffrax.Kvaerno5(), t0=float(ts[0]), t1=float(ts[-1]), dt0=None, y0=y0,
        args=(p, exp.seg_t0, exp.seg_va, exp.seg_tl, coulomb),
        saveat=diffrax.SaveAt(ts=jnp.asarray(ts)), stepsize_controller=controller,
        max_steps=max_steps,
    )
    return sol.ys[:, 0], sol.ys[:, 1]

