"""A trace whose rows a clock stamps without setting their pace (a loop's ``millis()``):
where one of its channels fails a check, how much a reading's time off by up to a tick
moves it, against its noise.

The model takes each stamp as the reading's exact time.  A reading taken up to a tick
``q`` after its stamp (uniformly: an error of sd ``q/√12`` in time) is off by its
signal's slope times that error; where the slope's largest such error exceeds the
channel's own noise, the stamps alone make a misfit of the size the checks see, and a
dead time or a lag the diagnosis proposes from it would fit the stamps, not the rig.
"""

from __future__ import annotations

import numpy as np

from ...io.channel import ChannelId
from ...io.lattice import clock_tick
from ..model.noise import noise_scale

__all__ = ["clock_rules"]

_UNITS = {"speed": "rad/s", "current": "A", "position": "rad"}


def clock_rules(model, findings) -> list[str]:
    """A sentence for each failing channel of a trace stamped by a clock of its own
    (:func:`~pmdc_bayes.io.lattice.clock_tick`) that a tick's error in time moves, at
    its fastest, by more than its noise."""
    failing = {f.where for f in findings if f.failed and isinstance(f.where, ChannelId)}
    out = []
    for tr in model.session.traces:
        tick = clock_tick(tr.time)
        if not tick > 0.0:
            continue
        logged = {"speed": tr.speed if tr.speed_logged else None, "current": tr.current,
                  "position": tr.position}
        for what, y in logged.items():
            if y is None or ChannelId(tr.name, what) not in failing:
                continue
            ok = np.isfinite(y)
            if ok.sum() < 3:
                continue
            t, v = np.asarray(tr.time, float)[ok], np.asarray(y, float)[ok]
            moved = float(np.max(np.abs(np.gradient(v, t)))) * tick / np.sqrt(12.0)
            noise = noise_scale(v)
            if not moved > noise:
                continue
            out.append(f"{tr.name}: its rows are stamped to {tick * 1e3:.3g} ms by a clock "
                       f"that does not set their pace, and where its {what} moves fastest "
                       f"a reading's time off within a tick moves it by {moved:.2g} "
                       f"{_UNITS[what]} (sd), {moved / noise:.2g} times its noise: the "
                       "model takes each stamp as exact, so this misfit may be the stamps', "
                       "not the motor's, and a dead time or lag fitted to it would be too; "
                       "log the time with a finer clock (micros()) or sample at a steady "
                       "rate")
    return out
