"""What the closed form reads off a step trace, and the checks its result must pass.

The step of a trace (its largest voltage change) and whether it ends turning are what
the method reads; a result no motor can have (K <= 0, J <= 0, a time constant no longer
than the electrical one) or one its own trace contradicts (a speed moving against the
voltage, a settled speed a factor :data:`GAIN_MISMATCH` away from the gain (10)) is
refused as :class:`~pmdc_bayes.NotApplicable`, naming the input that makes it so.
"""

from __future__ import annotations

import numpy as np

from .._errors import NotApplicable
from ..io.robust import MAD_SD
from ..io.session import Session, Trace
from ..physics.motor import gain
from .changes import responses

__all__ = ["GAIN_MISMATCH", "SETTLED", "step_of", "turns", "check_trace", "check_physical",
           "traces_without_steady_current"]


STEP_OVER_JITTER = 10.0  # a logged voltage's step stands this far above its jitter


def step_of(trace: Trace) -> tuple[float, float, float]:
    """(time of the largest voltage change, voltage before, voltage after); a constant
    voltage is a step from rest at the first sample.

    A voltage logged at every sample jitters: its largest change is a step only when it
    stands :data:`STEP_OVER_JITTER` times above the jitter (a robust scale of the
    sample-to-sample changes), and the levels either side are medians of ten samples.
    """
    v = trace.voltage.values
    times = trace.voltage.times
    if v.size < 2:
        return float(trace.time[0]), 0.0, float(v[0])
    jumps = np.abs(np.diff(v))
    k = int(np.argmax(jumps))
    if v.size < max(8, trace.n // 2):  # a schedule: every change is a step
        return float(max(times[k + 1], trace.time[0])), float(v[k]), float(v[k + 1])
    if jumps[k] <= STEP_OVER_JITTER * MAD_SD * float(np.median(jumps)):
        return float(trace.time[0]), 0.0, float(np.median(v))
    return (float(max(times[k + 1], trace.time[0])), float(np.median(v[max(0, k - 9):k + 1])),
            float(np.median(v[k + 1:k + 11])))


def turns(trace: Trace) -> bool:
    """Whether a trace ends turning: its settled speed is a fair share of its largest
    (a motor that never moved shows only noise, whose mean is far below its peaks),
    so it gives a steady point for (20)."""
    n_tail = max(3, trace.n // 10)
    w = abs(float(np.mean(trace.speed[-n_tail:])))
    return w > 0.2 * float(np.max(np.abs(trace.speed))) and w > 0


SETTLED = 0.02  # a trace's last tenth moving less than this share of its level has settled
GAIN_MISMATCH = 2.0  # a trace settling this factor away from the gain (10) contradicts it


def check_trace(session: Session, tr: Trace, K, B, Ra) -> None:
    """Refuse a step trace that contradicts the closed form: a speed moving against the
    voltage step over its response (a reversed sign), or an unloaded settled speed a
    factor :data:`GAIN_MISMATCH` away from what the gain (10) predicts (a unit slip
    between the operating point and the trace)."""
    found = responses(tr)  # the largest change and its response (a staircase's one step)
    if found:
        v0, v1, a, b = found[0].before, found[0].after, found[0].start, found[0].stop
    else:
        (_, v0, v1), a, b = step_of(tr), 0, tr.n
    n_tail = max(3, tr.n // 10)
    w_end = float(np.mean(tr.speed[-n_tail:]))
    moved = float(np.mean(tr.speed[b - max(3, (b - a) // 10):b]) - np.mean(tr.speed[a:a + 3]))
    if (v1 - v0) * moved < 0:
        raise NotApplicable(tr.file, f"trace {tr.name!r}: the speed falls by {abs(moved):.3g} "
                            f"rad/s while the voltage steps {'up' if v1 > v0 else 'down'}: "
                            "the speed counts the other way; flip its sign (or the "
                            "voltage's) so that positive voltage gives positive speed")
    va_end = float(tr.voltage.at(tr.time[-n_tail:]).mean())
    tl_end = float(tr.load_torque.at(tr.time[-n_tail:]).mean())
    if not (turns(tr) and tl_end == 0 and va_end != 0):
        return
    tail = tr.speed[-n_tail:]
    half = tail.size // 2
    if abs(float(np.mean(tail[half:]) - np.mean(tail[:half]))) > SETTLED * abs(w_end):
        return  # still moving at its end (a short capture): no steady speed to compare
    predicted = gain(Ra, K, B) * va_end
    ratio = w_end / predicted
    if not 1 / GAIN_MISMATCH < ratio < GAIN_MISMATCH:
        raise NotApplicable(tr.file, f"trace {tr.name!r} settles at {w_end:.4g} rad/s at "
                            f"{va_end:.3g} V where the closed form's gain (10) predicts "
                            f"{predicted:.4g} rad/s ({ratio:.3g} x): the steady point and the "
                            "trace disagree; check both speeds' units (rpm given as rad/s "
                            "is 9.55 x)")


def check_physical(session: Session, Ra, La, K, B, tau, used) -> None:
    """Refuse a result no motor can have (K <= 0, J <= 0, a time constant no longer than
    the electrical one), naming the inputs that make it so.  A B <= 0 alone is a noisy
    no-load current, not an impossibility: :attr:`ClosedForm.warnings` says so."""
    toml = session.root / "session.toml"

    if not (np.isfinite(K) and K > 0):
        raise NotApplicable(toml, f"{used['K']} gives K = {K:.3g} (it must be positive): the "
                            "resistive drop Ra*Ia reaches the applied voltage there; check "
                            "the current, the voltage (duty as a fraction, supply in V), "
                            "bench.Ra and K_decimals", where="operating_point")
    if not (np.isfinite(B) and B * Ra + K * K > 0):  # J of (9) > 0
        raise NotApplicable(toml, f"{used['B']} gives B = {B:.3g}, and with it J <= 0 from "
                            "(9): the steady current or speed there is not positive; check "
                            "their signs and values", where="operating_point")
    if not (np.isfinite(tau) and tau > La / Ra):
        raise NotApplicable(toml, f"the time constant from the {used['tau']} is "
                            f"{tau:.3g} s, not longer than the electrical time constant "
                            f"La/Ra = {La / Ra:.3g} s, so it cannot be the mechanical one of "
                            "(8); check the value and its unit", where="step_reading")


def traces_without_steady_current(session) -> str:
    """Why the traces that log a current give the closed form no steady current, for its
    refusal (empty if none logs one)."""
    why = [f"step trace {t.name!r} ends near rest" if t.kind == "step" else
           f"trace {t.name!r} is a {t.kind.replace('_', ' ')}"
           for t in session.traces if t.current is not None][:3]
    return (f" ({'; '.join(why)}: the method reads the settled end of a step that turns);"
            " `pmdc-bayes fit` needs none, it starts from the data") if why else ""
