"""The general solution path: equations (5)–(6) integrated by diffrax.

For irregular sampling, inputs that are not piecewise constant on the sample grid,
and as an independent check of the exact path in :mod:`pmdc_bayes.physics.solution`;
:func:`simulate_scan`, the straightforward zero-order-hold formulation
(``expm([[A, b], [0, 0]]·dt)`` stepped sample by sample in ``lax.scan``), is the other
reference, for the viscous model.  The
solver is stiff-capable (Kvaerno5, an implicit ESDIRK method) because the electrical
time constant La/Ra is about a thousand times shorter than the mechanical one; the
input breakpoints are given to the step-size controller so that no step straddles
a discontinuity.
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

from . import motor
from .solution import Experiment, Params, initial_state, system_matrices

__all__ = ["vector_field", "simulate_ode", "simulate_scan"]


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


def simulate_scan(p: Params, exp: Experiment):
    """Viscous model by zero-order-hold ``expm`` steps over samples and input changes.

    The reference formulation: the augmented matrix ``[[A, b], [0, 0]]·dt`` is
    exponentiated for every step of the grid formed by the sample times and the
    input breakpoints, and the state is carried through ``lax.scan``.
    """
    t = exp.time
    grid = np.unique(np.concatenate([t, np.asarray(exp.seg_t0)]))
    seg_of = np.searchsorted(np.asarray(exp.seg_t0), grid[:-1], side="right") - 1
    dts = jnp.asarray(np.diff(grid))
    va = exp.seg_va[seg_of]
    tl = exp.seg_tl[seg_of]
    A, Bu = system_matrices(p)  # x = (ω, ia), u = (TL, Va)
    A, Bu = jnp.asarray(A), jnp.asarray(Bu)
    ia0, w0 = initial_state(p, exp, False)
    x0 = jnp.stack([w0, ia0])

    def step(x, inp):
        dt, v, load = inp
        b = Bu @ jnp.stack([load, v])
        M = jnp.zeros((3, 3)).at[:2, :2].set(A).at[:2, 2].set(b)
        E = jax.scipy.linalg.expm(M * dt)
        x_new = E[:2, :2] @ x + E[:2, 2]
        return x_new, x_new

    _, xs = jax.lax.scan(step, x0, (dts, va, tl))
    xs = jnp.concatenate([x0[None], xs])
    idx = np.searchsorted(grid, t)
    return xs[idx, 1], xs[idx, 0]
