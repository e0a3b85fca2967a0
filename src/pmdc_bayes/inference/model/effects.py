"""The rig's non-idealities in the prediction: the experiment as the motor sees it
(:meth:`RigEffects.inputs`: dead times, a driver's dead zone (:meth:`RigEffects.driven`),
unknown drags), the circuit the logged voltage
drives (:meth:`RigEffects.circuit`: a source resistance; :meth:`RigEffects.armature_drop`:
the voltage drop, which opposes the current), the driver's limit, the sensors'
lags (:meth:`RigEffects.lags`, states of the exact solution) and their gains and offsets
(:meth:`RigEffects.read_by`)."""

from __future__ import annotations

import jax.numpy as jnp

from ...physics.motor import driver_output
from .column_levels import INPUTS, level_names
from .nuisances import DEAD_ZONE_NAMES, NO_LIMIT, dead_time_name, load_names
from .switch_lead import session_lead_names

__all__ = ["RigEffects"]


class RigEffects:
    """The rig's non-idealities in the prediction, for a model with ``registry`` and
    ``session``."""

    def circuit(self, theta):
        """The motor's parameters as the logged voltage drives them: Ra plus the fitted
        source resistance ``Rs`` when the model has one."""
        p = self.params(theta)
        if "Rs" in self.registry:
            p = p._replace(Ra=p.Ra + self.registry.values(theta)["Rs"])
        return p

    def limit(self, theta):
        """The fitted current limit at θ (A); :data:`NO_LIMIT` when the model has none
        but needs the regime-switching solution (Coulomb friction through a voltage
        reversal, a voltage drop), else None."""
        if "Imax" in self.registry:
            return self.registry.values(theta)["Imax"]
        return NO_LIMIT if self.reverses or self.switches_drop else None

    @property
    def switches_drop(self) -> bool:
        """Whether a drop opposes the current: a fitted one, or a driver's open armature
        at a zero command (``open_at_zero``)."""
        return "Vdrop" in self.registry or "open_at_zero" in self.session.nuisances

    def drop(self, theta):
        """The fitted voltage drop at θ (V), 0 when the model has none."""
        return self.registry.values(theta)["Vdrop"] if "Vdrop" in self.registry else 0.0

    def armature_drop(self, theta, d):
        """The drops the exact solution opposes to the current at θ (``simulate_padded``'s
        ``drop`` and ``open_volts``): the fitted voltage drop (V), None when the model has
        none; and at a zero command the freewheel voltage of a driver that opens the
        armature there (``d["open_volts"]``, :func:`.nuisances.open_data`), else None."""
        drop = self.registry.values(theta)["Vdrop"] if "Vdrop" in self.registry else None
        return {"drop": drop, "open_volts": d.get("open_volts")}

    def steady_at(self, theta, va, tl):
        """Steady ``(ia, ω)`` at θ for the commanded voltages ``va`` and loads ``tl``: the
        circuit the logged voltage drives, through the driver and its drop."""
        return self.steady_prediction(self.circuit(theta), self.driven(theta, va), tl,
                                      self.drop(theta))

    def driven(self, theta, va):
        """The voltage the driver puts out at θ for the commands ``va`` (V): through its
        fitted dead zone when the model has one, else ``va``."""
        if "dead_zone" not in self.session.nuisances:
            return va
        v = self.registry.values(theta)
        fwd, rev = (v.get(DEAD_ZONE_NAMES[sign][0], 0.0) for sign in (1, -1))
        return driver_output(va, fwd, rev)

    def held(self, theta, exp, d):
        """The experiment with each segment a noisy input column's fitted level drives at
        that level's value at θ (:mod:`.column_levels`; ``d["level_<input>"]`` each
        segment's level, −1 for none)."""
        v = self.registry.values(theta)
        for what, spec in INPUTS.items():
            index = d.get(f"level_{what}")
            if index is not None:
                exp = exp._replace(**{spec.segments: _per_segment(
                    v, level_names(self.session, what), index, getattr(exp, spec.segments))})
        return exp

    def inputs(self, theta, exp, d=None):
        """The experiment as the motor sees it at θ: each
        trace's response its fitted dead time later than its inputs (each sample
        evaluated in the segment its time less the dead time lies in: exact;
        before the trace's first segment, its starting state), each change of a logged
        column its fitted lead before the sample that shows it (``d["lead_index"]``, each
        segment's lead: :mod:`.switch_lead`), and each trace's fitted
        unknown drag per segment, added to its known one (set in the experiment); each
        segment's voltage as the driver puts it out (:meth:`driven`)."""
        if "dead_zone" in self.session.nuisances:
            exp = exp._replace(seg_va=self.driven(theta, exp.seg_va))
        v, zero = self.registry.values(theta), jnp.zeros(())
        index = None if d is None else d.get("lead_index")
        shift = None
        if index is not None:
            shift = _per_segment(v, session_lead_names(self.session), index, 0.0)
        if "dead_time" in self.session.nuisances or shift is not None:
            # a trace's own dead time, one shared by every trace, or (in a superset
            # model, :mod:`.superset`) the sum of both forms
            exp = exp.delayed(jnp.stack([v.get(dead_time_name(tr.name), zero)
                                         + v.get(dead_time_name(tr.name, True), zero)
                                         for tr in self.session.traces]), shift)
        loaded = self.session.unknown_load_traces()
        if loaded:
            parts = [[v[n] if tr.name in loaded and n in v else zero
                      for n in load_names(tr.name)] for tr in self.session.traces]
            tc, b = (jnp.stack([jnp.asarray(q[k]) for q in parts]) for k in (0, 1))
            known = exp.seg_b is not None
            exp = exp._replace(seg_b=b[exp.seg_trace] + (exp.seg_b if known else 0.0),
                               seg_tc=tc[exp.seg_trace] + (exp.seg_tc if known else 0.0))
        return exp

    def lags(self, theta):
        """The fitted time constants (s) of the current and speed sensors' lags at θ,
        None for a sensor the model reads without one (``simulate_padded(lags=)``)."""
        v = self.registry.values(theta)
        return tuple(v.get(f"{sensor}_lag") for sensor in ("current", "speed"))

    def read_by(self, theta, sensor: str, x):
        """``x``, the ``sensor``'s (``"speed"`` or ``"current"``) lagged reading, as the
        sensor reports it at θ: times its declared gain, plus its declared offset."""
        v = self.registry.values(theta)
        if f"{sensor}_gain" in self.registry:
            x = v[f"{sensor}_gain"] * x
        if f"{sensor}_offset" in self.registry:
            x = x + v[f"{sensor}_offset"]
        return x

    def sensed(self, theta, ia, w):
        """What the sensors report of their lagged readings ``(ia, ω)``."""
        return self.read_by(theta, "current", ia), self.read_by(theta, "speed", w)


def _per_segment(values, names, index, otherwise):
    """Each segment's value of the parameter ``names[index]`` (``values`` by name), or
    ``otherwise`` where its index is −1."""
    table = jnp.stack([values[n] for n in names])
    return jnp.where(index >= 0, table[jnp.maximum(index, 0)], otherwise)
