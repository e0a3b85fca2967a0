"""The rotor's angle: what a position sensor or an encoder reads.

The angle is the exact integral of the exact solution.  Within a constant segment the
motor passes through regimes (held at rest, moving, clamped at a current limit), and
within each the two equations (5)–(6) integrate in closed form: a moving phase turns
``∫ω = (K·∫Va − Ra·∫T − Ra·J·Δω − K·La·Δia)/(K² + Ra·B)``
(:func:`~pmdc_bayes.physics.motor.angle_increment`), a clamped one
``(±K·I·τ − ∫T − J·Δω)/B``, a held one nothing.  The solvers
(:mod:`.solution`, :mod:`.limited`) add these up phase by phase: each segment's whole
angle, and each sample's angle since its segment's start.  :func:`assemble_angle` joins
them into the angle since each trace's start, and :func:`since_first_sample` measures
it from the trace's first sample.  No quadrature of ω is involved, so the angle is
exact wherever the state is, and it moves continuously with the parameters, a
breakaway, a stop or a clamp crossing a sample included.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from . import motor
from .experiment import Experiment
from .regimes import CLAMPED, MOVING, Phase, phase_voltage

__all__ = ["assemble_angle", "since_first_sample", "phase_angle", "angle_in_segment"]


def assemble_angle(exp: Experiment, totals, within, w_start):
    """The angle since each trace's start (rad), in the padded layout.

    Parameters
    ----------
    exp : the experiment as the motor sees it.
    totals : the angle each segment turns over its whole length, ``(segments,)``.
    within : each sample's angle since its segment's start, padded ``(C, L)``.
    w_start : the starting speed of each sample's segment
        (:attr:`~.experiment.Experiment.sample_segments`).  A sample before its trace's
        delayed start (``exp.tau_pre < 0``, a dead time) holds the trace's starting
        state, so the rotor turns at that speed until then.
    """
    idx = jnp.arange(totals.shape[0])
    before = jnp.cumsum(totals) - totals
    first = jax.lax.cummax(jnp.where(exp.seg_first, idx, 0))
    start = before - before[first]
    angle = start[exp.sample_segments] + within
    if exp.tau_pre is not None:
        angle = angle + w_start * exp.tau_pre
    return angle


def since_first_sample(exp: Experiment, angle, start):
    """Per sample in time order (traces one after another), the padded ``angle`` less
    its value at the trace's first sample (``start`` flags the first samples)."""
    a = exp.unpad(angle)
    first = jax.lax.cummax(jnp.where(start, jnp.arange(a.shape[0]), 0))
    return a - a[first]


def phase_angle(p, va, tl, tc, limit, ph: Phase, tau, ia, w, drop=None):
    """Angle turned in phase ``ph`` from its start to ``tau`` after it, where the state
    is ``(ia, w)`` (broadcasts): none held at rest; a moving phase's from both
    equations (:func:`~.motor.angle_increment`); a clamped one's from the mechanical
    equation alone, ``B·∫ω = (±K·I − TL − d·Tc)·τ − J·Δω``."""
    load = (tl + ph.d * tc) * tau
    v = phase_voltage(va, drop, ph)
    moving = motor.angle_increment(p.Ra, p.La, p.K, p.B, p.J, v * tau, load, ia - ph.ia,
                                   w - ph.w)
    clamped = (p.K * ph.s * limit * tau - load - p.J * (w - ph.w)) / p.B
    return jnp.where(ph.mode == MOVING, moving,
                     jnp.where((ph.mode == CLAMPED) & (ph.d != 0), clamped, 0.0))


def angle_in_segment(p, phases: Phase, va, tl, tc, limit, tau, ia, w, drop=None):
    """Angle turned from the segment's start to ``tau`` after it, where the state is
    ``(ia, w)``: the whole of each phase that ended before ``tau`` (from the next
    phase's starting state) and the part of the one ``tau`` lies in; exact, and
    continuous as the phases' times move with the parameters."""
    ph = jax.tree_util.tree_map(lambda a: a[0], phases)
    done = jnp.zeros_like(ph.t0)
    before = done
    for k in range(1, phases.t0.shape[0]):
        q = jax.tree_util.tree_map(lambda a, k=k: a[k], phases)
        prev = jax.tree_util.tree_map(lambda a, k=k: a[k - 1], phases)
        ended = jnp.isfinite(q.t0)
        dur = jnp.where(ended, q.t0 - prev.t0, 0.0)
        done = done + jnp.where(
            ended, phase_angle(p, va, tl, tc, limit, prev, dur, q.ia, q.w, drop), 0.0)
        on = tau >= q.t0
        ph = jax.tree_util.tree_map(lambda a, b, on=on: jnp.where(on, b, a), ph, q)
        before = jnp.where(on, done, before)
    return before + phase_angle(p, va, tl, tc, limit, ph, tau - ph.t0, ia, w, drop)
