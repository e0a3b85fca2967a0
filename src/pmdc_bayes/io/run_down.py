"""A coast-down's start: the rows of an oscilloscope's pre-trigger or a logger started
early, where the rotor still ran driven before the armature was opened.

A rotor coasting against viscous and Coulomb friction slows fastest at its start
(``J·dω/dt = −B·ω − Tc``, its deceleration falling with its speed), so its speed never
falls by more over a stretch of time than over the same stretch before it.  A record
whose time starts before 0 (an oscilloscope's, from its trigger), whose speed holds up to
the trigger and then falls faster, starts before the armature was opened; fitted as a
coast-down from its first row, its level start would be read as friction.  A lagging
speed sensor's reading also holds at first, from the record's start, so a record whose
speed begins to fall before 0, or one whose time starts at 0, is not refused here: the
search fits the lag, and where the fit misses such a hold the finding on its speed names
the opening (:func:`hold_then_fall`, read by the adequacy checks).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .robust import departure, noise_floor, smallest_step
from .toml_tables import Table

__all__ = ["check_run_down_start", "hold_then_fall", "Hold", "HOLD_Z"]

CLEAR = 10.0  # a departure this many noise sds from the first level (and 5 % of the fall)
HOLD_Z = 6.0  # sds of its noise by which the later fall must exceed the earlier one


def _mean(x: np.ndarray, at: int, half: int) -> float:
    return float(np.nanmean(x[max(0, at - half):at + half + 1]))


class Hold(NamedTuple):
    """A speed that holds at its first level and then falls faster: the time (s) it
    began to fall (``began``), the sample before (``opened``), and the fall's ratio over
    two equal stretches, ``t1`` to ``t2`` after against the same before."""

    began: float
    opened: float
    ratio: float
    t1: float
    t2: float


def hold_then_fall(time: np.ndarray, speed: np.ndarray) -> Hold | None:
    """The hold a coasting rotor cannot show (module docstring), or None: ``k`` samples
    to leave its first level by :data:`CLEAR` sds and 5 % of its fall, and its fall over
    the ``s`` samples after ``k`` more than that over the ``s`` before (``s`` ≤ ``k``, as
    the record allows; means over windows of ``s/4`` samples) by :data:`HOLD_Z` sds of the
    difference and a quantum of a quantised speed."""
    w = np.asarray(speed, float)
    ok = np.isfinite(w)
    time, w = np.asarray(time, float)[ok], np.abs(w[ok])
    quantum, sigma = smallest_step(w), noise_floor(w)
    if w.size < 20 or sigma == 0.0:
        return None
    k = departure(w, sigma, CLEAR, falling=True)
    began = departure(w, sigma, 3.0, share=0.0, falling=True)  # where it began to fall
    if k is None or began is None:
        return None
    s = min(began, int((w.size - 1 - began) / 1.25))  # the windows' spacing
    half = s // 8
    if s < 8:
        return None
    m = 2 * half + 1
    at = (began - s + half, began + half, began + s + half)  # equally spaced centres
    lv = [_mean(w, i, half) for i in at]
    excess = (lv[1] - lv[2]) - (lv[0] - lv[1])
    if excess <= HOLD_Z * sigma * np.sqrt(6.0 / m) + quantum:  # a lattice's means: ±q/2
        return None
    ratio = (lv[1] - lv[2]) / max(lv[0] - lv[1], sigma)
    return Hold(float(time[began]), float(time[max(0, began - 1)]), float(ratio),
                float(time[at[1]]), float(time[at[2]]))


def check_run_down_start(t: Table, time: np.ndarray, speed: np.ndarray, unit: str,
                         per_unit: float) -> None:
    """Refuse a coast-down whose record starts before 0 and whose speed holds at its
    first level up to 0 and then falls faster (:func:`hold_then_fall`).  ``time`` in s,
    ``unit`` the trace's unit of time, ``per_unit`` seconds per unit."""
    if not time[0] < 0.0:
        return
    h = hold_then_fall(time, speed)
    if h is None or h.began < -2.0 * float(np.median(np.diff(time))):
        return  # it began to fall before the trigger: no hold up to it
    opened = h.opened / per_unit
    t.fail("file", f"the speed falls {h.ratio:.3g}× as much from {h.t1 / per_unit:.4g} "
           f"to {h.t2 / per_unit:.4g} {unit} as in the same time before, as a "
           "coasting rotor cannot (it slows fastest at its start): the record holds rows "
           "from before the armature was opened (an oscilloscope's pre-trigger?); give "
           f"opened = {opened:.4g} (where it began to fall, in {unit}; 0 if the scope "
           "triggered on the opening), or remove the rows before it")
