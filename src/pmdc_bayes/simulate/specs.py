"""The records of a checked simulation plan (:func:`~.plan.check_plan` makes them): the
bench measurements, operating points, steady tables and traces to draw."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io.drag import NO_DRAG, Drag
from .rig import RigSpec

__all__ = ["Plan", "BenchSpec", "PointSpec", "TableSpec", "TraceSpec"]


@dataclass(frozen=True)
class BenchSpec:
    """A bench measurement to draw: ``sd`` in ``unit`` (a resistance or inductance unit)."""

    key: str
    sd: float
    unit: str


@dataclass(frozen=True)
class PointSpec:
    """A steady operating point: Vs (V), duty (1), TL (N·m), noise sds (rad/s, A)."""

    name: str
    supply_voltage: float
    duty: float
    load_torque: float
    speed_sd: float
    current_sd: float


@dataclass(frozen=True)
class TableSpec:
    """A steady table: voltages (V), loads (N·m or None), noise sds (rad/s, A or None)."""

    name: str
    voltages: tuple[float, ...]
    load_torques: tuple[float, ...] | None
    speed_sd: float
    current_sd: float | None


@dataclass(frozen=True)
class TraceSpec:
    """A logged trace: ``duration`` (s) at ``rate`` (Hz), inputs as ``(time s, value)``
    pairs (V, N·m), and the sensor models (noise sds, quanta in rad/s and A, delay s)."""

    name: str
    kind: str
    duration: float
    rate: float
    voltage: tuple[tuple[float, float], ...]
    load_torque: tuple[tuple[float, float], ...] | None
    initial: str | tuple[float, float]
    speed_unit: str
    record_current: bool
    speed_noise: float
    speed_quantum: float
    current_noise: float
    current_quantum: float
    delay: float
    encoder: tuple[int, str] | None = None  # (counts per revolution, output), with a [rig]
    drag: Drag = NO_DRAG  # a known load that depends on the speed (SI)
    speed_noise_correlation: float = 0.0  # lag-1 correlation of the speed's noise, AR(1)

    @property
    def time(self) -> np.ndarray:
        """Sample times ``k / rate`` (s), from 0 to ``duration``."""
        return np.arange(int(math.floor(self.duration * self.rate + 1e-9)) + 1) / self.rate


@dataclass(frozen=True)
class Plan:
    """A checked plan; ``source`` is the plan file (None for a plan built in Python)."""

    source: Path | None
    seed: int | None
    motor: str
    friction: str
    truth: dict[str, float]
    bench: tuple[BenchSpec, ...]
    operating_points: tuple[PointSpec, ...]
    steady_tables: tuple[TableSpec, ...]
    traces: tuple[TraceSpec, ...]
    rig: RigSpec | None = None  # the rig's non-idealities (:mod:`.rig`); None: ideal
