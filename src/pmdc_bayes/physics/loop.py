"""A PI speed loop around the motor: its stability margins.

The plant is ω/Va of equation (7) (:func:`~.motor.tf_full`); the
controller ``C(s) = kp + ki/s``; an optional loop delay ``e^{-sτ}`` (a driver's or a
sampler's dead time).  The margins are read off the loop's frequency response on a
fine logarithmic grid, interpolated at each crossing.
"""

from __future__ import annotations

import numpy as np

from .motor import tf_full

__all__ = ["pi_margins", "pi_loop", "FREQUENCIES"]

FREQUENCIES = np.logspace(-4, 8, 4801)  # rad/s: 400 points a decade


def _crossings(x: np.ndarray) -> np.ndarray:
    """Indices ``i`` where ``x`` changes sign between ``i`` and ``i + 1``."""
    return np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]


def _at(i: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``y`` linearly interpolated where ``x`` crosses zero between ``i`` and ``i + 1``."""
    f = x[i] / (x[i] - x[i + 1])
    return y[i] + f * (y[i + 1] - y[i])


def pi_margins(Ra, La, K, B, J, kp: float, ki: float, delay: float = 0.0,
               w: np.ndarray = FREQUENCIES) -> dict:
    """Gain margin (dB), phase margin (deg) and their frequencies (rad/s) of the loop
    ``C·G·e^{-sτ}``.  Where the loop's phase never reaches −180° the gain margin is
    infinite; where its gain never crosses 1, the phase margin is infinite.  With
    several crossings, the smallest margin."""
    s = 1j * w
    num, den = tf_full(Ra, La, K, B, J)
    loop = (kp + ki / s) * np.polyval(num, s) / np.polyval(den, s) * np.exp(-s * delay)
    log_gain = np.log(np.abs(loop))
    phase = np.degrees(np.unwrap(np.angle(loop)))
    logw = np.log(w)
    out = {"gain_margin_db": np.inf, "phase_crossover": np.nan,
           "phase_margin_deg": np.inf, "gain_crossover": np.nan}
    i = _crossings(log_gain)
    if i.size:
        pm = (_at(i, log_gain, phase) + 180.0 + 180.0) % 360.0 - 180.0
        k = int(np.argmin(pm))
        out["phase_margin_deg"] = float(pm[k])
        out["gain_crossover"] = float(np.exp(_at(i, log_gain, logw))[k])
    # where the phase is -180° + 360°·n, for every n it reaches
    turns = (phase + 180.0) / 360.0
    gm, wc = [], []
    for n in np.arange(np.floor(turns.min()), np.ceil(turns.max()) + 1):
        j = _crossings(turns - n)
        gm.extend(-_at(j, turns - n, log_gain) * 20.0 / np.log(10.0))
        wc.extend(np.exp(_at(j, turns - n, logw)))
    if gm:
        k = int(np.argmin(gm))
        out["gain_margin_db"] = float(gm[k])
        out["phase_crossover"] = float(wc[k])
    return out


def _points(x: np.ndarray) -> list:
    """The 3 %, 50 % and 97 % points (nearest rank: infinite margins allowed)."""
    x = np.sort(x)
    return [x[int(round(q * (x.size - 1)))] for q in (0.03, 0.5, 0.97)]


def _finite_or_none(x: float):
    return float(x) if np.isfinite(x) else None


def pi_loop(kp: float, ki: float, delay: float, best: dict, draws=None) -> dict:
    """The margins of the PI loop at ``best`` (SI values by name) and, given ``draws``
    (a sequence of such dicts), their spread over the draws: the 3 %, 50 % and 97 %
    points and the share of draws with a phase margin under 45° or a gain margin under
    6 dB.  Infinite margins are None (JSON has no infinity)."""
    motor = ("Ra", "La", "K", "B", "J")
    at = pi_margins(*(best[n] for n in motor), kp, ki, delay)
    out = {"kp": kp, "ki": ki, "delay": delay,
           "at_estimate": {k: _finite_or_none(v) for k, v in at.items()}}
    if draws:
        rows = [pi_margins(*(d[n] for n in motor), kp, ki, delay) for d in draws]
        pm = np.array([r["phase_margin_deg"] for r in rows])
        gm = np.array([r["gain_margin_db"] for r in rows])
        out["over_draws"] = {
            "n": len(rows),
            "phase_margin_deg": [_finite_or_none(q) for q in _points(pm)],
            "gain_margin_db": [_finite_or_none(q) for q in _points(gm)],
            "share_pm_below_45": float(np.mean(pm < 45.0)),
            "share_gm_below_6db": float(np.mean(gm < 6.0)),
        }
    return out
