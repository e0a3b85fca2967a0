"""One objective for a whole session: every trace, steady point and bench measurement.

Parameters live in unconstrained log space, ``θ = log(Ra, La, K, B, J[, Tc])``; the
transform is :func:`SessionModel.params`.  Each *channel* (a trace's speed, a trace's
current, the steady speeds, the steady currents, the step readings) has its own unknown
noise level σ_c with a conjugate inverse-gamma prior of ``NU0`` pseudo-observations at
a scale ``s0_c`` estimated from the data (model-free, from sample-to-sample
differences for traces; 1 % of the typical reading for steady points).  σ_c is
integrated out analytically, so a channel contributes
``−(n_c + NU0)/2 · log(NU0·s0_c² + SS_c(θ))`` to the log-posterior, where SS_c is its
sum of squared residuals.  A quantised channel that its noise does not dither
(:func:`.noise.effective_fraction`) repeats one quantisation error until the signal
has moved on by a quantum, so only a share ``α_c`` of its readings carry independent
errors; its
likelihood counts ``α_c·n_c`` of them, ``−(α_c·n_c + NU0)/2 · log(NU0·s0_c² +
α_c·SS_c)`` (the data pytree holds ``α_c·n_c`` and ``s0_c/√α_c``, equal up to a
constant), while the fitted noise level stays the readings' own.  Bench Ra and La
enter as Gaussian priors with their stated uncertainty; K, B, J and Tc have log-normal
priors centred on the closed-form seed, a factor ``PRIOR_FACTOR`` wide (one standard
deviation), which do not bind.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..._x64 import to_device, x64
from ...io.readings import steady_points
from ...io.session import Session
from ...paper.closed_form import ClosedForm
from ...physics import motor
from ...physics.solution import Params, experiment_from_traces, real_modes
from .._runtime import compiled as cached_program
from .._runtime import release_structure
from .channels import SteadyBlock, blocks_for, entry_weights
from .coloured import PREFIX as AR_PREFIX
from .coloured import coloured_data, noise_rho, start_residuals, whiten
from .effects import RigEffects
from .noise import NU0, Channel, integrated_log_likelihood, noise_scale
from .nuisances import nuisance_specs
from .params import PRIOR_FACTOR, Registry, motor_registry
from .pointwise import Pointwise
from .predictions import Predictions
from .seed import drop_seed, motor_seed
from .trace_states import coast_down_specs, position_specs

__all__ = ["SessionModel", "build_model", "NU0", "PRIOR_FACTOR", "noise_scale"]

BATCH_CHUNK = 4  # parameter vectors evaluated together inside a batch (see benchmarks/)


class SessionModel(RigEffects, Predictions, Pointwise):
    """Predictions, residuals and log-posterior of a session as functions of θ.

    Build with :func:`build_model`.  The likelihood is composed of the blocks of
    :mod:`.channels`; every method below treats their residual arrays alike.  All
    methods are pure JAX functions of θ (shape ``(P,)``) and of the data pytree, and
    can be jit-compiled and ``vmap``-ped; ``log_posterior_batch`` chooses the fast
    real-eigenvalue path for a whole batch when it applies.
    """

    def __init__(self, session: Session, seed: ClosedForm, *, coulomb: bool):
        self.session = session
        self.coulomb = coulomb
        self.seed = seed
        steady = steady_points(session)
        start = motor_seed(seed, session, steady)
        motor_specs = motor_registry(session, start, coulomb=coulomb).specs
        self.registry = Registry(motor_specs
                                 + tuple(nuisance_specs(session, drop_seed(session), start["B"]))
                                 + tuple(coast_down_specs(session))
                                 + tuple(position_specs(session)))
        # a trace's friction-like unknown load needs the stick-slip solution, whatever
        # the motor's own friction model
        self.coulomb_path = (coulomb or bool(session.unknown_load_traces())
                             or any(tr.drag[0] > 0 for tr in session.traces))
        self.names = self.registry.names
        self.channels: list[Channel] = []
        self.exp = experiment_from_traces(session.traces) if session.traces else None
        # friction and a voltage reversed within a trace: a moving rotor stops and is
        # driven back, which takes the regime-switching solution
        self.reverses = bool(self.coulomb_path and self.exp is not None
                             and self.exp.voltage_reverses)
        self.blocks = blocks_for(session, self.exp, self._add)
        self.steady = next(b for b in self.blocks if isinstance(b, SteadyBlock)).points
        self.n_obs = np.array([c.n for c in self.channels], dtype=float)
        self.s0 = np.array([c.s0 for c in self.channels], dtype=float)
        self.prior_sd = self.registry.prior_width_log()
        self.coloured = any(s.name.startswith(AR_PREFIX) for s in self.registry.specs)
        self.data = self._collect_data()

    # -- construction helpers ---------------------------------------------------------
    def _collect_data(self) -> dict:
        """Every array the objective reads, as one pytree: pass it as an argument to a
        compiled function so that sessions of the same shapes share the compilation."""
        d = {b.key: b.data() for b in self.blocks}
        alpha = np.array([c.alpha for c in self.channels], dtype=float)
        d.update(n_obs=alpha * self.n_obs, s0=self.s0 / np.sqrt(alpha))
        d["prior_centre"], d["prior_scale"] = self.registry.prior_arrays()
        d["off"] = np.zeros(len(self.registry), bool)
        d["neutral"] = np.zeros(len(self.registry))
        if self.coloured:
            d["noise_ar"] = coloured_data(self)
        return jax.tree_util.tree_map(to_device, d)

    def _add(self, cid, unit, n, s0, alpha=1.0) -> int:
        self.channels.append(Channel(cid, unit, int(n), float(s0), float(alpha)))
        return len(self.channels) - 1

    def structure_key(self) -> tuple:
        """Everything compiled code depends on besides ``data``'s values: sessions with
        the same key share compiled functions."""
        leaves, treedef = jax.tree_util.tree_flatten(self.data)
        return (self.coulomb, self.coulomb_path, self.reverses, self.registry.structure(),
                len(self.channels),
                tuple(b.key for b in self.blocks), treedef,
                tuple((x.shape, str(x.dtype)) for x in leaves))

    def compiled(self, name: str, build):
        """A compiled function of ``(..., data)``, built once per ``name`` and structure.

        ``build()`` must return a ``jax.jit``-ed function that reads the session only
        through its ``data`` argument (the methods of this class do).
        """
        return cached_program((name,) + self.structure_key(), build)

    def release(self) -> None:
        """Let go of the compiled programs of this model's structure (made again if asked)."""
        release_structure(self.structure_key())

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
        return to_device(self.registry.to_theta(full))

    def theta_seed(self) -> jax.Array:
        return to_device(self.registry.seed_theta())

    # -- predictions and residuals -------------------------------------------------------
    def steady_prediction(self, p: Params, v, tl, drop=0.0):
        """Steady ``(ia, ω)`` at voltages ``v`` and loads ``tl`` (equations (15)–(18)),
        with ``drop`` volts lost at the brushes and driver."""
        return motor.steady_with_drop(p.Ra, p.K, p.B, v, tl, p.Tc if self.coulomb else None,
                                      drop)

    def tau_prediction(self, p: Params):
        """First-order time constant (9): what a 63.2 % reading measures when La/Ra ≪ τ."""
        return motor.time_constant(p.Ra, p.K, p.B, p.J)

    def _d(self, data):
        return self.data if data is None else data

    @staticmethod
    def switched(theta, d):
        """θ as the prediction reads it: each parameter ``d["off"]`` switches off at its
        neutral θ ``d["neutral"]`` (:mod:`.superset`; none for a model of its own)."""
        return jnp.where(d["off"], d["neutral"], theta)

    def _parts(self, theta, d, fast: bool = False, whitened: bool = True) -> list:
        """Every residual array of every block with its mask and channels:
        ``[(r, mask, ch), ...]`` in block order; a channel whose noise is coloured gives
        its innovations (:mod:`.coloured`) unless not ``whitened``."""
        theta = self.switched(theta, d)
        rho = self.noise_rho(theta, d) if self.coloured else None
        out = []
        for b in self.blocks:
            bd = d[b.key]
            for r, (m, c), prev in zip(b.residuals(self, theta, bd, fast), b.layout(bd),
                                       b.previous(bd), strict=True):
                if rho is not None and whitened and prev is not None:
                    r = whiten(r, prev, entry_weights(rho, c, r))
                out.append((r, m, c))
        return out

    def noise_rho(self, theta, d=None):
        """Per channel the lag-1 correlation of its noise (0: white; :mod:`.coloured`)."""
        d = self._d(d)
        return noise_rho(theta, d["noise_ar"]) if self.coloured else jnp.zeros(len(self.channels))

    def channel_residuals(self, theta, *, fast: bool = False, data=None):
        """Residuals per channel (observed − model) with their masks, in channel order."""
        parts = self._parts(theta, self._d(data), fast)
        out = []
        for c in range(len(self.channels)):
            for r, m, ch in parts:
                sel = np.asarray(m) & np.asarray(entry_weights(np.asarray(ch) == c, ch, r))
                if sel.any():
                    out.append((r, sel))
                    break
            else:
                out.append((jnp.zeros(0), np.zeros(0, bool)))
        return out

    def sums_of_squares(self, theta, *, fast: bool = False, data=None):
        """Sum of squared residuals per channel."""
        return self._sums(self._parts(theta, self._d(data), fast))

    def _sums(self, parts):
        n_ch = len(self.channels)
        ss = jnp.zeros(n_ch)
        for r, m, ch in parts:
            sq = jnp.where(m, r * r, 0.0)
            sq = sq.reshape(sq.shape[0], -1).sum(axis=1) if sq.ndim > 1 else sq
            ss = ss + jax.ops.segment_sum(sq, ch, num_segments=n_ch)
        return ss

    def prior_residuals(self, theta, *, data=None):
        """The registry's standardised prior residuals; a parameter switched off has a
        standard Gaussian in θ about ``prior_centre`` instead, which leaves its value
        nowhere in the prediction and adds nothing to the evidence.  With coloured noise,
        one more per channel: its whitening's Jacobian (:func:`.coloured.start_residuals`),
        a term of the likelihood that depends on θ alone."""
        d = self._d(data)
        theta = jnp.asarray(theta)
        r = self.registry.prior_residuals(theta, d["prior_centre"], d["prior_scale"])
        r = jnp.where(d["off"], theta - d["prior_centre"], r)
        if not self.coloured:
            return r
        rho = self.noise_rho(self.switched(theta, d), d)
        return jnp.concatenate([r, start_residuals(rho, d["noise_ar"]["starts"])])

    def log_prior(self, theta, *, data=None):
        """The registry's priors (bench Gaussians in value, log-normal elsewhere)."""
        d = self._d(data)
        r = self.prior_residuals(theta, data=d)
        on = jnp.where(d["off"], 0.0, jnp.asarray(theta))
        return -0.5 * jnp.sum(r * r) + self.registry.log_jacobian(on)

    def log_likelihood(self, theta, *, fast: bool = False, data=None):
        """Σ_c −(n_c + ν0)/2 · log(ν0·s0_c² + SS_c): Gaussian noise, σ_c integrated out."""
        d = self._d(data)
        ss = self.sums_of_squares(theta, fast=fast, data=d)
        return jnp.sum(integrated_log_likelihood(ss, d["n_obs"], d["s0"]))

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
        d = self._d(data)
        exp = d["traces"]["exp"] if "traces" in d else None
        known = (jnp.zeros(1) if exp is None or exp.seg_b is None
                 else jnp.concatenate([jnp.zeros(1), exp.seg_b]))

        def real(t):  # with each segment's known viscous drag too: it moves the modes
            p = self.circuit(self.switched(t, d))
            return jnp.all(real_modes(p._replace(B=p.B + known)))

        ok = jnp.all(jax.vmap(real)(thetas))
        if self.session.unknown_load_traces() or any(tr.drag.curved
                                                     for tr in self.session.traces):
            ok = jnp.asarray(False)  # a fitted or curved drag moves them anywhere

        def over(fast):
            # Sub-batches of a few vectors keep each pass over the samples in cache; a
            # whole batch at once is several times slower per vector on large sessions.
            return lambda th: jax.lax.map(
                lambda t: self.log_posterior(t, fast=fast, data=data), th,
                batch_size=BATCH_CHUNK)

        return jax.lax.cond(ok, over(True), over(False), thetas)

    def weighted_residuals(self, theta, weights, *, fast: bool = False, data=None):
        """Residual vector whose half squared norm is the negative log-posterior at fixed
        weights (for Levenberg–Marquardt)."""
        d = self._d(data)
        sw = jnp.sqrt(weights)
        parts = [(jnp.where(m, r, 0.0) * entry_weights(sw, ch, r)).reshape(-1)
                 for r, m, ch in self._parts(theta, d, fast)]
        return jnp.concatenate(parts + [self.prior_residuals(theta, data=d)])


@x64
def build_model(session: Session, seed: ClosedForm, *, coulomb: bool | None = None) -> SessionModel:
    """The objective of a session; ``coulomb`` defaults to the session's friction model."""
    if coulomb is None:
        coulomb = session.friction == "coulomb"
    return SessionModel(session, seed, coulomb=coulomb)
