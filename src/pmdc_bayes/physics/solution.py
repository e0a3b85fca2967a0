"""The motor model, equations (5)–(6), and its exact solution for piecewise-constant inputs.

The state as a pair ``(ia, ω)``, the order of pairs in :mod:`.motor`; inputs the
armature voltage Va(t) and load torque TL(t), both
piecewise constant (a logged column is held between samples).  Between input
changes the viscous model is linear and time-invariant, so its solution is a
matrix exponential; :func:`simulate` evaluates it in closed (modal) form at every
sample at once, after a short sequential pass over the input segments.  Coulomb
friction's stick and slip are located inside each segment (:mod:`.free`), so the
solution stays exact.

A current-limited driver, and Coulomb friction through a voltage reversal, take the
regime-switching solution of :mod:`.limited`.  A lagging sensor's reading is one more
linear state, carried exactly through the same regimes (:mod:`.sensor`).  The
references are in :mod:`.ode`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import free, limited, load, motor, sensor
from .angle import angle_in_segment, assemble_angle
from .experiment import (
    INITIAL_MODES,
    Experiment,
    experiment_from_trace,
    experiment_from_traces,
    make_experiment,
    stack_experiments,
)
from .motor import state_space
from .propagator import real_modes
from .regimes import NO_LIMIT, clamped_steady, drop_at

__all__ = ["Params", "Experiment", "experiment_from_trace", "experiment_from_traces",
           "stack_experiments", "make_experiment", "steady_state", "simulate",
           "simulate_padded", "real_modes", "system_matrices", "initial_state"]


class Params(NamedTuple):
    """Motor parameters, SI.

    Attributes
    ----------
    Ra : armature resistance (Ω).
    La : armature inductance (H).
    K : torque constant = back-emf constant (N·m/A = V·s/rad).
    B : viscous friction (N·m·s/rad).
    J : inertia of rotor and load (kg·m²).
    Tc : Coulomb friction torque (N·m); 0 for the viscous model.
    """

    Ra: jax.Array | float
    La: jax.Array | float
    K: jax.Array | float
    B: jax.Array | float
    J: jax.Array | float
    Tc: jax.Array | float = 0.0


def system_matrices(p: Params):
    """``A`` and the input matrix in the documented order x = (ω, ia), u = (TL, Va):
    equations (11)–(14) (:func:`pmdc_bayes.physics.motor.state_space`)."""
    A, Bu, _, _ = state_space(p.Ra, p.La, p.K, p.B, p.J)
    return A, Bu


def steady_state(p: Params, va, tl=0.0):
    """Steady ``(ia, ω)`` of the viscous model under constant inputs, equations (15)–(18)."""
    return motor.steady_state(p.Ra, p.K, p.B, va, tl)


def _initial_for(p: Params, va, tl, mode, x0, coulomb: bool, drop=None):
    tc = p.Tc if coulomb else None
    ss_i, ss_w = (motor.steady_state(p.Ra, p.K, p.B, va, tl, tc) if drop is None else
                  motor.steady_with_drop(p.Ra, p.K, p.B, va, tl, tc, drop))
    given = mode == INITIAL_MODES["given"]
    steady = mode == INITIAL_MODES["steady"]
    ia = jnp.where(given, x0[0], jnp.where(steady, ss_i, 0.0))
    w = jnp.where(given, x0[1], jnp.where(steady, ss_w, 0.0))
    return ia, w


def initial_state(p: Params, exp: Experiment, coulomb: bool):
    """Initial ``(ia, ω)`` of the experiment's first trace."""
    return _initial_for(p, exp.seg_va[0], exp.seg_tl[0], exp.seg_mode[0], exp.seg_x0[0],
                        coulomb)


def simulate_padded(p: Params, exp: Experiment, *, coulomb: bool = False,
                    fast: bool = False, limit=None, with_angle: bool = False, lags=None,
                    drop=None, overflow: bool = False, open_volts=None):
    """Exact ``(ia, ω)`` in the experiment's padded ``(C, L)`` sample layout, and with
    ``with_angle`` the angle turned since each trace's start (rad), exact too
    (:mod:`.angle`).

    ``fast=True`` assumes real, well-separated eigenvalues (:func:`real_modes`) and
    skips the complex and nearly-repeated branches; callers check that first.
    ``limit`` (A), when given, is the driver's current limit (:mod:`.limited`).
    ``lags``, when given, is a pair of time constants (s) of first-order sensors of the
    current and the speed, None for one read without a lag: that signal is then
    returned as its sensor reads it (:mod:`.sensor`), settled at each trace's start.
    ``drop`` (V), when given, is a voltage drop at the brushes and driver, which opposes
    the current (:mod:`.limited`); ``open_volts`` (V) the drop at a zero command, where
    a driver opens the armature (:func:`~.regimes.drop_at`).
    ``overflow=True`` appends, per segment, whether its regime changes more often than
    the :data:`~.limited.PHASES` the regime-switching solution follows (the prediction
    is then not exact after the last of them; always False without a limit or drop).
    """
    lags = (None, None) if lags is None else tuple(lags)
    mus = tuple(None if tau is None else sensor.pole(tau) for tau in lags)
    drop = 0.0 if open_volts is not None and drop is None else drop
    if drop is not None and limit is None:
        limit = NO_LIMIT
    if limit is not None:
        out = _simulate_limited(p, exp, coulomb, fast, limit, with_angle, mus,
                                lambda va: drop_at(drop, open_volts, va), overflow)
    else:
        out = _simulate_free(p, exp, coulomb, fast, with_angle, mus)
        if overflow:
            out = out + (jnp.zeros(exp.seg_va.shape, bool),)
    extra = out[-1:] if overflow else ()
    if not with_angle:
        return out[:2] + extra
    ia, w, totals, within, w_start = out[:5]
    return (ia, w, assemble_angle(exp, totals, within, w_start)) + extra


def _drags(p: Params, exp: Experiment, tc0):
    """Each segment's added viscous and constant drag, and the parameters a segment
    with drag ``(b, tc)`` sees (``tc0`` the motor's own friction torque on this path)."""
    drag = exp.seg_b is not None or exp.seg_q is not None
    b_x = exp.seg_b if exp.seg_b is not None else jnp.zeros_like(exp.seg_va)
    tc_x = exp.seg_tc if exp.seg_tc is not None else jnp.zeros_like(exp.seg_va)

    def seen(b, tc):
        return p._replace(B=p.B + b, Tc=tc0 + tc) if drag else p._replace(Tc=tc0)

    return b_x, tc_x, seen


def _pass(start, advance, seen, limit, fast: bool, mus, drop_for=None):
    """The step of the pass over the segments: ``start(ps, va, tl, mode, x0)`` the state
    a trace starts from; ``advance(ps, x, va, tl, length)`` a segment's per-sample
    record, its regimes (:class:`~.limited.Phase` records), its end state and its whole
    angle.  Each lagging sensor (pole in ``mus``) is settled at a trace's start and
    carried through every regime; the step also returns the readings at the starts of
    each segment's regimes, and the viscous drag and load the segment saw (its own,
    with a curved drag's tangent at its starting speed); ``drop_for(va)`` the drop."""

    def step(carry, seg_in):
        x, y = carry
        va, tl, length, first, mode, xg, b, tc, curve = seg_in
        along, begin = load.curved_start(start, seen, curve)
        xi = begin(b, tc, va, tl, mode, xg)
        x = (jnp.where(first, xi[0], x[0]), jnp.where(first, xi[1], x[1]))
        b, tl = along(b, tc, tl, x, length)
        ps = seen(b, tc)
        record, phases, x_end, total = advance(ps, x, va, tl, length)
        drop = None if drop_for is None else drop_for(va)
        starts, y_end = [], []
        for row, mu in enumerate(mus):
            if mu is None:
                starts.append(None), y_end.append(None)
                continue
            y0 = jnp.where(first, x[row], y[row])
            st = sensor.phase_starts(ps, va, tl, ps.Tc, limit, phases, y0, mu, row, fast,
                                     drop)
            starts.append(st)
            y_end.append(sensor.reading_in_segment(ps, va, tl, ps.Tc, limit, phases, st, mu,
                                                   length, row, fast, drop))
        return (x_end, tuple(y_end)), (record, total, tuple(starts), (b, tl))

    return step


def _scan(exp: Experiment, step, x0, mus, b_x, tc_x):
    """Run ``step`` (:func:`_pass`) over the segments from ``x0``, the sensors settled;
    also each segment's extra viscous drag and load as the step saw them."""
    y0 = tuple(None if mu is None else x0[row] for row, mu in enumerate(mus))
    _, (record, total, starts, (b_seen, tl_seen)) = jax.lax.scan(
        step, (x0, y0), (exp.seg_va, exp.seg_tl, exp.seg_len, exp.seg_first, exp.seg_mode,
                         exp.seg_x0, b_x, tc_x, exp.curve))
    return record, total, starts, b_seen, tl_seen


def _readings(exp, p_chunk, va, tl, limit, phases, starts, mus, ia, w, fast, drop=None):
    """``(ia, ω)`` at the samples, each through its sensor's lag where it has one."""
    c = exp.sample_segments
    out = [ia, w]
    for row, mu in enumerate(mus):
        if mu is None:
            continue
        st = jnp.moveaxis(starts[row][c], -1, 0)
        out[row] = sensor.reading_in_segment(p_chunk, va, tl, p_chunk.Tc, limit, phases, st,
                                             mu, exp.tau, row, fast, drop)
    return out


def _simulate_free(p: Params, exp: Experiment, coulomb: bool, fast: bool, angle: bool, mus):
    """:func:`simulate_padded` without a current limit: ``(ia, ω)`` (through the
    sensors' lags), and with ``angle`` each segment's angle, each sample's angle since
    its segment's start and its segment's starting speed."""
    b_x, tc_x, seen = _drags(p, exp, p.Tc if coulomb else 0.0)

    def start(ps, va, tl, mode, xg):
        return _initial_for(ps, va, tl, mode, xg, coulomb)

    def advance(ps, x, va, tl, length):
        seg = free.segment_info(ps, x, va, tl, length, coulomb, fast)
        x_end = free.state_in_segment(ps, seg, va, length, coulomb, fast)
        total = free.angle_in_segment(ps, seg, va, tl, length, *x_end)
        return seg, free.phases(seg, coulomb), x_end, total

    x0 = start(seen(b_x[0], tc_x[0]), exp.seg_va[0], exp.seg_tl[0], exp.seg_mode[0],
               exp.seg_x0[0])
    segs, totals, starts, b_seen, tl_seen = _scan(
        exp, _pass(start, advance, seen, 0.0, fast, mus), x0, mus, b_x, tc_x)
    c = exp.sample_segments
    per_chunk = jax.tree_util.tree_map(lambda a: a[c], segs)
    va, tl = exp.seg_va[c], tl_seen[c]
    pc = seen(b_seen[c], tc_x[c])
    ia, w = free.state_in_segment(pc, per_chunk, va, exp.tau, coulomb, fast)
    ia_r, w_r = _readings(exp, pc, va, tl, 0.0, free.phases(per_chunk, coulomb), starts, mus,
                          ia, w, fast)
    if not angle:
        return ia_r, w_r
    within = free.angle_in_segment(pc, per_chunk, va, tl, exp.tau, ia, w)
    return ia_r, w_r, totals, within, per_chunk.w0


def _simulate_limited(p: Params, exp: Experiment, coulomb: bool, fast: bool, limit,
                      angle: bool, mus, drop_for, overflow: bool = False):
    """:func:`_simulate_free` with a current limit or a drop (``drop_for(va)``), each
    segment split into its regimes (:func:`.limited.segment_phases`); with ``overflow``,
    also whether each changes regime more often than they follow."""
    b_x, tc_x, seen = _drags(p, exp, p.Tc if coulomb else 0.0)

    def start(ps, va, tl, mode, xg):
        ia, w = _initial_for(ps, va, tl, mode, xg, coulomb, drop_for(va))
        return clamped_steady(ps, va, tl, ps.Tc, limit, ia, w)

    def advance(ps, x, va, tl, length):
        drop = drop_for(va)
        phases = limited.segment_phases(ps, x, va, tl, ps.Tc, limit, length, coulomb, fast,
                                        drop, overflow)
        record = phases
        if overflow:
            phases = phases[0]
        x_end = limited.state_in_segment(ps, phases, va, tl, ps.Tc, limit, length, fast, drop)
        total = angle_in_segment(ps, phases, va, tl, ps.Tc, limit, length, *x_end, drop=drop)
        return record, phases, x_end, total

    x0 = start(seen(b_x[0], tc_x[0]), exp.seg_va[0], exp.seg_tl[0], exp.seg_mode[0],
               exp.seg_x0[0])
    phases, totals, starts, b_seen, tl_seen = _scan(
        exp, _pass(start, advance, seen, limit, fast, mus, drop_for), x0, mus, b_x, tc_x)
    flags = None
    if overflow:
        phases, flags = phases
    # (segments, PHASES) → (PHASES, chunks, 1 or L): each sample's segment's phases.
    c = exp.sample_segments
    per_chunk = jax.tree_util.tree_map(lambda a: jnp.moveaxis(a[c], -1, 0), phases)
    pc = seen(b_seen[c], tc_x[c])
    va, tl = exp.seg_va[c], tl_seen[c]
    drop = drop_for(va)
    ia, w = limited.state_in_segment(pc, per_chunk, va, tl, pc.Tc, limit, exp.tau, fast, drop)
    ia_r, w_r = _readings(exp, pc, va, tl, limit, per_chunk, starts, mus, ia, w, fast, drop)
    extra = () if flags is None else (flags,)
    if not angle:
        return (ia_r, w_r) + extra
    within = angle_in_segment(pc, per_chunk, va, tl, pc.Tc, limit, exp.tau, ia, w, drop)
    return (ia_r, w_r, totals, within, per_chunk.w[0]) + extra


def simulate(p: Params, exp: Experiment, *, coulomb: bool = False):
    """Exact ``(ia, ω)`` at the experiment's sample times.

    Parameters
    ----------
    p : motor parameters (SI); ``p.Tc`` is used only when ``coulomb`` is True.
    exp : inputs and sample times from :func:`make_experiment`.
    coulomb : include Coulomb friction (static: compiled separately).

    Returns
    -------
    ia, omega : arrays of shape ``(n_samples,)``, A and rad/s, in time order.

    Notes
    -----
    Between input changes, ``x(t0 + τ) = x_ss + expm(A·τ)·(x(t0) − x_ss)`` with
    ``expm(A·τ) = α(τ)·I + β(τ)·A`` from A's two eigenvalues (Cayley–Hamilton), A
    and x_ss from equations (5)–(6) and (15)–(16).
    """
    ia, w = simulate_padded(p, exp, coulomb=coulomb)
    return exp.unpad(ia), exp.unpad(w)
