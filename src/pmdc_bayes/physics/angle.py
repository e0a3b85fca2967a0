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

from .experiment import Experiment

__all__ = ["assemble_angle", "since_first_sample"]


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
