"""The exact solution with a current-limited driver.

A driver with a current limit ``I`` lowers the voltage it applies whenever the
commanded voltage would push ``|ia|`` past ``I``: the current is then held at ``±I``
(``dia/dt = 0``, the terminals at ``Ra·ia + K·ω``) and the speed follows the first-order
``J·dω/dt = ±K·I − TL − Tc·sign(ω) − B·ω`` until the back-emf has risen so far that the
commanded voltage no longer drives the current past the limit.  Within a constant
segment the motor is therefore in one of three regimes (held at rest, moving, clamped),
each solved in closed form (:mod:`.regimes`).

A voltage drop at the brushes and driver opposes the current: ``Va − Vdrop·sign(ia)``
drives a conducting armature, and while ``|Va − K·ω| ≤ Vdrop`` no current flows at all.
Each phase carries the sign ``c`` of its current, so that the three regimes above take
``Va − c·Vdrop`` as their voltage; the current's zero crossing is one more located
event, after which the current flows the other way or stops (an open phase: ``CLAMPED``
at zero current, ``s = 0``), until the back-emf lets it flow again.

The segment is split into at most :data:`PHASES` phases at the located times where the
regime changes: breakaway and clamping of a stuck rotor, in closed form; the stop or
clamping of a moving one, bracketed on a geometric grid (the first crossing, not just
any) and located by Newton steps kept inside the bracket (bisection where a step would
leave it), then Newton steps that carry the time's dependence on the parameters; a
clamped phase's exit or stop, in closed form.  A change beyond the last phase is not
followed; ``segment_phases(overflow=True)`` says where that happens, and the adequacy
checks fail such a segment.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import motor
from .regimes import (
    CLAMPED,
    MOVING,
    STUCK,
    Phase,
    clamped_rate,
    held_direction,
    moving,
    phase_voltage,
    select,
    sign,
    state_at,
)

__all__ = ["PHASES", "segment_phases", "state_in_segment"]

PHASES = 6  # regimes followed per constant segment (e.g. stuck, moving, clamped, moving)
_GRID = 48  # geometric grid that brackets a moving phase's first event
_GRID_SPAN = 1e-9  # its first point, as a share of the remaining segment
_ROOT_STEPS = 12  # safeguarded Newton steps that locate it in its bracket
_TOL = 1e-12  # relative margin that keeps a phase from re-entering the one it left


def _safe_log1p_neg(q, ok):
    """``log1p(−q)`` where ``ok`` (0 ≤ q < 1), 0 elsewhere, without NaN tangents."""
    return jnp.where(ok, jnp.log1p(-jnp.where(ok, q, 0.0)), 0.0)


def _conducting(p, va, w, drop):
    """The sign of the current that starts to flow from zero at speed ``w``: that of
    ``va − K·w`` where it exceeds the drop, else 0 (none flows)."""
    drive = va - p.K * w
    return jnp.where(jnp.abs(drive) > drop, sign(drive), 0.0)


def _classify(p, va, tl, tc, limit, ia, w, coulomb, drop):
    """The regime of state ``(ia, w)`` at a segment's start under the segment's inputs."""
    s = sign(ia)
    c = s if drop is None else jnp.where(ia != 0, s, _conducting(p, va, w, drop))
    v = va if drop is None else va - c * drop
    pushes = s * (v - p.Ra * ia - p.K * w) > 0
    clamped = (jnp.abs(ia) >= limit * (1.0 - _TOL)) & pushes
    held = clamped | (c == 0)  # at the limit, or no current
    s_held = jnp.where(clamped, s, 0.0)
    d_move = jnp.where(w == 0, sign(p.K * ia - tl), sign(w))
    d_clamp = jnp.where(w == 0, held_direction(p, tl, tc, s_held, limit), sign(w))
    stuck = coulomb & (w == 0)
    mode = jnp.where(held, CLAMPED, jnp.where(stuck, STUCK, MOVING))
    d = jnp.where(held, d_clamp, d_move)
    return Phase(jnp.zeros_like(ia), mode, d, s_held, jnp.where(held, s_held * limit, ia), w,
                 jnp.where(clamped, s, c))


def _after_zero(p, va, tl, tc, limit, ph, w, drop):
    """The phase after the current of ``ph`` falls to zero at speed ``w``: it flows the
    other way where the back-emf lets it (MOVING, or STUCK at rest with friction), else
    none flows (CLAMPED at zero current)."""
    c = jnp.where(-ph.c * (va - p.K * w) > drop, -ph.c, 0.0)
    rest = w == 0
    d_open = jnp.where(rest, held_direction(p, tl, tc, 0.0, limit), sign(w))
    mode = jnp.where(c == 0, CLAMPED, jnp.where(rest & (ph.mode == STUCK), STUCK, MOVING))
    d = jnp.where(c == 0, d_open, jnp.where(rest, 0.0, sign(w)))
    zero = jnp.zeros_like(ph.ia)
    return Phase(zero, mode, d, zero, zero, w + zero, c)


def _after_stuck(p, va, tl, tc, limit, ph, drop):
    """Duration of a stuck phase and the phase after it (breakaway, clamp at rest, or
    the current's zero crossing)."""
    i_inf = phase_voltage(va, drop, ph) / p.Ra
    now = p.K * ph.ia - tl  # a torque past the friction already moves the rotor its way
    already = jnp.abs(now) > tc
    db = jnp.where(already, sign(now), sign(p.K * i_inf - tl))
    i_star = (tl + db * tc) / p.K
    possible = db * (p.K * i_inf - tl) > tc
    rate = p.La / p.Ra

    def time_to(level, ok):
        q = (level - ph.ia) / jnp.where(ok, i_inf - ph.ia, 1.0)
        good = ok & (q >= 0) & (q < 1)
        return jnp.where(good, -rate * _safe_log1p_neg(q, good), jnp.inf)

    t_b = jnp.where(already, 0.0, time_to(i_star, possible & ~already))
    sc = sign(i_inf)
    t_c = time_to(sc * limit, jnp.abs(i_inf) > limit)
    breaks = t_b <= t_c
    nxt = Phase(jnp.zeros_like(ph.ia), jnp.where(breaks, MOVING, CLAMPED),
                jnp.where(breaks, db, 0.0), jnp.where(breaks, 0.0, sc),
                jnp.where(breaks, jnp.where(already, ph.ia, i_star), sc * limit),
                jnp.zeros_like(ph.w), jnp.where(breaks, ph.c, sc))
    t_next = jnp.minimum(t_b, t_c)
    if drop is None:
        return t_next, nxt
    t_z = time_to(0.0, (ph.c * i_inf < 0) & (ph.c * ph.ia > 0))
    zero = t_z < t_next
    after = _after_zero(p, va, tl, tc, limit, ph, jnp.zeros_like(ph.w), drop)
    nxt = jax.tree_util.tree_map(lambda a, b: jnp.where(zero, a, b), after, nxt)
    return jnp.minimum(t_z, t_next), nxt


def _after_clamped(p, va, tl, tc, limit, ph, coulomb, drop):
    """Duration of a clamped phase and the phase after it (released or stopped); with no
    current (``s = 0``), released when the back-emf lets a current flow."""
    a = clamped_rate(p, tl, tc, limit, ph)
    w_inf = ph.w + a / p.B
    span = w_inf - ph.w
    v = phase_voltage(va, drop, ph)
    w_exit = (v - ph.s * p.Ra * limit) / p.K
    inside = ph.s * (v - ph.s * p.Ra * limit - p.K * ph.w) > 0

    def time_to(target, ok):
        q = (target - ph.w) / jnp.where(span == 0, 1.0, span)
        good = ok & (span != 0) & (q >= 0) & (q < 1)
        return jnp.where(good, -p.J / p.B * _safe_log1p_neg(q, good), jnp.inf)

    t_exit = jnp.where(inside, time_to(w_exit, True), 0.0)
    c_exit = ph.s
    if drop is not None:  # no current: until |va − K·ω| reaches the drop, either way
        drive = va - p.K * ph.w  # (past the drop already: at once)
        t_up = jnp.where(drive > drop, 0.0, time_to((va - drop) / p.K, True))
        t_down = jnp.where(drive < -drop, 0.0, time_to((va + drop) / p.K, True))
        open_ = ph.s == 0
        past = (drive > drop) | (drive < -drop)
        w_open = jnp.where(past, ph.w, jnp.where(t_up <= t_down, va - drop, va + drop) / p.K)
        w_exit = jnp.where(open_, w_open, w_exit)
        c_exit = jnp.where(open_, jnp.where(t_up <= t_down, 1.0, -1.0), ph.s)
        inside = inside | open_
        t_exit = jnp.where(open_, jnp.minimum(t_up, t_down), t_exit)
    t_stop = time_to(0.0, coulomb & (ph.d != 0) & (ph.w != 0)) if coulomb else jnp.inf
    exits = t_exit <= t_stop
    w_x = jnp.where(inside, w_exit, ph.w)
    at_rest = exits & (ph.d == 0)
    d_rest = held_direction(p, tl, tc, ph.s, limit)
    mode = jnp.where(exits, jnp.where(at_rest & coulomb, STUCK, MOVING), CLAMPED)
    nxt = Phase(jnp.zeros_like(ph.ia), mode, jnp.where(exits, ph.d, d_rest),
                jnp.where(exits, 0.0, ph.s), ph.s * limit,
                jnp.where(exits, jnp.where(at_rest, 0.0, w_x), 0.0),
                jnp.where(exits, c_exit, ph.c))
    return jnp.minimum(t_exit, t_stop), nxt


def _aftermoving(p, va, tl, tc, limit, ph, rem, coulomb, fast, drop):
    """Duration of a moving phase and the phase after it (stopped, clamped, or the
    current through zero): the first grid point past an event brackets it, safeguarded
    Newton steps locate it, and two more Newton steps carry its dependence on the
    parameters."""
    v = phase_voltage(va, drop, ph)
    frac = jnp.logspace(jnp.log10(_GRID_SPAN), 0.0, _GRID)
    grid = rem * frac
    pc = jax.lax.stop_gradient((p, ph))
    rectifies = drop is not None

    def margins(q, ia, w):
        """Each event's margin past its threshold (> 0: happened): stop, clamp, zero."""
        pq, phq = q
        scale = _TOL * (jnp.abs(phq.w) + 1e-300)
        # a current that starts from zero (dia/dt = 0 there) must not cross it on rounding
        current = _TOL * (jnp.abs(phq.ia) + jnp.abs(v) / pq.Ra + 1e-300)
        return [-phq.d * w - scale if coulomb else -jnp.ones_like(w),
                jnp.abs(ia) - limit * (1.0 + _TOL),
                -phq.c * ia - current if rectifies else -jnp.ones_like(ia)]

    def events(q, tau):
        ia, w = moving(q[0], v, tl, tc, q[1], tau, fast)
        return jnp.stack([m > 0 for m in margins(q, ia, w)])

    hit = events(pc, grid)  # (3, G)
    any_hit = hit.any(axis=1)
    first = jnp.argmax(hit, axis=1)
    hi = jnp.where(any_hit, grid[first], rem)
    lo = jnp.where(first > 0, grid[jnp.maximum(first - 1, 0)], 0.0)

    def excess(q, tau):
        """Each event's margin at its own time in ``tau`` (3,), and its rate of change."""
        pq, phq = q
        ia, w = moving(pq, v, tl, tc, phq, tau, fast)
        di, dw = motor.derivatives(pq.Ra, pq.La, pq.K, pq.B, pq.J, ia, w, va=v, tl=tl,
                                   tc=phq.d * tc)
        m = margins(q, ia, w)
        h = jnp.stack([m[0][0], m[1][1], m[2][2]])
        return h, jnp.stack([-phq.d * dw[0], sign(ia[1]) * di[1], -phq.c * di[2]])

    def safeguarded_newton(_, c):  # a Newton step inside the bracket, else bisection
        lo, hi, t = c
        h, dh = excess(pc, t)
        lo, hi = jnp.where(h > 0, lo, t), jnp.where(h > 0, t, hi)
        newton = t - h / jnp.where(dh == 0, 1.0, dh)
        inside = (dh != 0) & (newton > lo) & (newton < hi)
        return lo, hi, jnp.where(inside, newton, 0.5 * (lo + hi))

    _, _, t = jax.lax.fori_loop(0, _ROOT_STEPS, safeguarded_newton, (lo, hi, 0.5 * (lo + hi)))
    t_root = jax.lax.stop_gradient(jnp.where(any_hit, t, 0.0))
    s = sign(moving(pc[0], v, tl, tc, pc[1], t_root[1], fast)[0])
    # Newton steps from the located times carry their dependence on the parameters
    # (value, rate) of each event's function: the speed, the current less the limit, the
    # current
    targets = (lambda i, w, di, dw: (w, dw), lambda i, w, di, dw: (i - s * limit, di),
               lambda i, w, di, dw: (i, di))
    times = []
    for k, target in enumerate(targets):
        t_k = t_root[k]
        for _ in range(2):
            i1, w1 = moving(p, v, tl, tc, ph, t_k, fast)
            di, dw = motor.derivatives(p.Ra, p.La, p.K, p.B, p.J, i1, w1, va=v, tl=tl,
                                       tc=ph.d * tc)
            f, rate = target(i1, w1, di, dw)
            t_k = jnp.where(any_hit[k], t_k - f / jnp.where(rate == 0, 1.0, rate), 0.0)
        times.append(jnp.where(any_hit[k], t_k, jnp.inf))
    t_stop, t_clamp, t_zero = times
    t_ev = jnp.minimum(jnp.minimum(t_stop, t_clamp), t_zero)
    i_e, w_e = moving(p, v, tl, tc, ph, jnp.where(jnp.isfinite(t_ev), t_ev, rem), fast)
    clamps = t_clamp < t_stop
    nxt = Phase(jnp.zeros_like(ph.ia), jnp.where(clamps, CLAMPED, STUCK),
                jnp.where(clamps, ph.d, 0.0), jnp.where(clamps, s, 0.0),
                jnp.where(clamps, s * limit, i_e), jnp.where(clamps, w_e, 0.0),
                jnp.where(clamps, s, ph.c))
    if rectifies:
        zero = t_zero < jnp.minimum(t_stop, t_clamp)
        after = _after_zero(p, va, tl, tc, limit, ph, w_e, drop)
        nxt = jax.tree_util.tree_map(lambda a, b: jnp.where(zero, a, b), after, nxt)
    return t_ev, nxt


def segment_phases(p, x, va, tl, tc, limit, length, coulomb: bool, fast: bool,
                   drop=None, overflow: bool = False):
    """The phases of one segment from the state ``x = (ia, ω)`` at its start, stacked
    (leading axis :data:`PHASES`); ``drop`` (V), when given, opposes the current.  With
    ``overflow``, also whether the last of them ends inside the segment (a change the
    solution does not follow)."""
    first = _classify(p, va, tl, tc, limit, x[0], x[1], coulomb, drop)

    def next_phase(ph, _):
        rem = jnp.clip(length - ph.t0, 0.0, None)
        rem = jnp.where(jnp.isfinite(rem), rem, 0.0)
        dur_s, nx_s = _after_stuck(p, va, tl, tc, limit, ph, drop)
        dur_c, nx_c = _after_clamped(p, va, tl, tc, limit, ph, coulomb, drop)
        dur_m, nx_m = _aftermoving(p, va, tl, tc, limit, ph, rem, coulomb, fast, drop)
        pick = [ph.mode == STUCK, ph.mode == CLAMPED]
        dur = jnp.where(pick[0], dur_s, jnp.where(pick[1], dur_c, dur_m))
        nxt = jax.tree_util.tree_map(
            lambda a, b, c: jnp.where(pick[0], a, jnp.where(pick[1], b, c)), nx_s, nx_c, nx_m)
        t0 = jnp.where(dur < rem, ph.t0 + dur, jnp.inf)
        # A phase past the segment's end keeps a finite state (its predecessor's), so
        # that no tangent meets an infinity.
        nxt = nxt._replace(t0=t0, ia=jnp.where(jnp.isfinite(t0), nxt.ia, ph.ia),
                           w=jnp.where(jnp.isfinite(t0), nxt.w, ph.w))
        return nxt, nxt

    last, rest = jax.lax.scan(next_phase, first, None, length=PHASES - 1)
    phases = jax.tree_util.tree_map(lambda a, b: jnp.concatenate([a[None], b]), first, rest)
    if not overflow:
        return phases
    return phases, jnp.isfinite(next_phase(last, None)[0].t0)


def state_in_segment(p, phases: Phase, va, tl, tc, limit, tau, fast=False, drop=None):
    """``(ia, ω)`` at ``tau`` after the segment's start (broadcasts over samples), from
    the segment's phases (leading axis :data:`PHASES`, then the sample axes' shape)."""
    ph = select(phases, tau)
    return state_at(p, va, tl, tc, limit, ph, tau - ph.t0, fast, drop)


