"""Noise bookkeeping for the objective: model-free noise levels, channel records, and a
channel's likelihood and weight with its noise level integrated out."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ...io.channel import ChannelId
from ...io.lattice import quantum
from ...io.robust import difference_sd, noise_floor

__all__ = ["Channel", "noise_scale", "typical_level", "quantum", "effective_fraction",
           "quanta_passed", "run_fraction", "integrated_log_likelihood", "noise_weights",
           "NU0"]

NU0 = 2.0  # pseudo-observations of each channel's inverse-gamma noise prior

DEAD_BAND = 2.0  # quanta: noise below q/2 scatters readings over three levels at most


def noise_scale(y: np.ndarray) -> float:
    """Model-free noise level of a sampled signal (robust, from second differences).

    For white noise σ, second differences have standard deviation σ·√6; the median
    absolute deviation ignores the few samples where the signal itself bends.  A
    quantised signal whose differences are mostly zero gets the quantisation noise
    q/√12 of its smallest step as a floor.
    """
    y = np.asarray(y, dtype=float)
    return float(max(noise_floor(y, 2), 1e-9 * max(1e-12, np.abs(y).max())))


def _undithered(y: np.ndarray) -> float:
    """The quantum of a quantised signal whose analogue noise is below half of it (so
    does not dither it: Widrow's quantisation theorem needs noise of about ``q/2`` for
    independent, uniform errors), else 0."""
    q = quantum(y)
    if q == 0.0 or y.size < 3:
        return 0.0
    analogue = difference_sd(y, 2)
    return q if analogue < 0.5 * q else 0.0


def effective_fraction(y: np.ndarray) -> float:
    """The share of a channel's readings that carry independent errors, for its
    likelihood.

    An undithered quantised signal's error is where the signal sits within a quantum:
    the same error until the signal has moved on by a quantum, whatever the noise makes
    the reading flicker between neighbouring levels meanwhile.  Such a channel carries
    about one independent error per quantum the signal passes through
    (:func:`quanta_passed`) and one more for where it started: the fraction is that count
    over the readings.  Any other channel: 1.
    """
    y = np.asarray(y, dtype=float)
    q = _undithered(y)
    return 1.0 if q == 0.0 else float(min(1.0, (1 + quanta_passed(y, q)) / y.size))


def run_fraction(y: np.ndarray) -> float:
    """The share of a settled level's readings whose noise is independent: one per run
    of equal readings when the quantiser is undithered (what the noise adds to the
    level's mean beside the quantiser's bias, which does not average away and is
    reckoned apart), else 1."""
    y = np.asarray(y, dtype=float)
    if _undithered(y) == 0.0:
        return 1.0
    return float(min(1.0, (1 + int(np.count_nonzero(np.diff(y)))) / y.size))


def quanta_passed(y: np.ndarray, q: float) -> int:
    """How many quanta a quantised signal ``y`` (step ``q``) passes through, counted
    with a dead band of two quanta: readings that noise scatters over three neighbouring
    levels count nothing until they leave all three."""
    levels = np.rint(np.asarray(y, dtype=float) / q)
    runs = levels[np.concatenate([[True], np.diff(levels) != 0])]
    lo = hi = runs[0]
    passed = 0.0
    for v in runs[1:]:
        if v > hi:
            passed += max(0.0, v - lo - DEAD_BAND)
            lo, hi = max(lo, v - DEAD_BAND), v
        elif v < lo:
            passed += max(0.0, hi - v - DEAD_BAND)
            lo, hi = v, min(hi, v + DEAD_BAND)
    return int(passed)


@dataclass(frozen=True)
class Channel:
    """A group of observations sharing one unknown noise level."""

    id: ChannelId
    unit: str
    n: int
    s0: float
    alpha: float = 1.0  # share of the n readings with independent errors (effective_fraction)

    @property
    def name(self) -> str:
        """The channel's name for people, ``"<trace>: <signal>"``."""
        return str(self.id)


def typical_level(x, mask) -> float:
    """Mean absolute value of the masked entries (1 when there are none)."""
    vals = np.abs(np.asarray(x)[np.asarray(mask)])
    return float(np.mean(vals)) if vals.size else 1.0


def integrated_log_likelihood(ss, n, s0):
    """Per channel ``−(n_c + ν0)/2 · log(ν0·s0_c² + SS_c)``: the Gaussian likelihood of a
    channel's ``n_c`` residuals with sum of squares ``SS_c``, its noise level integrated
    out (0 for a channel without observations).  Works on JAX or NumPy arrays."""
    xp = jnp if isinstance(ss, jax.Array) else np
    return xp.where(n > 0, -0.5 * (n + NU0) * xp.log(NU0 * s0**2 + ss), 0.0)


def noise_weights(ss, n, s0):
    """Per channel ``w_c = (n_c + ν0)/(ν0·s0_c² + SS_c)``: ``1/σ_c²`` at the posterior
    mode of the noise level, and the channel's weight in the log-likelihood's gradient
    (0 for a channel without observations)."""
    xp = jnp if isinstance(ss, jax.Array) else np
    return xp.where(n > 0, (n + NU0) / (NU0 * s0**2 + ss), 0.0)
