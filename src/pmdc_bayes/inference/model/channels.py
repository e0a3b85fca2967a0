"""The likelihood's observations, grouped in *blocks* of channels.

A channel is a set of observations sharing one unknown noise level (a trace's speed,
a trace's current, the steady speeds, the steady currents, the step readings' τ).  A
block owns the channels that one prediction serves (one simulation of every trace,
one evaluation of the steady state) and knows three things about them:

* **observations and noise**: it registers its channels (name, unit, number of
  observations, model-free noise scale and, for a quantised signal noise does not
  dither, the share of readings with independent errors); its arrays go in the data;
* **layout**: for each residual array it returns, the mask of real observations and
  the channel of each entry along the first axis (every entry of a row of a 2-D array
  belongs to that row's channel), and the observed values in the same layout;
* **prediction**: the residuals (observed − model) at θ.

The objective treats every array alike (per-channel sums of squares, weighted residuals,
pointwise densities): a new kind of observation is one block in :func:`blocks_for`.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from ...io.channel import STEADY, STEP_READINGS, ChannelId
from ...io.readings import steady_points
from ...io.session import Session
from ...physics import motor
from ...physics.angle import since_first_sample
from ...physics.experiment import Experiment
from ...physics.sensor import coast_down_reading, pole
from ...physics.solution import simulate_padded
from .coloured import COLOURED, breaks, previous_index
from .column_levels import level_data
from .noise import effective_fraction, noise_scale, typical_level
from .nuisances import open_data
from .switch_lead import lead_data
from .trace_states import initial_speed_name, position_offset_name

__all__ = ["Block", "TraceBlock", "CoastDownBlock", "SteadyBlock", "StepReadingBlock",
           "blocks_for", "resting_counts", "STEADY_RELATIVE_NOISE"]

STEADY_RELATIVE_NOISE = 0.01

AddChannel = Callable[..., int]  # (ChannelId, unit, n, s0[, alpha]) -> channel index


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

    def previous(self, d) -> list:
        """Per residual array, each entry's previous reading where its noise may be
        coloured (:mod:`.coloured`), else None."""
        return [None] * len(self.layout(d))


def resting_counts(tr) -> np.ndarray:
    """The samples of a counted angle (``tr.encoder_step`` > 0) of a trace starting at
    rest that the likelihood leaves out: the run of identical readings the trace starts
    with, all but its last.  At rest a count's quantisation is not noise but one
    constant error (where the rotor sits within its count), repeated; read as
    independent Gaussian errors those readings would outweigh the motion and pull the
    fitted offset and dead time (by about a quarter of a sample on the bundled bench).
    The last of them keeps what they tell: the rotor had not yet moved a count."""
    out = np.zeros(tr.n, bool)
    if tr.position is None or not tr.encoder_step > 0 or tr.initial != "rest":
        return out
    y = tr.position
    ok = np.flatnonzero(np.isfinite(y))
    if ok.size < 2:
        return out
    moved = ok[np.flatnonzero(y[ok] != y[ok[0]])]
    if moved.size == 0:
        return out
    before = ok[ok < moved[0]]
    out[before[:-1]] = True
    return out


class TraceBlock(Block):
    """Every trace's speed (when logged), current (when logged) and angle (when a
    position sensor or an encoder read it), in the experiment's padded ``(C, L)`` chunk
    layout; one simulation predicts them all.  The angle is the exact integral of the
    speed (:mod:`~pmdc_bayes.physics.angle`) plus the trace's fitted
    ``position_offset_<trace>``."""

    key = "traces"

    def __init__(self, session: Session, exp: Experiment, add: AddChannel):
        self.exp = exp
        self.offsets = tuple(position_offset_name(tr.name) for tr in session.traces
                             if tr.position is not None)
        chans = {"speed": [], "current": [], "position": []}
        values = {"speed": [], "current": [], "position": []}
        seen = {"speed": [], "current": [], "position": []}
        for tr in session.traces:
            logged = {"speed": tr.speed if tr.speed_logged else None,
                      "current": tr.current, "position": tr.position}
            for what, unit in (("speed", "rad/s"), ("current", "A"), ("position", "rad")):
                y = logged[what]
                if y is None:
                    chans[what].append(-1)
                    values[what].append(np.zeros(tr.n))
                    seen[what].append(np.zeros(tr.n, bool))
                    continue
                ok = np.isfinite(y)
                if what == "position":
                    ok &= ~resting_counts(tr)
                chans[what].append(add(ChannelId(tr.name, what), unit, int(ok.sum()),
                                       noise_scale(y[ok]), effective_fraction(y[ok])))
                values[what].append(np.where(ok, y, 0.0))
                seen[what].append(ok)
        ct = np.asarray(exp.chunk_trace)
        starts = np.concatenate([np.arange(tr.n) == 0 for tr in session.traces])
        with_pos = [k for k, tr in enumerate(session.traces) if tr.position is not None]
        slot = np.zeros(len(session.traces), int)
        slot[with_pos] = np.arange(len(with_pos))
        self._data = {"exp": exp, "t": np.concatenate([tr.time for tr in session.traces]),
                      "start": starts, **level_data(session, exp), **lead_data(session, exp),
                      **open_data(session),
                      "sample_slot": np.repeat(slot, [tr.n for tr in session.traces])}
        for what in chans:
            ch = np.asarray(chans[what])[ct]
            self._data[what] = exp.pad(np.concatenate(values[what]))
            self._data[f"{what}_ch"] = np.where(ch >= 0, ch, 0)
            self._data[f"{what}_mask"] = (np.asarray(exp.mask) & (ch >= 0)[:, None]
                                          & np.asarray(exp.pad(np.concatenate(seen[what])),
                                                       bool))
        if COLOURED in session.nuisances:  # each reading's previous, for the whitening
            for what in ("speed", "current"):
                self._data[f"{what}_prev"] = previous_index(
                    np.concatenate(seen[what]),
                    np.concatenate([breaks(tr.time) for tr in session.traces]),
                    np.asarray(exp.index), np.shape(exp.mask))

    @staticmethod
    def previous(d) -> list:
        """Per residual array, each entry's previous reading (:mod:`.coloured`), or None
        for an array never whitened."""
        return [d.get("speed_prev"), d.get("current_prev"), None]

    @staticmethod
    def layout(d) -> list:
        return [(d[f"{w}_mask"], d[f"{w}_ch"]) for w in ("speed", "current", "position")]

    @staticmethod
    def observed(d) -> list:
        return [d["speed"], d["current"], d["position"]]

    def residuals(self, model, theta, d, fast: bool = False, overflow: bool = False) -> list:
        """The residuals of speed, current and angle; with ``overflow``, also per segment
        whether it changes regime more often than the exact solution follows."""
        exp = model.inputs(theta, model.held(theta, d["exp"], d), d)
        p = model.circuit(theta)
        sim = simulate_padded(p, exp, coulomb=model.coulomb_path, fast=fast,
                              limit=model.limit(theta), with_angle=bool(self.offsets),
                              lags=model.lags(theta), **model.armature_drop(theta, d),
                              overflow=overflow)
        ia, w = model.sensed(theta, sim[0], sim[1])
        out = [d["speed"] - w, d["current"] - ia]
        if not self.offsets:
            out.append(jnp.zeros_like(w))
        else:
            v = model.registry.values(theta)
            offset = jnp.stack([v[n] for n in self.offsets])[d["sample_slot"]]
            angle = since_first_sample(exp, sim[2], d["start"])
            out.append(d["position"] - exp.pad(offset + angle))
        return (out, sim[-1]) if overflow else out


class SteadyBlock(Block):
    """Steady speeds and currents: operating points, steady-table rows and the step
    readings' final speeds (:func:`~pmdc_bayes.io.readings.steady_points`),
    predicted by the steady state; noise scale 1 % of the typical reading."""

    key = "steady"

    def __init__(self, session: Session, add: AddChannel):
        st = steady_points(session)
        self.points = st
        cw = add(ChannelId(STEADY, "speed"), "rad/s", int(st["w_mask"].sum()),
                 STEADY_RELATIVE_NOISE * typical_level(st["w"], st["w_mask"]))
        ci = add(ChannelId(STEADY, "current"), "A", int(st["i_mask"].sum()),
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
        i, w = model.steady_at(theta, d["v"], d["tl"])
        return [d["w"] - w, d["i"] - i]


class StepReadingBlock(Block):
    """The step readings' 63.2 % times, predicted by the time constant (9); noise scale
    1 % of the mean reading."""

    key = "tau"

    def __init__(self, session: Session, add: AddChannel):
        taus = np.asarray([s.tau for s in session.step_readings], dtype=float)
        level = float(taus.mean()) if taus.size else 1.0
        c = add(ChannelId(STEP_READINGS, "tau"), "s", taus.size, STEADY_RELATIVE_NOISE * level)
        self._data = {"tau": taus, "mask": np.ones(taus.size, bool),
                      "ch": np.full(taus.size, c)}

    @staticmethod
    def observed(d) -> list:
        return [d["tau"]]

    @staticmethod
    def residuals(model, theta, d, fast: bool = False) -> list:
        return [d["tau"] - model.tau_prediction(model.circuit(theta))]


class CoastDownBlock(Block):
    """The coast-downs' speeds (the armature open), padded to one length; predicted by
    :func:`~pmdc_bayes.physics.motor.coast_down` from B, J, Tc and each trace's fitted
    initial speed (``initial_speed_<trace>``), read through the speed sensor's declared
    lag (:func:`~pmdc_bayes.physics.sensor.coast_down_reading`, settled at the first
    sample: the rotor ran steadily before), gain and offset, as the driven traces'
    speeds are."""

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
            t[k, tr.n:] = t[k, tr.n - 1]
            ch.append(add(ChannelId(tr.name, "speed"), "rad/s", tr.n, noise_scale(tr.speed),
                          effective_fraction(tr.speed)))
        self._data = {"t": t, "speed": y, "mask": mask, "ch": np.asarray(ch)}
        if COLOURED in session.nuisances:
            first = np.zeros(mask.shape, bool)
            for k, tr in enumerate(traces):
                first[k, :tr.n] = breaks(tr.time)
            self._data["prev"] = previous_index(mask.reshape(-1), first.reshape(-1),
                                                np.arange(mask.size), mask.shape)

    @staticmethod
    def previous(d) -> list:
        return [d.get("prev")]

    @staticmethod
    def observed(d) -> list:
        return [d["speed"]]

    def residuals(self, model, theta, d, fast: bool = False) -> list:
        p, v = model.params(theta), model.registry.values(theta)
        w0 = jnp.stack([v[n] for n in self.names])[:, None]
        tc = p.Tc if model.coulomb else 0.0
        lag = model.lags(theta)[1]
        if lag is None:
            w = motor.coast_down(p.B, p.J, w0, d["t"], tc)
        else:
            w = coast_down_reading(p.B, p.J, w0, d["t"], tc, pole(lag))
        return [d["speed"] - model.read_by(theta, "speed", w)]


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
