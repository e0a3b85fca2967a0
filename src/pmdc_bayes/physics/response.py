"""The linear motor's responses from ω/Va of equation (7) (:func:`~.motor.tf_full`): the
speed's step response and its frequency response, for one parameter set or many at
once (arrays of posterior draws broadcast against the times or frequencies).

Coulomb friction, a constant load opposing the motion, is not part of them, as it is
not part of the transfer function.
"""

from __future__ import annotations

import numpy as np

from .motor import tf_full

__all__ = ["step_response", "frequency_response", "poles"]


def _coefficients(Ra, La, K, B, J):
    (num,), (a, b, c) = tf_full(*(np.asarray(x, dtype=float)[..., None]
                                   for x in (Ra, La, K, B, J)))
    return num, a, b, c


def poles(Ra, La, K, B, J):
    """The two poles of (7), ``(slow, fast)`` (complex), computed without cancellation:
    ``q = −(b + √(b² − 4ac))/2``, ``p_fast = q/a``, ``p_slow = c/q``."""
    _, a, b, c = _coefficients(Ra, La, K, B, J)
    q = -0.5 * (b + np.sqrt((b * b - 4 * a * c).astype(complex)))
    return (c / q)[..., 0], (q / a)[..., 0]


def step_response(Ra, La, K, B, J, t) -> np.ndarray:
    """Speed (rad/s) per volt of a voltage step at ``t = 0`` from rest, at times ``t``
    (s, ≥ 0); parameters scalars or arrays of shape ``(N,)``, result ``(..., len(t))``.

    ``ω(t)/V = G·[1 + (p2·e^{p1 t} − p1·e^{p2 t})/(p1 − p2)]`` with ``G = K/(Ra·B + K²)``
    and the poles ``p1, p2`` of (7); for (near-)equal poles its limit
    ``G·[1 − (1 − p·t)·e^{p t}]``.
    """
    num, a, b, c = _coefficients(Ra, La, K, B, J)
    p1, p2 = (p[..., None] for p in poles(Ra, La, K, B, J))
    t = np.asarray(t, dtype=float)
    gain = num / c
    diff = p1 - p2
    equal = np.abs(diff) <= 1e-9 * np.abs(p1)
    safe = np.where(equal, 1.0, diff)
    distinct = 1 + (p2 * np.exp(p1 * t) - p1 * np.exp(p2 * t)) / safe
    double = 1 - (1 - p1 * t) * np.exp(p1 * t)
    return (gain * np.where(equal, double, distinct)).real


def frequency_response(Ra, La, K, B, J, w) -> np.ndarray:
    """ω/Va at ``s = jw`` (complex, rad/s per V), ``w`` in rad/s; parameters scalars or
    arrays of shape ``(N,)``, result ``(..., len(w))``."""
    num, a, b, c = _coefficients(Ra, La, K, B, J)
    s = 1j * np.asarray(w, dtype=float)
    return num / ((a * s + b) * s + c)
