"""One objective for a whole session: every trace, steady point and bench measurement.

Parameters live in unconstrained log space, ``θ = log(Ra, La, K, B, J[, Tc])``; the
transform is :func:`SessionModel.params`.  Each *channel* (a trace's speed, a trace's
current, the steady speeds, the steady currents, the step readings) has its own unknown
noise level σ_c with a conjugate inverse-gamma prior of ``NU0`` pseudo-observations at
a scale ``s0_c`` estimated from the data (model-free, from sample-to-sample
differences for traces; 1 % of the typical reading for steady points).  σ_c is
integrated out analytically, so a channel contributes
``−(n_c + NU0)/2 · log(NU0·s0_c² + SS_c(θ))`` to the log-posterior, where SS_c is its
sum of squared residuals.  Bench Ra and La enter as Gaussian priors with their stated
uncertainty; K, B, J and Tc have log-normal priors centred on the closed-form seed,
a factor ``PRIOR_FACTOR`` wide (one standard deviation), which do not bind.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import x64
from ..io.session import Session
from ..paper.closed_form import ClosedForm
from ..physics import motor
from ..physics.experiment import steady_points
from ..physics.solution import Params, experiment_from_traces, real_modes, simulate, simulate_padded
from . import cache as _cache
from .noise import Channel, noise_scale, typical_level
from .params import PRIOR_FACTOR, Registry, dead_time_name, motor_registry, nuisance_specs
from .seed import drop_seed, motor_seed

__all__ = ["SessionModel", "build_model", "NU0", "PRIOR_FACTOR", "noise_scale"]

NU0 = 2.0
STEADY_RELATIVE_NOISE = 0.01
BATCH_CHUNK = 4  # parameter vectors evaluated together inside a batch (see benchmarks/)


class SessionModel:
    """Predictions, residuals and log-posterior of a session as functions of θ.

    Build with :func:`build_model`.  All methods are pure JAX functions of θ (shape
    ``(P,)``) and can be jit-compiled and ``vmap``-ped; ``log_posterior_batch`` chooses
    the fast real-eigenvalue path for a whole batch when it applies.
    """

    def __init__(self, session: Session, seed: ClosedForm, *, coulomb: bool):
        self.session = session
        self.coulomb = coulomb
        self.seed = seed
        self._steady = steady_points(session)
        motor_specs = motor_registry(session, motor_seed(seed, session, self._steady),
                                     coulomb=coulomb).specs
        self.registry = Registry(motor_specs + tuple(nuisance_specs(session,
                                                                    drop_seed(session))))
        self.names = self.registry.names
        self.channels: list[Channel] = []
        self.exp = experiment_from_traces(session.traces) if session.traces else None
        speed_ch, current_ch = [], []
        speeds, currents = [], []
        for tr in session.traces:
            speed_ch.append(self._add(f"{tr.name}: speed", "rad/s", tr.n, noise_scale(tr.speed)))
            speeds.append(tr.speed)
            if tr.current is not None:
                current_ch.append(self._add(f"{tr.name}: current", "A", tr.n,
                                            noise_scale(tr.current)))
                currents.append(tr.current)
            else:
                current_ch.append(-1)
                currents.append(np.zeros(tr.n))
        if self.exp is not None:
            ct = np.asarray(self.exp.chunk_trace)
            self._speed = self.exp.pad(np.concatenate(speeds))
            self._current = self.exp.pad(np.concatenate(currents))
            self._speed_ch = np.asarray(speed_ch)[ct]
            cur = np.asarray(current_ch)[ct]
            self._current_mask = np.asarray(self.exp.mask) & (cur >= 0)[:, None]
            self._current_ch = np.where(cur >= 0, cur, 0)
        st = self._steady
        self._steady_w = self._add("steady: speed", "rad/s", st["w_mask"].sum(),
                                   STEADY_RELATIVE_NOISE * typical_level(st["w"], st["w_mask"]))
        self._steady_i = self._add("steady: current", "A", st["i_mask"].sum(),
                                   STEADY_RELATIVE_NOISE * typical_level(st["i"], st["i_mask"]))
        sr = session.step_readings
        self._tau_obs = jnp.asarray([s.tau for s in sr])
        tau_level = float(np.mean([s.tau for s in sr])) if sr else 1.0
        self._tau_ch = self._add("step readings: tau", "s", len(sr),
                                 STEADY_RELATIVE_NOISE * tau_level)
        self.n_obs = np.array([c.n for c in self.channels], dtype=float)
        self.s0 = np.array([c.s0 for c in self.channels], dtype=float)
        self.prior_sd = self.registry.prior_width_log()
        self.data = self._collect_data()

    # -- construction helpers ---------------------------------------------------------
    def _collect_data(self) -> dict:
        """Every array the objective reads, as one pytree: pass it as an argument to a
        compiled function so that sessions of the same shapes share the compilation."""
        st = self._steady
        d = {"steady_v": st["v"], "steady_tl": st["tl"], "steady_w": st["w"],
             "steady_i": st["i"], "steady_w_mask": st["w_mask"], "steady_i_mask": st["i_mask"],
             "tau_obs": self._tau_obs, "n_obs": self.n_obs, "s0": self.s0}
        d["prior_centre"], d["prior_scale"] = self.registry.prior_arrays()
        if self.exp is not None:
            d.update(exp=self.exp, speed=self._speed, current=self._current,
                     current_mask=self._current_mask, speed_ch=self._speed_ch,
                     current_ch=self._current_ch)
        return jax.tree_util.tree_map(jnp.asarray, d)

    def _add(self, name, unit, n, s0) -> int:
        self.channels.append(Channel(name, unit, int(n), float(s0)))
        return len(self.channels) - 1

    def structure_key(self) -> tuple:
        """Everything compiled code depends on besides ``data``'s values: sessions with
        the same key share compiled functions."""
        leaves, treedef = jax.tree_util.tree_flatten(self.data)
        return (self.coulomb, self.registry.structure(), len(self.channels), self.exp is None,
                treedef,
                tuple((x.shape, str(x.dtype)) for x in leaves))

    def compiled(self, name: str, build):
        """A compiled function of ``(..., data)``, built once per ``name`` and structure.

        ``build()`` must return a ``jax.jit``-ed function that reads the session only
        through its ``data`` argument (the methods of this class do).
        """
        return _cache.compiled((name,) + self.structure_key(), build)

    # -- parameters ----------------------------------------------------------------------
    def params(self, theta) -> Params:
        """The motor parameters (SI) at θ, through the registry's transforms."""
        v = self.registry.values(theta)
        return Params(v["Ra"], v["La"], v["K"], v["B"], v["J"], v.get("Tc", 0.0))

    def theta(self, values: dict) -> jax.Array:
        """θ of ``values`` (SI); a missing untransformed parameter (a nuisance) sits at its
        prior's centre, a missing or zero positive one (Tc of a viscous set) at 1e-300."""
        full = {s.name: (float(values.get(s.name, s.prior.centre)) if s.transform == "identity"
                         else max(float(values.get(s.name) or 0.0), 1e-300))
                for s in self.registry.specs}
        return jnp.asarray(self.registry.to_theta(full))

    def theta_seed(self) -> jax.Array:
        return jnp.asarray(self.registry.seed_theta())

    def drop(self, theta):
        """The fitted voltage drop at θ (V), 0 when the model has none."""
        return self.registry.values(theta)["Vdrop"] if "Vdrop" in self.registry else 0.0

    def inputs(self, theta, exp):
        """The experiment as the motor sees it at θ: voltages less the fitted drop, and
        each trace's samples taken its fitted dead time earlier (before the response
        starts, the state at the segment's start: exact when the preceding segment is at
        rest or steady)."""
        if "Vdrop" in self.registry:
            exp = exp._replace(seg_va=motor.terminal_voltage(exp.seg_va, self.drop(theta)))
        if "dead_time" in self.session.nuisances:
            v = self.registry.values(theta)
            delay = jnp.stack([v[dead_time_name(tr.name)] for tr in self.session.traces])
            exp = exp._replace(tau=jnp.maximum(exp.tau - delay[exp.chunk_trace][:, None], 0.0))
        return exp

    # -- predictions --------------------------------------------------------------------
    def steady_prediction(self, p: Params, v, tl, drop=0.0):
        """Steady ``(ω, ia)`` at voltages ``v`` and loads ``tl`` (equations (15)–(18)),
        with ``drop`` volts lost at the brushes and driver."""
        i, w = motor.steady_state(p.Ra, p.K, p.B, motor.terminal_voltage(v, drop), tl,
                                  p.Tc if self.coulomb else None)
        return w, i

    def tau_prediction(self, p: Params):
        """First-order time constant (9): what a 63.2 % reading measures when La/Ra ≪ τ."""
        return motor.time_constant(p.Ra, p.K, p.B, p.J)

    def _d(self, data):
        return self.data if data is None else data

    def _steady_and_tau_residuals(self, p: Params, *, data=None, drop=0.0):
        d = self._d(data)
        w, i = self.steady_prediction(p, d["steady_v"], d["steady_tl"], drop)
        return [(d["steady_w"] - w, d["steady_w_mask"]), (d["steady_i"] - i, d["steady_i_mask"]),
                (d["tau_obs"] - self.tau_prediction(p), jnp.ones(d["tau_obs"].shape, bool))]

    def trace_residuals(self, theta, *, fast: bool = False, data=None):
        """Padded speed and current residuals (observed − model) of all traces."""
        d = self._d(data)
        ia, w = simulate_padded(self.params(theta), self.inputs(theta, d["exp"]),
                                coulomb=self.coulomb, fast=fast)
        return d["speed"] - w, d["current"] - ia

    def channel_residuals(self, theta, *, fast: bool = False, data=None):
        """Residuals per channel (observed − model) with their masks, in channel order."""
        d = self._d(data)
        out = []
        if self.exp is not None:
            rw, ri = self.trace_residuals(theta, fast=fast, data=d)
            mask = np.asarray(self.exp.mask)
            for c in range(len(self.channels) - 3):
                m_w = mask & (self._speed_ch == c)[:, None]
                m_i = self._current_mask & (self._current_ch == c)[:, None]
                out.append((rw, m_w) if m_w.any() else (ri, m_i))
        return out + self._steady_and_tau_residuals(self.params(theta), data=d,
                                                       drop=self.drop(theta))

    def sums_of_squares(self, theta, *, fast: bool = False, data=None):
        """Sum of squared residuals per channel."""
        d = self._d(data)
        n_ch = len(self.channels)
        if self.exp is not None:
            rw, ri = self.trace_residuals(theta, fast=fast, data=d)
            row_w = jnp.sum(jnp.where(d["exp"].mask, rw * rw, 0.0), axis=1)
            row_i = jnp.sum(jnp.where(d["current_mask"], ri * ri, 0.0), axis=1)
            ss = (jax.ops.segment_sum(row_w, d["speed_ch"], num_segments=n_ch)
                  + jax.ops.segment_sum(row_i, d["current_ch"], num_segments=n_ch))
        else:
            ss = jnp.zeros(n_ch)
        tail = [jnp.sum(jnp.where(m, r, 0.0) ** 2)
                for r, m in self._steady_and_tau_residuals(self.params(theta), data=d,
                                                       drop=self.drop(theta))]
        return ss.at[n_ch - 3:].add(jnp.stack(tail))

    def log_prior(self, theta, *, data=None):
        """The registry's priors (bench Gaussians in value, log-normal elsewhere)."""
        d = self._d(data)
        return self.registry.log_prior(theta, d["prior_centre"], d["prior_scale"])

    def log_likelihood(self, theta, *, fast: bool = False, data=None):
        """Σ_c −(n_c + ν0)/2 · log(ν0·s0_c² + SS_c): Gaussian noise, σ_c integrated out."""
        d = self._d(data)
        ss = self.sums_of_squares(theta, fast=fast, data=d)
        n, s0 = d["n_obs"], d["s0"]
        return jnp.sum(jnp.where(n > 0, -0.5 * (n + NU0) * jnp.log(NU0 * s0**2 + ss), 0.0))

    def log_posterior(self, theta, *, fast: bool = False, data=None):
        """Log-posterior (up to a constant); −inf wherever the model is not finite."""
        lp = self.log_prior(theta, data=data) + self.log_likelihood(theta, fast=fast, data=data)
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    def log_posterior_batch(self, thetas, *, data=None):
        """Log-posterior of a batch ``(W, P)``; the fast path when every member allows it.

        The batch is evaluated ``BATCH_CHUNK`` vectors at a time (``lax.map``): measured
        on 3 × 10,000 samples, 4 at a time gives ~6,000 vectors/s whatever the batch
        size, where vectorising all 64 at once gives under 1,000.
        """
        ok = jnp.all(jax.vmap(lambda t: real_modes(self.params(t)))(thetas))

        def over(fast):
            # Sub-batches of a few vectors keep each pass over the samples in cache; a
            # whole batch at once is several times slower per vector on large sessions.
            return lambda th: jax.lax.map(
                lambda t: self.log_posterior(t, fast=fast, data=data), th,
                batch_size=BATCH_CHUNK)

        return jax.lax.cond(ok, over(True), over(False), thetas)

    def weights(self, theta, *, data=None):
        """Per-channel weights 1/σ_c² at θ: the posterior mode of σ_c² given SS_c."""
        d = self._d(data)
        ss = self.sums_of_squares(theta, data=d)
        return (d["n_obs"] + NU0) / (NU0 * d["s0"] ** 2 + ss)

    def weighted_residuals(self, theta, weights, *, fast: bool = False, data=None):
        """Residual vector whose half squared norm is the negative log-posterior at fixed
        weights (for Levenberg–Marquardt)."""
        d = self._d(data)
        sw = jnp.sqrt(weights)
        parts = []
        if self.exp is not None:
            rw, ri = self.trace_residuals(theta, fast=fast, data=d)
            parts.append((jnp.where(d["exp"].mask, rw, 0.0) * sw[d["speed_ch"]][:, None])
                         .reshape(-1))
            parts.append((jnp.where(d["current_mask"], ri, 0.0)
                          * sw[d["current_ch"]][:, None]).reshape(-1))
        n_ch = len(self.channels)
        for k, (r, m) in enumerate(self._steady_and_tau_residuals(self.params(theta), data=d,
                                                       drop=self.drop(theta))):
            parts.append(jnp.where(m, r, 0.0) * sw[n_ch - 3 + k])
        prior = self.registry.prior_residuals(theta, d["prior_centre"], d["prior_scale"])
        return jnp.concatenate(parts + [prior])

    @x64
    def predict(self, theta, *, coulomb: bool | None = None):
        """Per trace ``(ia, ω)`` in time order (A, rad/s), as NumPy arrays."""
        if self.exp is None:
            return []
        c = self.coulomb if coulomb is None else coulomb
        fn = self.compiled(f"predict-coulomb={c}", lambda: jax.jit(
            lambda t, d: simulate(self.params(t), self.inputs(t, d["exp"]), coulomb=c)))
        ia, w = fn(jnp.asarray(theta), self.data)
        return list(zip(self.exp.split(ia), self.exp.split(w)))

    def padded_log_density(self, theta, *, data=None) -> list:
        """Gaussian log-density of every observation, padded, at its channel's noise level
        ``σ_c² = (ν0·s0_c² + SS_c)/(n_c + ν0)`` (for LOO): the traces' speed and current in
        the ``(C, L)`` layout, then the steady speeds, steady currents and τ readings.
        :meth:`observation_selection` picks each channel's observations out of it."""
        d = self._d(data)
        ss = self.sums_of_squares(theta, data=d)
        var = (NU0 * d["s0"] ** 2 + ss) / (d["n_obs"] + NU0)

        def dens(r, v):
            return -0.5 * (jnp.log(2 * jnp.pi * v) + r * r / v)

        out = []
        if self.exp is not None:
            rw, ri = self.trace_residuals(theta, data=d)
            out += [dens(rw, var[d["speed_ch"]][:, None]),
                    dens(ri, var[d["current_ch"]][:, None])]
        n_ch = len(self.channels)
        for k, (r, _) in enumerate(self._steady_and_tau_residuals(self.params(theta), data=d,
                                                       drop=self.drop(theta))):
            # lax.map cannot batch an empty output: an empty channel gets a dummy entry
            # that its (empty) selection never reads.
            out.append(dens(r if r.shape[0] else jnp.zeros(1), var[n_ch - 3 + k]))
        return out

    def observation_selection(self) -> list:
        """Per channel, in channel order: (which output of :meth:`padded_log_density`,
        flat indices of its observations)."""
        n_ch = len(self.channels)
        sel = []
        if self.exp is not None:
            mask = np.asarray(self.exp.mask)
            for c in range(n_ch - 3):
                m_w = (mask & (self._speed_ch == c)[:, None]).reshape(-1)
                m_i = (self._current_mask & (self._current_ch == c)[:, None]).reshape(-1)
                sel.append((0, np.nonzero(m_w)[0]) if m_w.any() else (1, np.nonzero(m_i)[0]))
        base = 2 if self.exp is not None else 0
        st = self._steady
        sel.append((base, np.nonzero(st["w_mask"])[0]))
        sel.append((base + 1, np.nonzero(st["i_mask"])[0]))
        sel.append((base + 2, np.arange(len(self.session.step_readings))))
        return sel

    def pointwise_log_likelihood(self, theta, *, data=None) -> list:
        """Per channel, the log-density of each of its observations (see
        :meth:`padded_log_density`)."""
        outs = self.padded_log_density(theta, data=data)
        return [jnp.asarray(outs[k]).reshape(-1)[idx] for k, idx in self.observation_selection()]


@x64
def build_model(session: Session, seed: ClosedForm, *, coulomb: bool | None = None) -> SessionModel:
    """The objective of a session; ``coulomb`` defaults to the session's friction model."""
    if coulomb is None:
        coulomb = session.friction == "coulomb"
    return SessionModel(session, seed, coulomb=coulomb)
