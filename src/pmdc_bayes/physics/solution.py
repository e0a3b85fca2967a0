"""The motor model, equations (5)–(6), and its exact solution for piecewise-constant inputs.

State ``x = (ia, ω)``; inputs the armature voltage Va(t) and load torque TL(t), both
piecewise constant (a logged column is held between samples).  Between input
changes the viscous model is linear and time-invariant, so its solution is a
matrix exponential; :func:`simulate` evaluates it in closed (modal) form at every
sample at once, after a short sequential pass over the input segments.  Coulomb
friction is a constant torque ``Tc·sign(ω)`` while the motor turns, with the rotor
held at rest while the driving torque cannot overcome it; the breakaway and stop
times are found inside each segment, so the solution stays exact.

A current-limited driver, and Coulomb friction through a voltage reversal, take the
regime-switching solution of :mod:`.limited`.  The references are in :mod:`.ode`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from . import limited, motor
from .angle import assemble_angle
from .experiment import (
    INITIAL_MODES,
    Experiment,
    experiment_from_trace,
    experiment_from_traces,
    make_experiment,
    stack_experiments,
)
from .motor import state_space
from .propagator import apply_alpha_beta, coefficients, coefficients_real, real_modes

__all__ = [
    "Params",
    "Experiment",
    "experiment_from_trace",
    "experiment_from_traces",
    "stack_experiments",
    "make_experiment",
    "steady_state",
    "simulate",
    "simulate_padded",
    "real_modes",
    "system_matrices",
    "initial_state",
]



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


def _steady_coulomb(p: Params, va, tl, direction):
    """Steady state of the moving phase, friction ``Tc`` opposing ``direction``."""
    return motor.steady_state(p.Ra, p.K, p.B, va, tl + direction * p.Tc)


def _stuck_current(p: Params, ia0, va, tau):
    """Current with the rotor held at rest: first order with time constant La/Ra."""
    return motor.stuck_current(p.Ra, p.La, ia0, va, tau)


class _Segment(NamedTuple):
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


def _moving(p, seg, tau_m, fast=False):
    alpha, beta = (coefficients_real if fast else coefficients)(p, tau_m)
    di, dw = apply_alpha_beta(p, alpha, beta, (seg.xm_i - seg.ss_i, seg.xm_w - seg.ss_w))
    return seg.ss_i + di, seg.ss_w + dw


def _segment_info(p: Params, x, va, tl, length, coulomb: bool, fast: bool) -> _Segment:
    ia0, w0 = x
    inf = jnp.inf
    if not coulomb:
        ss_i, ss_w = steady_state(p, va, tl)
        zero = jnp.zeros_like(ia0)
        return _Segment(ia0, zero, ia0, w0, ss_i, ss_w, zero + inf, zero, w0, zero)
    at_rest = w0 == 0.0
    drive = p.K * va / p.Ra - tl
    direction = jnp.where(at_rest, jnp.where(drive >= 0, 1.0, -1.0),
                          jnp.where(w0 >= 0, 1.0, -1.0))
    # Breakaway from rest: K·ia − TL reaches ±Tc while ia rises towards Va/Ra.
    i_star = (tl + direction * p.Tc) / p.K
    i_inf = va / p.Ra
    already = direction * (p.K * ia0 - tl) > p.Tc
    possible = direction * drive > p.Tc
    breaks = possible & ~already
    ratio = jnp.where(breaks, (i_inf - i_star) / jnp.where(breaks, i_inf - ia0, 1.0), 1.0)
    t_break = -p.La / p.Ra * jnp.log(jnp.clip(ratio, 1e-300, 1.0))
    t_move = jnp.where(at_rest, jnp.where(already, 0.0, jnp.where(possible, t_break, inf)), 0.0)
    xm_i = jnp.where(at_rest & ~already, i_star, ia0)
    ss_i, ss_w = _steady_coulomb(p, va, tl, direction)
    seg = _Segment(ia0, t_move, xm_i, w0, ss_i, ss_w, jnp.zeros_like(ia0) + inf, ia0, w0,
                   direction)
    # Stop: the moving phase crosses ω = 0 before the segment ends.
    span = jnp.clip(length - jnp.where(jnp.isfinite(t_move), t_move, length), 0.0, None)
    _, w_end = _moving(p, seg, span, fast)
    stops = jnp.isfinite(t_move) & (direction * w_end < 0)

    # Bisection brackets the root without derivatives (no tangents flow through the
    # loop); the Newton steps below carry its dependence on the parameters.
    p_c, seg_c, dir_c = jax.lax.stop_gradient((p, seg, direction))

    def bisect(_, lohi):
        lo, hi = lohi
        mid = 0.5 * (lo + hi)
        _, wm = _moving(p_c, seg_c, mid, fast)
        pos = dir_c * wm > 0
        return jnp.where(pos, mid, lo), jnp.where(pos, hi, mid)

    span_c = jax.lax.stop_gradient(span)
    lo, hi = jax.lax.fori_loop(0, 60, bisect, (jnp.zeros_like(span_c), span_c))
    t_root = jax.lax.stop_gradient(jnp.where(stops, 0.5 * (lo + hi), 0.0))
    for _ in range(2):  # Newton steps carry the root's dependence on the parameters
        i_r, w_r = _moving(p, seg, t_root, fast)
        _, dw_dt = motor.derivatives(p.Ra, p.La, p.K, p.B, p.J, i_r, w_r, tl=tl,
                                     tc=direction * p.Tc)
        # Only where the motor stops: elsewhere the step would run off to huge times,
        # whose overflowing exponentials poison reverse-mode derivatives.
        t_root = jnp.where(stops, t_root - w_r / jnp.where(dw_dt == 0, 1.0, dw_dt), 0.0)
    i_stop, _ = _moving(p, seg, t_root, fast)
    return seg._replace(t_stop=jnp.where(stops, t_root, inf),
                        i_stop=jnp.where(stops, i_stop, ia0))


def _state_in_segment(p: Params, seg: _Segment, va, tau, coulomb: bool, fast: bool):
    """State at ``tau`` after the segment start (broadcasts over samples)."""
    if not coulomb:
        return _moving(p, seg, tau, fast)
    t_move = jnp.where(jnp.isfinite(seg.t_move), seg.t_move, 0.0)
    tau_m = jnp.clip(tau - t_move, 0.0, None)
    t_end = jnp.where(jnp.isfinite(seg.t_stop), seg.t_stop, tau_m)
    i_m, w_m = _moving(p, seg, jnp.minimum(tau_m, t_end), fast)
    i_pre = _stuck_current(p, seg.ia0, va, tau)
    t_stop = jnp.where(jnp.isfinite(seg.t_stop), seg.t_stop, 0.0)
    i_post = _stuck_current(p, seg.i_stop, va, jnp.clip(tau_m - t_stop, 0.0, None))
    before = tau < seg.t_move
    after = jnp.isfinite(seg.t_stop) & (tau_m >= seg.t_stop)
    ia = jnp.where(before, i_pre, jnp.where(after, i_post, i_m))
    w = jnp.where(before | after, 0.0, w_m)
    return ia, w


def _angle_in_segment(p: Params, seg: _Segment, va, tl, tau, ia, w):
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


def _initial_for(p: Params, va, tl, mode, x0, coulomb: bool):
    ss_i, ss_w = motor.steady_state(p.Ra, p.K, p.B, va, tl, p.Tc if coulomb else None)
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
                    fast: bool = False, limit=None, with_angle: bool = False):
    """Exact ``(ia, ω)`` in the experiment's padded ``(C, L)`` sample layout, and with
    ``with_angle`` the angle turned since each trace's start (rad), exact too
    (:mod:`.angle`).

    ``fast=True`` assumes real, well-separated eigenvalues (:func:`real_modes`) and
    skips the complex and nearly-repeated branches; callers check that first.
    ``limit`` (A), when given, is the driver's current limit (:mod:`.limited`).
    """
    if limit is not None:
        out = _simulate_limited(p, exp, coulomb, fast, limit, with_angle)
    else:
        out = _simulate_free(p, exp, coulomb, fast, with_angle)
    if not with_angle:
        return out[:2]
    ia, w, totals, within, w_start = out
    return ia, w, assemble_angle(exp, totals, within, w_start)


def _simulate_free(p: Params, exp: Experiment, coulomb: bool, fast: bool, angle: bool):
    """:func:`simulate_padded` without a current limit: ``(ia, ω)``, and with ``angle``
    each segment's angle, each sample's angle since its segment's start and its
    segment's starting speed."""
    drag = exp.seg_b is not None
    b_x = exp.seg_b if drag else jnp.zeros_like(exp.seg_va)
    tc_x = exp.seg_tc if drag else jnp.zeros_like(exp.seg_va)

    def with_drag(b, tc):
        """The parameters a segment sees: the motor's own, plus its trace's drag."""
        return p._replace(B=p.B + b, Tc=p.Tc + tc) if drag else p

    x0 = initial_state(with_drag(b_x[0], tc_x[0]), exp, coulomb)

    def step(x, seg_in):
        va, tl, length, first, mode, xg, b, tc = seg_in
        ps = with_drag(b, tc)
        xi = _initial_for(ps, va, tl, mode, xg, coulomb)
        x = (jnp.where(first, xi[0], x[0]), jnp.where(first, xi[1], x[1]))
        seg = _segment_info(ps, x, va, tl, length, coulomb, fast)
        x_end = _state_in_segment(ps, seg, va, length, coulomb, fast)
        return x_end, (seg, _angle_in_segment(ps, seg, va, tl, length, *x_end))

    _, (segs, totals) = jax.lax.scan(step, x0, (exp.seg_va, exp.seg_tl, exp.seg_len,
                                                exp.seg_first, exp.seg_mode, exp.seg_x0,
                                                b_x, tc_x))
    c = exp.chunk_seg
    per_chunk = jax.tree_util.tree_map(lambda a: a[c][:, None], segs)
    va, tl = exp.seg_va[c][:, None], exp.seg_tl[c][:, None]
    pc = with_drag(b_x[c][:, None], tc_x[c][:, None])
    ia, w = _state_in_segment(pc, per_chunk, va, exp.tau, coulomb, fast)
    if not angle:
        return ia, w
    within = _angle_in_segment(pc, per_chunk, va, tl, exp.tau, ia, w)
    return ia, w, totals, within, per_chunk.w0


def _simulate_limited(p: Params, exp: Experiment, coulomb: bool, fast: bool, limit,
                      angle: bool):
    """:func:`_simulate_free` with a current-limited driver: each segment split into
    its regimes by :func:`.limited.segment_phases`."""
    drag = exp.seg_b is not None
    b_x = exp.seg_b if drag else jnp.zeros_like(exp.seg_va)
    tc_x = exp.seg_tc if drag else jnp.zeros_like(exp.seg_va)
    tc0 = p.Tc if coulomb else 0.0

    def seen(b, tc):
        return p._replace(B=p.B + b, Tc=tc0 + tc)

    def start(ps, va, tl, mode, xg):
        ia, w = _initial_for(ps, va, tl, mode, xg, coulomb)
        return limited.clamped_steady(ps, va, tl, ps.Tc, limit, ia, w)

    ps0 = seen(b_x[0], tc_x[0])
    x0 = start(ps0, exp.seg_va[0], exp.seg_tl[0], exp.seg_mode[0], exp.seg_x0[0])

    def step(x, seg_in):
        va, tl, length, first, mode, xg, b, tc = seg_in
        ps = seen(b, tc)
        xi = start(ps, va, tl, mode, xg)
        x = (jnp.where(first, xi[0], x[0]), jnp.where(first, xi[1], x[1]))
        phases = limited.segment_phases(ps, x, va, tl, ps.Tc, limit, length, coulomb, fast)
        x_end = limited.state_in_segment(ps, phases, va, tl, ps.Tc, limit, length, fast)
        total = limited.angle_in_segment(ps, phases, va, tl, ps.Tc, limit, length, *x_end)
        return x_end, (phases, total)

    _, (phases, totals) = jax.lax.scan(step, x0, (exp.seg_va, exp.seg_tl, exp.seg_len,
                                                  exp.seg_first, exp.seg_mode, exp.seg_x0,
                                                  b_x, tc_x))
    # (segments, PHASES) → (PHASES, chunks, 1): each chunk's segment's phases.
    per_chunk = jax.tree_util.tree_map(lambda a: a[exp.chunk_seg].T[:, :, None], phases)
    c = exp.chunk_seg
    pc = seen(b_x[c][:, None], tc_x[c][:, None])
    va, tl = exp.seg_va[c][:, None], exp.seg_tl[c][:, None]
    ia, w = limited.state_in_segment(pc, per_chunk, va, tl, pc.Tc, limit, exp.tau, fast)
    if not angle:
        return ia, w
    within = limited.angle_in_segment(pc, per_chunk, va, tl, pc.Tc, limit, exp.tau, ia, w)
    return ia, w, totals, within, per_chunk.w[0]


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
