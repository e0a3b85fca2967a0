"""The in-memory form of a session: one motor's bench work, every number in SI.

A session is read from a directory holding ``session.toml`` by
:func:`pmdc_bayes.io.loader.load_session`, which validates everything once; the records
here are what the numerics see.  See ``docs/session-format.md`` for the file format.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .drag import NO_DRAG, Drag
from .readings import Measurement, OperatingPoint, SteadyTable, StepReading

__all__ = [
    "COAST_DOWN",
    "Measurement",
    "OperatingPoint",
    "SteadyTable",
    "StepReading",
    "Schedule",
    "Drag",
    "NO_DRAG",
    "Trace",
    "Session",
    "FRICTION_MODELS",
    "LOAD_KINDS",
    "DEAD_TIMES",
]

FRICTION_MODELS = ("viscous", "coulomb")


LOAD_KINDS = ("both", "constant", "viscous")  # an unknown drag's fitted parts, per trace
DEAD_TIMES = ("per_trace", "shared")  # one dead time per driven trace, or one for all
NUISANCES = ("dead_time", "voltage_drop", "speed_lag", "current_lag", "unknown_load",
             "speed_gain", "speed_offset", "current_gain", "current_offset",
             "source_resistance", "current_limit", "dead_zone", "open_at_zero",
             "coloured_noise")
COAST_DOWN = "coast-down"  # the trace kind of a run-down with the armature open
LA_TIME_CONSTANT = 1e-3  # s: La/Ra assumed when La was not measured ...
LA_PRIOR_LOG_SD = float(np.log(10.0)) / 2  # ... give or take a factor 10 at 2 sd (log)
LA_ASSUMED = "not measured: La/Ra = 1 ms, a factor 10 either way at 2 sd"


@dataclass(frozen=True)
class Schedule:
    """A piecewise-constant input: ``values[i]`` holds on ``[times[i], times[i+1])``.

    The last value holds to the end of the trace.  A logged input column is a
    schedule with one breakpoint per sample (zero-order hold), or, where the column is
    noisy, one per level it held (:mod:`.held_levels`), ``se`` each level's standard
    error (0 for one read as zero), ``noise`` the readings' noise sd (both or
    neither given), and ``switched`` whether the column sampled a switching driver's
    output (its levels the duty's).
    """

    times: np.ndarray
    values: np.ndarray
    se: np.ndarray | None = None
    noise: float | None = None
    switched: bool = False

    def __post_init__(self):
        if (self.se is None) != (self.noise is None):
            raise ValueError("a schedule read as levels gives both their se and the noise")

    def at(self, t: np.ndarray) -> np.ndarray:
        """Value of the input at times ``t`` (right-continuous)."""
        idx = np.searchsorted(self.times, np.asarray(t), side="right") - 1
        return self.values[np.clip(idx, 0, len(self.values) - 1)]

    def change_times(self) -> np.ndarray:
        """The times at which the value changes (each breakpoint whose value differs
        from the one before it), in order."""
        values = np.asarray(self.values, dtype=float)
        return np.asarray(self.times, dtype=float)[1:][values[1:] != values[:-1]]


@dataclass(frozen=True, repr=False)
class Trace:
    """One logged time series: samples of speed (and current) under known inputs.

    Attributes
    ----------
    time : sample times (s), strictly increasing.
    speed : measured speed (rad/s).
    current : measured armature current (A), or None.
    voltage, load_torque : the inputs as piecewise-constant schedules (V, N·m).
    voltage_logged, load_logged : whether the input came from a column (True) or a
        schedule written in ``session.toml`` (False).
    initial : ``"rest"``, ``"steady"`` (steady state of the inputs at the first
        sample) or a tuple ``(current A, speed rad/s)``.
    position : the rotor's angle (rad) where a position sensor or an encoder read it,
        NaN at samples it did not (an encoder trace's start, before the first edge),
        or None.
    speed_logged : False when ``speed`` was not logged but estimated from
        ``position`` (for the closed form, the seeds and the figures; the likelihood
        then reads the position only).
    encoder_step : the angle of one encoder count (rad) when the position is counted,
        0 otherwise.
    drag : a known load that depends on the speed (:class:`Drag`): a torque
        ``constant·sign(ω) + viscous·ω`` plus a curved part opposing the motion (a fan,
        a brake, a generator into a known resistor), on top of ``load_torque``.
    rows_left_out : the file lines of the CSV's rows left out for a reading the logger
        missed (an empty or ``NaN`` cell in a channel).
    time_unit : the unit its file and ``session.toml`` give its times in (``time`` is
        in s), for messages that name a time the user writes back.
    """

    name: str
    kind: str
    file: Path
    time: np.ndarray
    speed: np.ndarray
    current: np.ndarray | None
    voltage: Schedule
    load_torque: Schedule
    voltage_logged: bool = False
    load_logged: bool = False
    initial: str | tuple[float, float] = "rest"
    position: np.ndarray | None = None
    speed_logged: bool = True
    encoder_step: float = 0.0
    drag: Drag = NO_DRAG
    rows_left_out: tuple[int, ...] = ()
    time_unit: str = "s"

    def __repr__(self) -> str:
        logged = [c for c, y in (("speed", self.speed if self.speed_logged else None),
                                 ("current", self.current), ("position", self.position))
                  if y is not None]
        span = f" over {self.time[-1] - self.time[0]:.6g} s" if self.n else ""
        return (f"Trace({self.name!r}, kind={self.kind!r}, {self.n} samples{span}, "
                f"logged={logged})")

    @property
    def n(self) -> int:
        return int(self.time.shape[0])

    @property
    def dt(self) -> float:
        """Median sampling interval (s)."""
        return float(np.median(np.diff(self.time)))


@dataclass(frozen=True, repr=False)
class Session:
    """One motor's bench work, every number in SI.

    ``closed_form_options`` carries settings for the paper's method (e.g.
    ``{"K_decimals": 3}`` to carry Kb rounded as the paper printed it).
    ``truth`` holds the true parameters of a simulated session (from ``truth.json``).
    ``nuisances`` names the rig's non-idealities to fit with the motor
    (:data:`NUISANCES`: ``"dead_time"`` per trace, ``"voltage_drop"``, a first-order
    lag of the speed or current sensor ``"speed_lag"``, ``"current_lag"``, an unknown
    drag ``"unknown_load"`` on the traces ``loaded_traces`` names, or on every driven
    trace when it is empty (``load_kinds`` pairs a trace with ``"constant"`` or
    ``"viscous"`` when its drag has only that part; ``"both"`` otherwise), a driver's
    current limit ``"current_limit"``, centred on ``current_limit_setting`` (A) when the
    user gave the driver's setting, a driver's dead zone ``"dead_zone"``, its own width
    for each direction of the command, a driver that opens the armature at a zero
    command ``"open_at_zero"``); ``shared_dead_time``: one dead time for every
    driven trace (one driver, one logger) instead of one per trace.
    ``coloured_traces``: the traces whose noise ``"coloured_noise"`` fits (none: all).
    ``gear_ratio``: motor turns per output turn when the session was measured at a
    gearbox's output (every speed, angle and torque here is already the motor shaft's,
    :mod:`.gear`); 1 otherwise.
    ``bench`` holds the further bench measurements given (of ``"K"``, ``"J"``,
    ``"B"``), each a prior of the fit.  ``coast_downs`` are traces of kind
    ``"coast-down"``: the rotor running down with the armature open (speed only, no
    current, no input), kept apart from ``traces`` (which the motor drives).
    """

    name: str
    root: Path
    motor: str
    Ra: Measurement
    La: Measurement
    friction: str = "viscous"
    operating_points: tuple[OperatingPoint, ...] = ()
    steady_tables: tuple[SteadyTable, ...] = ()
    step_readings: tuple[StepReading, ...] = ()
    traces: tuple[Trace, ...] = ()
    closed_form_options: dict = field(default_factory=dict)
    truth: dict | None = None
    nuisances: tuple[str, ...] = ()
    bench: dict = field(default_factory=dict)
    coast_downs: tuple[Trace, ...] = ()
    loaded_traces: tuple[str, ...] = ()
    current_limit_setting: float | None = None
    load_kinds: tuple[tuple[str, str], ...] = ()
    shared_dead_time: bool = False
    gear_ratio: float = 1.0
    coloured_traces: tuple[str, ...] = ()

    def __repr__(self) -> str:
        parts = [f"{self.name!r}", f"motor={self.motor!r}", f"friction={self.friction!r}",
                 f"traces={[f'{t.name} ({t.n} samples)' for t in self.traces]}"]
        parts += [f"{what}={n}" for what, n in (
            ("steady_tables", len(self.steady_tables)),
            ("operating_points", len(self.operating_points)),
            ("step_readings", len(self.step_readings)),
            ("coast_downs", len(self.coast_downs))) if n]
        if self.nuisances:
            parts.append(f"nuisances={list(self.nuisances)}")
        return f"Session({', '.join(parts)}, root={str(self.root)!r})"

    @classmethod
    def from_arrays(cls, *, Ra, traces=None, La=None, K=None, J=None, B=None,
                    motor: str = "motor", friction: str = "viscous", steady=None,
                    operating_points=None, model=None, name=None,
                    directory=None) -> Session:
        """A session from data in memory, checked as a session directory is.

        Parameters
        ----------
        Ra, La, K, J, B : a bench measurement ``(value, sd)`` in SI (Ω, H, V·s/rad,
            kg·m², N·m·s/rad), or a mapping ``{"value", "unit", "sd", "source"}`` as in
            ``session.toml``; Ra is required, the others optional (priors of the fit).
        traces : ``{name: data}``; ``data`` is a dict or a pandas DataFrame of columns
            ``time`` (s) and ``speed`` (rad/s) and/or ``position`` (rad), optionally
            ``current`` (A), ``voltage`` (V), ``load_torque`` (N·m), ``direction``; a
            ``voltage`` or ``load_torque`` that is not a column is a constant or
            ``(time, value)`` pairs; the settings ``kind`` (default ``"step"``),
            ``initial``, ``units``, ``counts_per_rev``, ``edges``, ``drag``,
            ``time_wrap`` are as in ``[[trace]]`` (``docs/session-format.md``).
        steady : ``{name: data}`` with columns ``voltage``, ``speed`` (``current``,
            ``load_torque``): steady tables.
        operating_points : ``{name: {"supply_voltage", "duty", "current", "speed"}}``.
        model : the ``[model]`` table: ``{"dead_time": True, ...}``.
        name : the session's name (default ``"session"``); its files are then written
            to a temporary directory removed when Python exits.
        directory : a new (or empty) directory to keep the session's files in instead;
            the session is named after it.

        Raises :class:`~pmdc_bayes.UsageError` for arguments of the wrong shape and
        :class:`~pmdc_bayes.SessionError` for data a session file would be refused for.
        """
        from .arrays import session_from_arrays

        return session_from_arrays(
            Ra=Ra, traces=traces, La=La, K=K, J=J, B=B, motor=motor, friction=friction,
            steady=steady, operating_points=operating_points, model=model, name=name,
            directory=directory)

    def coloured_noise_traces(self) -> tuple[str, ...]:
        """The traces (driven and coast-downs) whose analogue channels' noise is fitted
        as coloured (``coloured_noise``): those ``coloured_traces`` names, or every one
        when it names none."""
        if "coloured_noise" not in self.nuisances:
            return ()
        names = tuple(t.name for t in self.traces + self.coast_downs)
        return tuple(n for n in names if n in self.coloured_traces) if self.coloured_traces \
            else names

    def load_kind(self, trace_name: str) -> str:
        """Which parts of a loaded trace's unknown drag are fitted: :data:`LOAD_KINDS`."""
        return dict(self.load_kinds).get(trace_name, "both")

    def unknown_load_traces(self) -> tuple[str, ...]:
        """The driven traces that carry an unknown drag of their own (``unknown_load``)."""
        if "unknown_load" not in self.nuisances:
            return ()
        names = tuple(t.name for t in self.traces)
        return tuple(n for n in names if n in self.loaded_traces) if self.loaded_traces \
            else names

    def inert_nuisance(self, names=None) -> tuple[str, str] | None:
        """The first of ``names`` (default: the session's nuisances) with nothing in the
        session to act on, and why (:func:`._inert.inert_nuisance`)."""
        from ._inert import inert_nuisance

        return inert_nuisance(self, self.nuisances if names is None else names)

    def trace(self, name: str) -> Trace:
        for tr in self.traces:
            if tr.name == name:
                return tr
        names = ", ".join(t.name for t in self.traces) or "none"
        raise KeyError(f"no trace named {name!r} (traces: {names})")

    def without_traces(self, names) -> Session:
        """A copy without the named traces (for hold-out validation)."""
        import dataclasses

        keep = tuple(t for t in self.traces if t.name not in set(names))
        return dataclasses.replace(self, traces=keep)

    def files(self) -> tuple[Path, ...]:
        """Every file the session was read from: session.toml, the CSV files and
        truth.json (when present), each once."""
        found = [self.root / "session.toml", *(t.file for t in self.traces),
                 *(t.file for t in self.coast_downs), *(t.file for t in self.steady_tables)]
        if (self.root / "truth.json").is_file():
            found.append(self.root / "truth.json")
        return tuple(dict.fromkeys(Path(f) for f in found))
