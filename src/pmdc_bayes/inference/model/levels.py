"""The session's steady levels, model-free: where the speed-voltage line crosses zero
speed, the current left at zero speed, and traces whose level sits off the line the
rest of the session draws."""

from __future__ import annotations

import numpy as np

from ...paper.changes import AT_REST, plateaus

__all__ = ["settled", "unloaded_levels", "voltage_intercept", "direction_intercepts",
           "friction_offset", "level_outliers", "level_se"]

LEVEL_MISS = 0.03  # a level off the others' line by more than this fraction of itself
LINE_FIT = 0.01  # the others must sit on their line within this fraction (rms)
_SE_FLOOR = 1e-9  # a level's standard error, at least this fraction of the largest level


def settled(y) -> bool:
    """Whether a trace has reached its steady level: the means of its last two tenths
    agree within 0.5 % of the level plus what the noise allows (of three samples each
    at least: a shorter trace is not judged settled)."""
    from .noise import noise_scale

    y = np.asarray(y, float)
    n = max(3, y.size // 10)
    if y.size < 2 * n:
        return False
    a, b = float(np.mean(y[-2 * n:-n])), float(np.mean(y[-n:]))
    return abs(b - a) <= 0.005 * abs(b) + 4 * noise_scale(y) / np.sqrt(n)


def unloaded_levels(session, *, with_drag: bool = False,
                    held: bool = False) -> tuple[np.ndarray, list]:
    """Every unloaded steady level (rows of voltage, speed, current or NaN) and, per
    row, the trace it ends (None for tables and operating points); traces that end
    before they settle, or that drive a load (a load torque, a declared drag unless
    ``with_drag``), give none.

    With ``held``, a trace gives a level at the end of every plateau its voltage is held
    on (:func:`pmdc_bayes.paper.changes.plateaus`, a staircase's every step) where its
    speed has settled and no load is applied (not one held at 0 V), named by the trace;
    the voltage of a level is the mean of the input over the samples its speed is read
    from.
    """
    rows, names = [], []
    for tab in session.steady_tables:
        cur = tab.current if tab.current is not None else np.full(tab.voltage.size, np.nan)
        for v, w, i, tl in zip(tab.voltage, tab.speed, cur, tab.load_torque, strict=True):
            if tl == 0:
                rows.append((v, w, i))
                names.append(None)
    for op in session.operating_points:
        if op.load_torque == 0:
            rows.append((op.voltage, op.speed, np.nan if op.current is None else op.current))
            names.append(None)
    for tr in session.traces:
        if tr.drag.nonzero and not with_drag:
            continue
        for row in (_held_levels(tr) if held else _end_level(tr)):
            rows.append(row)
            names.append(tr.name)
    return np.asarray(rows, float).reshape(-1, 3), names


def _end_level(tr) -> list[tuple]:
    """The level a trace ends on, when it settles there unloaded (none otherwise)."""
    if not (np.all(tr.load_torque.values == 0) and settled(tr.speed)):
        return []
    n = max(3, tr.n // 10)
    i = np.nan if tr.current is None else float(np.mean(tr.current[-n:]))
    v = (float(np.mean(tr.voltage.at(tr.time[-n:]))) if tr.voltage_logged
         else float(tr.voltage.values[-1]))
    return [(v, float(np.mean(tr.speed[-n:])), i)]


def _held_levels(tr, with_se: bool = False) -> list[tuple]:
    """The settled, unloaded end of every plateau a trace's voltage is held on, except
    a plateau at rest (0 V, or a logged 0 V's noise: below :data:`AT_REST` of the
    trace's largest voltage), which has no gain to read: ``(voltage, speed, current)``,
    or with ``with_se`` ``(voltage, speed, the speed's standard error)``: the readings'
    own (:func:`level_se`), and no less than what the sensor's resolution leaves
    (:func:`_resolution`), which averaging does not remove."""
    held = plateaus(tr)
    dt = float(np.median(np.diff(tr.time))) if tr.n > 1 else 1.0
    top = max(abs(p.level) for p in held)
    cuts = sorted({p.start for p in held}
                  | {p.start for p in plateaus(tr, "load_torque")} | {tr.n})
    out = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        n = max(3, (b - a) // 10)
        if b - a < 3 * n or np.any(tr.load_torque.at(tr.time[a:b]) != 0):
            continue
        if abs(float(np.median(tr.voltage.at(tr.time[a:b])))) <= AT_REST * top:
            continue
        if not settled(tr.speed[a:b]):
            continue
        i = np.nan if tr.current is None else float(np.mean(tr.current[b - n:b]))
        if with_se:
            i = max(level_se(tr.speed[a:b], n), _resolution(tr, n * dt))
        out.append((float(np.mean(tr.voltage.at(tr.time[b - n:b]))),
                    float(np.mean(tr.speed[b - n:b])), i))
    return out


def level_se(y, n: int) -> float:
    """The standard error of the mean of a settled signal's last ``n`` readings, from
    the noise's level (:func:`~.noise.noise_scale`, over the whole of ``y``) and the
    lag-1 correlation ρ of those readings about their straight line (a sensor's filter
    colours them; less its estimate's bias, about −(2 + 4ρ)/n about a fitted line): the
    AR(1) mean's (:func:`~.coloured.mean_se_factor`), its innovations' level read from
    the second differences' (:func:`~.coloured.innovation_scale`); white (ρ = 0) for a
    quantised signal (on a lattice, or few distinct readings), whose resolution is
    reckoned apart, and for ρ ≤ 0."""
    from .coloured import innovation_scale, mean_se_factor
    from .noise import noise_scale, quantum

    y = np.asarray(y, float)
    s = noise_scale(y)
    tail = y[-n:]
    rho = 0.0
    if n > 3 and quantum(y) == 0.0 and np.unique(tail).size > n // 2:  # analogue
        k = np.arange(n, dtype=float)
        tail = tail - np.polyval(np.polyfit(k, tail, 1), k)
        ss = float(tail @ tail)
        r = float(tail[1:] @ tail[:-1]) / ss if ss > 0 else 0.0
        rho = min(max(r + (2.0 + 4.0 * r) / n, 0.0), 0.99) if r > 0 else 0.0
    if rho == 0.0:
        return s / np.sqrt(n)
    return float(s * innovation_scale(rho) * mean_se_factor(rho, n) / np.sqrt(n))


def _resolution(tr, window: float) -> float:
    """The error a speed level averaged over ``window`` seconds keeps however quiet its
    readings: a counted angle's (one count at each end of the window, over the window),
    else a quantised speed's (its quantum over √12); 0 for an analogue speed."""
    from .noise import quantum

    if not tr.speed_logged and tr.position is not None:
        step = tr.encoder_step or quantum(tr.position)
        return step / (np.sqrt(6.0) * window)
    return quantum(tr.speed) / np.sqrt(12.0)


def voltage_intercept(session) -> dict | None:
    """The line of steady speed against voltage over every unloaded steady level: the
    voltage where it crosses zero speed, with its standard error (None with fewer than
    three distinct voltages or a line that does not rise)."""
    rows, _ = unloaded_levels(session)
    if rows.shape[0] < 3 or np.unique(np.round(rows[:, 0], 9)).size < 3:
        return None
    (slope, icpt), cov = np.polyfit(rows[:, 0], rows[:, 1], 1, cov=True)
    if slope <= 0:
        return None
    g = np.array([icpt / slope**2, -1 / slope])
    return {"voltage": float(-icpt / slope), "se": float(np.sqrt(max(g @ cov @ g, 0.0))),
            "largest_voltage": float(np.max(np.abs(rows[:, 0])))}


def direction_intercepts(session) -> dict[int, dict]:
    """For each sign of the voltage with levels at two or more distinct voltages (every
    settled plateau of every trace, the tables' and operating points'), where the line of
    steady speed against voltage in magnitude crosses zero speed, with its standard error:
    sign -> ``{"voltage", "se"}``.  Each level's speed is weighted by its mean's own
    standard error (:func:`level_se`, a coloured sensor's counted; a level of a table or
    operating point by 1 % of itself)."""
    rows, errs = [], []
    for tab in session.steady_tables:
        for v, w, tl in zip(tab.voltage, tab.speed, tab.load_torque, strict=True):
            if tl == 0:
                rows.append((v, w))
                errs.append(0.01 * abs(w))
    for op in session.operating_points:
        if op.load_torque == 0:
            rows.append((op.voltage, op.speed))
            errs.append(0.01 * abs(op.speed))
    for tr in session.traces:
        if not tr.drag.nonzero:
            for v, w, se in _held_levels(tr, with_se=True):
                rows.append((v, w))
                errs.append(se)
    out = {}
    for sign in (1, -1):
        pick = [k for k, (v, w) in enumerate(rows) if np.sign(v) == sign and w * sign > 0]
        v = np.array([abs(rows[k][0]) for k in pick])
        w = np.array([abs(rows[k][1]) for k in pick])
        if np.unique(np.round(v, 9)).size < 2:
            continue
        se = np.maximum(np.array([errs[k] for k in pick]), _SE_FLOOR * max(w.max(), 1e-300))
        fitted = _weighted_line(v, w, se)
        if fitted is None:
            continue
        (slope, icpt), cov = fitted
        if slope <= 0:
            continue
        g = np.array([icpt / slope**2, -1 / slope])
        out[sign] = {"voltage": float(-icpt / slope), "se": float(np.sqrt(max(g @ cov @ g, 0.0)))}
    return out


def _weighted_line(x, y, se):
    """The weighted least-squares line ``y = slope·x + intercept`` and its covariance,
    solved through the singular values of the weighted design (not its normal
    equations, which lose the line when a few levels carry almost all the weight);
    None when the levels cannot fix a line."""
    a = np.stack([x, np.ones_like(x)], axis=1) / se[:, None]
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    if s[-1] <= s[0] * 1e-12:
        return None
    coef = vt.T @ ((u.T @ (y / se)) / s)
    cov = (vt.T / s**2) @ vt
    return coef, cov


def friction_offset(session) -> dict | None:
    """The line of steady current against speed: the current left at zero speed
    (friction torque that does not scale with speed, over K), with its standard error."""
    rows, _ = unloaded_levels(session)
    rows = rows[np.isfinite(rows[:, 2])]
    if rows.shape[0] < 3 or np.unique(np.round(rows[:, 1], 6)).size < 3:
        return None
    (_, icpt), cov = np.polyfit(rows[:, 1], rows[:, 2], 1, cov=True)
    return {"current": float(icpt), "se": float(np.sqrt(max(cov[1, 1], 0.0))),
            "mean_current": float(np.mean(np.abs(rows[:, 2])))}


def level_outliers(session) -> dict | None:
    """Traces whose final speed sits off the speed-voltage line of the other levels
    (left out one at a time) by more than :data:`LEVEL_MISS` of itself, while those
    others lie on their line: trace name -> relative miss (negative: below).  None when
    the session has too few levels to draw a line without the trace."""
    rows, names = unloaded_levels(session)
    out, judged = {}, False
    for k, name in enumerate(names):
        if name is None:
            continue
        rest = np.delete(rows, k, axis=0)
        if rest.shape[0] < 3 or np.unique(np.round(rest[:, 0], 9)).size < 2:
            continue
        judged = True
        slope, icpt = np.polyfit(rest[:, 0], rest[:, 1], 1)
        scale = max(float(np.max(np.abs(rest[:, 1]))), 1e-300)
        spread = np.sqrt(np.mean((rest[:, 1] - (slope * rest[:, 0] + icpt)) ** 2)) / scale
        expected = slope * rows[k, 0] + icpt
        miss = (rows[k, 1] - expected) / max(abs(expected), 1e-300)
        if abs(miss) > LEVEL_MISS and spread < LINE_FIT:
            out[name] = float(miss)
    return out if judged else None
