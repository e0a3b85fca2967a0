"""Quantities derived from the motor parameters, computed draw by draw.

Each quantity is evaluated at every posterior draw, so its summary carries the full
joint uncertainty (correlations included) instead of a linearised propagation.
"""

from __future__ import annotations

import numpy as np

from ...physics import motor

__all__ = ["derived_quantities", "derived_draws", "LABELS"]

# How each derived quantity (keyed as in ``summary.json``) is named to people.
LABELS = {
    "tau_m": "mechanical time constant τm",
    "tau_e": "electrical time constant τe",
    "gain": "steady gain G",
    "no_load_speed": "no-load speed ω0",
    "no_load_current": "no-load current i0",
    "stall_torque": "stall torque",
    "stall_current": "stall current",
    "Kv": "speed constant Kv",
}


def derived_draws(draws_si: dict[str, np.ndarray], *, voltage: float) -> dict:
    """Per draw, ``name -> (unit, values)``; ``Tc`` is optional (0 when absent).

    Notes
    -----
    With ``D = B·Ra + K²``:

    - mechanical time constant ``τm = J·Ra/D`` (s), equation (9);
    - electrical time constant ``τe = La/Ra`` (s);
    - steady gain ``G = K/D`` (rad/s per V), equation (10);
    - no-load speed ``ω0 = (K·V − Ra·Tc)/D`` (rad/s) and current
      ``i0 = (B·V + K·Tc)/D`` (A) at ``V = voltage``, equations (15)–(16) with the
      load ``Tc``;
    - stall torque ``K·V/Ra − Tc`` (N·m) and stall current ``V/Ra`` (A);
    - speed constant ``Kv = 60/(2π·K)`` (rpm/V).
    """
    Ra, La, K, B, J = (np.asarray(draws_si[k], dtype=float) for k in ("Ra", "La", "K", "B", "J"))
    Tc = np.asarray(draws_si.get("Tc", np.zeros_like(Ra)), dtype=float)
    V = float(voltage)
    i0, w0 = motor.steady_state(Ra, K, B, V, 0.0, Tc)
    return {
        "tau_m": ("s", motor.time_constant(Ra, K, B, J)),
        "tau_e": ("s", motor.electrical_time_constant(Ra, La)),
        "gain": ("rad/s/V", motor.gain(Ra, K, B)),
        "no_load_speed": ("rad/s", w0),
        "no_load_current": ("A", i0),
        "stall_torque": ("N*m", K * V / Ra - Tc),
        "stall_current": ("A", V / Ra),
        "Kv": ("rpm/V", 60.0 / (2.0 * np.pi * K)),
    }


def derived_quantities(draws_si: dict[str, np.ndarray], *, voltage: float) -> dict:
    """Mean, sd and 94 % HDI of each derived quantity (see :func:`derived_draws`).

    Parameters
    ----------
    draws_si : SI draws per parameter name (``Ra, La, K, B, J`` and optionally ``Tc``),
        equal-length 1-D arrays, e.g. :meth:`~.posterior.Posterior.draws_si`.
    voltage : armature voltage (V) for the no-load and stall quantities.
    """
    from .arviz_import import az  # ArviZ is imported only when there are draws
    from .diagnostics import HDI_PROB

    out = {}
    for name, (unit, x) in derived_draws(draws_si, voltage=voltage).items():
        lo, hi = az.hdi(x, hdi_prob=HDI_PROB)
        out[name] = {"unit": unit, "mean": float(np.mean(x)), "sd": float(np.std(x, ddof=1)),
                     "hdi_3%": float(lo), "hdi_97%": float(hi)}
    return out
