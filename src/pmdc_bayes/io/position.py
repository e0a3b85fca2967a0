"""Position and encoder traces: a logged angle (rad, deg, rev or encoder counts), one
row per encoder edge, and time counters that wrap (part of the session loader).

A trace may log the rotor's angle instead of (or with) its speed.  With
``edges = true`` each row of its file is one encoder edge: the angle is one count
further (or back, by the ``direction`` column) at that row's time, exactly; the samples
are then as irregular as the edges.  A speed estimated from the angle is kept for the
closed form, the seeds and the figures; the likelihood reads the angle.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .._errors import SessionError
from ._steady_clock import stamp_resolution
from .toml_tables import Table
from .toml_tables import describe as _describe
from .units import to_si

__all__ = ["check_motion_columns", "direction_signs", "unwrap_time", "unwrap_position",
           "angle_si", "edge_angles", "speed_estimate", "speed_window", "counts_step",
           "differenced_angle", "stamp_tick", "SPEED_WINDOW", "WHOLE_COUNT", "edges_flag"]

SPEED_WINDOW = 0.005  # half-width of the speed estimate's difference, as a share of the samples
WHOLE_COUNT = 0.05  # a differenced speed's counts per interval lie this close to whole numbers


def counts_step(t: Table, needed_for: str) -> float:
    """The angle of one count (rad) from the trace's ``counts_per_rev``."""
    if "counts_per_rev" not in t.data:
        t.fail("counts_per_rev", f"{needed_for} needs the encoder's counts per revolution; "
               "add counts_per_rev = <edges counted per turn> to the trace")
    cpr = t.number("counts_per_rev", positive=True)
    return 2.0 * math.pi / cpr


def unwrap_time(t: Table, path: Path, t_raw: np.ndarray) -> np.ndarray:
    """A time counter that wraps at ``time_wrap`` (in the trace's time unit) made
    continuous: the modulus is added at every backward step."""
    if "time_wrap" not in t.data:
        return t_raw
    wrap = t.number("time_wrap", positive=True)
    bad = np.nonzero((t_raw < 0) | (t_raw >= wrap))[0]
    if bad.size:
        raise SessionError(path, f"time {t_raw[bad[0]]:g} (row {bad[0] + 1}) lies outside "
                           f"the counter's range [0, {wrap:g}) that time_wrap states; check "
                           "time_wrap and the time column's unit")
    back = np.concatenate([[0.0], np.cumsum(np.diff(t_raw) < 0)])
    return t_raw + back * wrap


def unwrap_position(t: Table, path: Path, raw: np.ndarray, unit: str) -> np.ndarray:
    """A position counter that wraps at ``position_wrap`` (in the position's unit, e.g.
    65536 for a 16-bit timer counting encoder edges, signed or not) made continuous: a
    step between rows of more than half the modulus is a wrap.  A position that wraps
    unstated (:func:`_unstated_wrap`) is refused with the fix."""
    if "position_wrap" in t.data:
        wrap = t.number("position_wrap", positive=True)
        steps = np.diff(raw)
        turns = np.where(np.abs(steps) > 0.5 * wrap, np.sign(steps), 0.0)
        return raw - wrap * np.concatenate([[0.0], np.cumsum(turns)])
    cpr = t.number("counts_per_rev", positive=True) if "counts_per_rev" in t.data else None
    found = _unstated_wrap(raw, _moduli(unit, cpr))
    if found is not None:
        k, wrap = found
        raise SessionError(path, f"the position jumps by {abs(raw[k + 1] - raw[k]):.6g} "
                           f"{unit} between rows {k + 1} and {k + 2} (of the data), about "
                           f"{wrap:.6g} {unit}, and stays within that range: a sensor or "
                           f"counter that wraps; add position_wrap = {wrap:.6g} to the trace")
    return raw


def _moduli(unit: str, counts_per_rev: float | None) -> tuple[float, ...]:
    """What a position logged in ``unit`` may wrap at: a turn (an absolute angle
    sensor), and in counts a binary counter's 2^k."""
    turn = {"rad": 2.0 * math.pi, "deg": 360.0, "rev": 1.0}.get(unit)
    if unit == "counts":
        binary = tuple(2.0**bits for bits in (8, 10, 12, 14, 16, 24, 32))
        return binary + ((counts_per_rev,) if counts_per_rev else ())
    return (turn,) if turn else ()


def _unstated_wrap(raw: np.ndarray, moduli) -> tuple[int, float] | None:
    """The first row of a wrap and its modulus where ``raw`` wraps at one of ``moduli``:
    it spans no more than the modulus, steps by more than half of it at least once, and
    read with those steps as wraps moves less than a quarter of it from row to row (a
    jump that no turning rotor makes between two samples); None where it does not."""
    y = np.asarray(raw, dtype=float)
    y = y[np.isfinite(y)]
    if y.size < 3:
        return None
    steps = np.diff(y)
    for wrap in sorted(moduli):
        jumps = np.flatnonzero(np.abs(steps) > 0.5 * wrap)
        if not jumps.size or float(np.ptp(y)) > 1.001 * wrap:
            continue
        moved = steps - wrap * np.round(steps / wrap)
        if float(np.max(np.abs(moved))) < 0.25 * wrap:
            return int(jumps[0]), wrap
    return None


def angle_si(t: Table, raw: np.ndarray, unit: str) -> tuple[np.ndarray, float]:
    """A logged angle in SI and the angle of one count (0 unless in ``counts``)."""
    if unit == "counts":
        q = counts_step(t, "a position in counts")
        return raw * q, q
    return to_si(raw, "angle", unit), 0.0


def differenced_angle(t: Table, time: np.ndarray, speed: np.ndarray, left_out: tuple,
                      stamps: tuple = (None, "s")) -> tuple[np.ndarray, float]:
    """The counted angle (rad, 0 at the first sample) behind a speed (rad/s) that is an
    encoder's counts differenced over each sample interval, and the angle of one count:
    each interval's counts, the speed times the interval (its own, or the trace's
    median: a logger that divides by its nominal rate), are whole numbers to within
    :data:`WHOLE_COUNT`.  A logger that divides by an interval of its own clock and
    stamps the row with a coarser one (an Arduino's ``micros()`` interval beside a
    ``millis()`` stamp) writes counts that are whole only against that unlogged
    interval, within two ticks of the stamps' clock (``stamps``: the raw time column and
    its unit; :func:`stamp_tick`) of the logged one: where every row admits such a
    whole count (:func:`_unlogged_intervals`), the angle is the speed integrated over
    the logged intervals, which is the counted angle at the stamps up to the stamps'
    rounding.  The first row's speed (the interval before it) is not read.  A trace
    that declares ``counts_per_rev`` with a speed column and no position is read so;
    its speed is refused with the fix where no whole counts fit or a row is missing
    (the counts of its interval are lost)."""
    q = counts_step(t, "a speed differenced from encoder counts")
    dt = np.diff(time)
    for step in (dt, np.full_like(dt, np.median(dt))):
        n = speed[1:] * step / q
        off = np.abs(n - np.rint(n))
        if n.size and np.all(off < WHOLE_COUNT):
            n = np.rint(n)
            break
    else:
        tick = stamp_tick(*stamps)
        k = (_unlogged_intervals(speed[1:], dt, q, tick) if 0.0 < tick < 0.5 * np.min(dt)
             else int(np.argmax(off)))
        if k >= 0:
            t.fail("counts_per_rev", f"with a speed column (and no position) the speed is "
                   f"read as the encoder's counts differenced over each sample interval, but "
                   f"row {k + 2}'s speed times its interval is {n[k]:.4g} counts, a whole "
                   "number neither over it nor over any interval within two ticks of the "
                   "time stamps' clock; remove counts_per_rev (a speed the sensor "
                   "measured), or log the counts as columns.position")
        n = speed[1:] * dt / q
    if left_out:
        t.fail("counts_per_rev", f"a speed differenced from encoder counts is read as the "
               f"counted angle, which rows left out break (row {left_out[0]} and "
               f"{len(left_out) - 1} more); fill in those rows, or remove counts_per_rev")
    return q * np.concatenate([[0.0], np.cumsum(n)]), q


def stamp_tick(stamps, unit: str) -> float:
    """The tick (s) of the clock that wrote a time column's raw ``stamps``: the
    resolution they are written to (:func:`~._steady_clock.stamp_resolution`), at most
    one unit of the column (``millis()`` stamps 10 ms apart tick in 1 ms); 0 when there
    are no stamps (a trace given a ``sample_rate``) or none can be told."""
    if stamps is None:
        return 0.0
    return float(to_si(min(stamp_resolution(stamps), 1.0), "time", unit))


def _unlogged_intervals(speed: np.ndarray, dt: np.ndarray, q: float, tick: float) -> int:
    """The first interval (index into ``dt``) whose ``speed`` is not a whole number of
    counts ``q`` over some interval within two ticks (``tick``) of the logged ``dt`` (each end
    stamped up to two ticks late, as by a ``millis()`` that steps by two at times), to
    :data:`WHOLE_COUNT`; a speed of 0 is 0 counts, any other at least one; −1 when
    every interval admits one."""
    v = np.abs(speed)
    lo = np.ceil(v * (dt - 2.0 * tick) / q - WHOLE_COUNT)
    hi = np.floor(v * (dt + 2.0 * tick) / q + WHOLE_COUNT)
    ok = np.where(v > 0.0, hi >= np.maximum(lo, 1.0), True)
    return int(np.argmin(ok)) if not np.all(ok) else -1


def edge_angles(t: Table, n: int, signs: np.ndarray | None) -> tuple:
    """The angle at each edge (rad) and the angle of one count: one count per row,
    forward unless the direction column's ``signs`` (:func:`direction_signs`) say
    backward.  An edge is the boundary between two counts that the rotor crosses: a
    forward edge into count k lies at k counts, a backward edge into count k at k + 1
    (the boundary it left by), so a rotor that turns back re-crosses the same angles."""
    q = counts_step(t, "an encoder-edge trace (edges = true)")
    steps = np.ones(n) if signs is None else signs
    return q * (np.cumsum(steps) + (steps < 0)), q


def direction_signs(path: Path, direction: np.ndarray, lines) -> np.ndarray:
    """A direction column (1 forward; 0 or −1 backward) as signs, +1 or −1; anything
    else is refused with its line of the file (``lines``: each row's)."""
    d = np.asarray(direction, dtype=float)
    bad = np.nonzero(~np.isin(d, (-1.0, 0.0, 1.0)))[0]
    if bad.size:
        raise SessionError(path, f"direction {d[bad[0]]:g} is not 1 (forward), 0 or -1 "
                           "(backward); write the driver's or the decoder's direction bit",
                           where=f"line {lines[bad[0]]}")
    return np.where(d > 0, 1.0, -1.0)


def check_motion_columns(t: Table, cols: dict, edges: bool) -> None:
    """A driven trace logs a speed, an angle, or one row per encoder edge."""
    if edges:
        for role in ("speed", "position", "voltage", "load_torque", "current"):
            if role in cols:
                t.fail(f"columns.{role}", "a trace with edges = true has one row per encoder "
                       "edge (time and, optionally, direction); log the "
                       f"{role} in a trace of its own" + (
                           ", or give it as a schedule" if role in ("voltage", "load_torque")
                           else ""))
    elif "speed" not in cols and "position" not in cols:
        t.fail("columns", 'no speed or position column; add columns.speed = "<header>" or '
               'columns.position = "<header>", or set edges = true for one row per encoder edge')
    if "position_wrap" in t.data and "position" not in cols:
        t.fail("position_wrap", "is only read with a position column (columns.position); "
               "remove it")
    if "direction" in cols and not (edges or "voltage" in cols):
        t.fail("columns.direction", "a direction column signs a voltage column logged as a "
               "magnitude (add columns.voltage), or an encoder-edge trace's edges (set "
               "edges = true); else remove it")


def edges_flag(t: Table) -> bool:
    value = t.data.get("edges", False)
    if not isinstance(value, bool):
        t.fail("edges", f"expected true or false, got {_describe(value)}")
    return value


def speed_window(time: np.ndarray, angle: np.ndarray) -> int:
    """The half-width (in samples read) of :func:`speed_estimate`'s difference for this
    angle: :data:`SPEED_WINDOW` of the samples (at least one), widened until one count
    of a counted angle is at most 1 % of the typical speed (the distance turned, back
    and forth, over the time), up to a twentieth of the samples."""
    ok = np.isfinite(angle)
    tt, aa = time[ok], angle[ok]
    m = max(1, int(round(SPEED_WINDOW * tt.size)))
    steps = np.abs(np.diff(aa))
    steps = steps[steps > 0]
    if steps.size and tt.size > 20:
        typical = float(np.sum(steps)) / np.ptp(tt)
        dt = float(np.median(np.diff(tt)))
        m = max(m, min(int(np.ceil(steps.min() / (0.02 * typical * dt))), tt.size // 20))
    return m


def speed_estimate(time: np.ndarray, angle: np.ndarray, window: int | None = None) -> np.ndarray:
    """The speed (rad/s) from an angle by centred differences over ``window`` samples
    each side (default :func:`speed_window` of this angle; pass the data's to estimate a
    model's angle the same way); 0 where the angle was not read (an encoder trace's
    start at rest)."""
    ok = np.isfinite(angle)
    tt, aa = time[ok], angle[ok]
    m = speed_window(time, angle) if window is None else window
    i = np.arange(tt.size)
    lo, hi = np.maximum(i - m, 0), np.minimum(i + m, tt.size - 1)
    out = np.zeros(time.size)
    out[ok] = (aa[hi] - aa[lo]) / (tt[hi] - tt[lo])
    return out
