"""The likelihood's observations, grouped in *blocks* of channels.

A channel is a set of observations sharing one unknown noise level (a trace's speed,
a trace's current, the steady speeds, the steady currents, the step readings' τ).  A
block owns the channels that one prediction serves (one simulation of every trace,
one evaluation of the steady state) and knows three things about them:

* **observations and noise**: it registers its channels (name, unit, number of
  observations, model-free noise scale) and puts its arrays in the data pytree;
* **layout**: for each residual array it returns, the mask of real observations and
  the channel of each entry along the first axis (every entry of a row of a 2-D array
  belongs to that row's channel), and the observed values in the same layout;
* **prediction**: the residuals (observed − model) at θ.

The objective treats every array alike (sums of squares per channel, weighted
residuals, pointwise densities), so a new kind of observation is one new block here,
added to :func:`blocks_for`.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from ..io.session import Session
from ..physics import motor
from ..physics.experiment import Experiment, steady_points
from ..physics.solution import simulate_padded
from .noise import noise_scale, typical_level
from .nuisances import initial_speed_name

__all__ = ["Block", "TraceBlock", "CoastDownBlock", "SteadyBlock", "StepReadingBlock", "blocks_for",
           "STEADY_RELATIVE_NOISE"]

STEADY_RELATIVE_NOISE = 0.01

AddChannel = Callable[[str, str, int, float], int]


class Block:
    """What every block shares: its data pytree, and the layout of a block with one
    residual array whose mask and channels are ``d["mask"]`` and ``d["ch"]``."""

    key = ""
    _data: dict

    def data(self) -> dict:
        return self._data

    @staticmethod
    def layout(d) -> list:
        return [(d["mask"], d["ch"])]


class TraceBlock(Block):
    """Every trace's speed and (when logged) current, in the experiment's padded
    ``(C, L)`` chunk layout; one simulation predicts them all."""

    key = "traces"

    def __init__(self, session: Session, exp: Experiment, add: AddChannel):
        self.exp = exp
        speed_ch, current_ch, speeds, currents = [], [], [], []
        for tr in session.traces:
            speed_ch.append(add(f"{tr.name}: speed", "rad/s", tr.n, noise_scale(tr.speed)))
            speeds.append(tr.speed)
            if tr.current is not None:
                current_ch.append(add(f"{tr.name}: current", "A", tr.n,
                                      noise_scale(tr.current)))
                currents.append(tr.current)
            else:
                current_ch.append(-1)
                currents.append(np.zeros(tr.n))
        ct = np.asarray(exp.chunk_trace)
        cur = np.asarray(current_ch)[ct]
        starts = np.concatenate([np.arange(tr.n) == 0 for tr in session.traces])
        self._data = {"exp": exp, "speed": exp.pad(np.concatenate(speeds)),
                      "t": np.concatenate([tr.time for tr in session.traces]),
                      "start": starts,
                      "current": exp.pad(np.concatenate(currents)),
                      "speed_ch": np.asarray(speed_ch)[ct],
                      "current_ch": np.where(cur >= 0, cur, 0),
                      "current_mask": np.asarray(exp.mask) & (cur >= 0)[:, None]}

    @staticmethod
    def layout(d) -> list:
        return [(d["exp"].mask, d["speed_ch"]), (d["current_mask"], d["current_ch"])]

    @staticmethod
    def observed(d) -> list:
        return [d["speed"], d["current"]]

    @staticmethod
    def residuals(model, theta, d, fast: bool = False) -> list:
        ia, w = model.sensed(theta, *simulate_padded(
            model.params(theta), model.inputs(theta, d["exp"]), coulomb=model.coulomb_path,
            fast=fast), d)
        return [d["speed"] - w, d["current"] - ia]


class SteadyBlock(Block):
    """Steady speeds and currents: operating points, steady-table rows and the step
    readings' final speeds (:func:`~pmdc_bayes.physics.experiment.steady_points`),
    predicted by the steady state; noise scale 1 % of the typical reading."""

    key = "steady"

    def __init__(self, session: Session, add: AddChannel):
        st = steady_points(session)
        self.points = st
        cw = add("steady: speed", "rad/s", int(st["w_mask"].sum()),
                 STEADY_RELATIVE_NOISE * typical_level(st["w"], st["w_mask"]))
        ci = add("steady: current", "A", int(st["i_mask"].sum()),
                 STEADY_RELATIVE_NOISE * typical_level(st["i"], st["i_mask"]))
        n = st["v"].size
        self._data = dict(st, w_ch=np.full(n, cw), i_ch=np.full(n, ci))

    @staticmethod
    def layout(d) -> list:
        return [(d["w_mask"], d["w_ch"]), (d["i_mask"], d["i_ch"])]

    @staticmethod
    def observed(d) -> list:
        return [d["w"], d["i"]]

    @staticmethod
    def residuals(model, theta, d, fast: bool = False) -> list:
        w, i = model.steady_prediction(model.params(theta), d["v"], d["tl"],
                                       model.drop(theta))
        return [d["w"] - w, d["i"] - i]


class StepReadingBlock(Block):
    """The step readings' 63.2 % times, predicted by the time constant (9); noise scale
    1 % of the mean reading."""

    key = "tau"

    def __init__(self, session: Session, add: AddChannel):
        taus = np.asarray([s.tau for s in session.step_readings], dtype=float)
        level = float(taus.mean()) if taus.size else 1.0
        c = add("step readings: tau", "s", taus.size, STEADY_RELATIVE_NOISE * level)
        self._data = {"tau": taus, "mask": np.ones(taus.size, bool),
                      "ch": np.full(taus.size, c)}

    @staticmethod
    def observed(d) -> list:
        return [d["tau"]]

    @staticmethod
    def residuals(model, theta, d, fast: bool = False) -> list:
        return [d["tau"] - model.tau_prediction(model.params(theta))]


class CoastDownBlock(Block):
    """The coast-downs' speeds (the armature open), padded to one length; predicted by
    :func:`~pmdc_bayes.physics.motor.coast_down` from B, J, Tc and each trace's fitted
    initial speed (``initial_speed_<trace>``)."""

    key = "coast_down"

    def __init__(self, session: Session, add: AddChannel):
        traces = session.coast_downs
        self.names = tuple(initial_speed_name(tr.name) for tr in traces)
        length = max(tr.n for tr in traces)
        t, y = np.zeros((len(traces), length)), np.zeros((len(traces), length))
        mask = np.zeros((len(traces), length), bool)
        ch = []
        for k, tr in enumerate(traces):
            t[k, :tr.n], y[k, :tr.n], mask[k, :tr.n] = tr.time - tr.time[0], tr.speed, True
            ch.append(add(f"{tr.name}: speed", "rad/s", tr.n, noise_scale(tr.speed)))
        self._data = {"t": t, "speed": y, "mask": mask, "ch": np.asarray(ch)}

    @staticmethod
    def observed(d) -> list:
        return [d["speed"]]

    def residuals(self, model, theta, d, fast: bool = False) -> list:
        p = model.params(theta)
        v = model.registry.values(theta)
        w0 = jnp.stack([v[n] for n in self.names])[:, None]
        w = motor.coast_down(p.B, p.J, w0, d["t"], p.Tc if model.coulomb else 0.0)
        return [d["speed"] - w]


def blocks_for(session: Session, exp: Experiment | None, add: AddChannel) -> list:
    """The blocks of a session, in channel order: the driven traces (when there are
    any), the coast-downs (when there are any), the steady readings, the step
    readings."""
    out = [TraceBlock(session, exp, add)] if exp is not None else []
    if session.coast_downs:
        out.append(CoastDownBlock(session, add))
    return out + [SteadyBlock(session, add), StepReadingBlock(session, add)]


def entry_weights(values, ch, r):
    """``values[ch]`` shaped to multiply ``r`` (a row's channel spans its row)."""
    v = jnp.asarray(values)[ch]
    return v.reshape(v.shape + (1,) * (r.ndim - v.ndim))
