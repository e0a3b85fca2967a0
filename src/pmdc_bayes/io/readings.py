"""The readings of a session besides its traces: a bench measurement, an operating point,
a steady table, a step response read off a plot (SI values); the steady ones as arrays."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Measurement", "OperatingPoint", "SteadyTable", "StepReading", "steady_points"]


@dataclass(frozen=True)
class Measurement:
    """A direct bench measurement (SI value and one-standard-deviation uncertainty).

    ``unit`` is the unit the user wrote, kept for display only.  An La the user did
    not measure is :data:`LA_ASSUMED` in ``source``, ``sd`` then a log-scale width.
    """

    value: float
    sd: float
    unit: str
    source: str = ""


@dataclass(frozen=True)
class OperatingPoint:
    """A steady operating point, e.g. the chopper point of equation (20).

    Attributes: ``supply_voltage`` (V), ``duty`` (1, in (0, 1]), ``current`` (A, or
    None if not measured), ``speed`` (rad/s), ``load_torque`` (N·m).  The mean armature
    voltage is ``duty * supply_voltage``.
    """

    name: str
    supply_voltage: float
    duty: float
    current: float | None
    speed: float
    load_torque: float = 0.0

    @property
    def voltage(self) -> float:
        """Mean armature voltage d·Vs (V)."""
        return self.duty * self.supply_voltage


@dataclass(frozen=True)
class SteadyTable:
    """Steady-state points: voltage (V), speed (rad/s), current (A or None), load (N·m)."""

    name: str
    file: Path
    voltage: np.ndarray
    speed: np.ndarray
    current: np.ndarray | None
    load_torque: np.ndarray


@dataclass(frozen=True)
class StepReading:
    """A step response read off a plot when no trace was logged (the paper's Figure 4).

    ``voltage`` (V) applied from ``initial_speed`` (rad/s), settling at ``final_speed``
    (rad/s), with the 63.2 % time constant ``tau`` (s).
    """

    name: str
    voltage: float
    final_speed: float
    tau: float
    initial_speed: float = 0.0


def steady_points(session) -> dict:
    """Every steady reading of a session as arrays (SI): voltage ``v``, load ``tl``,
    speed ``w``, current ``i`` (0 where not logged) and which speeds and currents are
    observed (``w_mask``, ``i_mask``): operating points, steady-table rows, then step
    readings (their final speed)."""
    v, tl, w, i, wm, im = [], [], [], [], [], []
    for op in session.operating_points:
        v.append(op.voltage), tl.append(op.load_torque), w.append(op.speed)
        i.append(op.current if op.current is not None else 0.0)
        wm.append(True), im.append(op.current is not None)
    for tab in session.steady_tables:
        for k in range(tab.voltage.size):
            v.append(tab.voltage[k]), tl.append(tab.load_torque[k]), w.append(tab.speed[k])
            has_i = tab.current is not None
            i.append(tab.current[k] if has_i else 0.0)
            wm.append(True), im.append(has_i)
    for s in session.step_readings:
        v.append(s.voltage), tl.append(0.0), w.append(s.final_speed), i.append(0.0)
        wm.append(True), im.append(False)
    arr = {k: np.asarray(x, dtype=float) for k, x in dict(v=v, tl=tl, w=w, i=i).items()}
    arr["w_mask"] = np.asarray(wm, dtype=bool)
    arr["i_mask"] = np.asarray(im, dtype=bool)
    return arr
