"""The parameter registry: every fitted quantity, described once.

A model's parameters are a :class:`Registry` of :class:`ParamSpec` records, each with
its name, SI unit, block (``motor``, ``friction``, ``trace``, ``sensor``, ``driver``),
transform to the unconstrained space the optimiser and sampler work in, prior and
seed.  Everything that needs the parameter list (the objective, the fit's starts,
identifiability, the posterior's record, ``summary.json`` and the report) reads it
from here, so adding a parameter is one entry (here for the motor, in
:mod:`.nuisances` for the rig) and its use in the prediction.

Priors
------
``normal``: Gaussian in the parameter's value, centre and sd in SI (a bench
measurement).  ``lognormal``: Gaussian in the log of the value, centre in SI and sd
in natural-log units.  For a log-transformed parameter with a ``normal`` prior the
log-Jacobian of θ = log(value) is added, so the density is the stated one in value.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np
from scipy.stats import norm

from ..._x64 import to_device
from ...io.session import LA_ASSUMED, Session

__all__ = ["Prior", "ParamSpec", "Registry", "motor_registry", "identifier",
           "PRIOR_FACTOR", "BLOCKS"]

PRIOR_FACTOR = 10.0  # one-sd width of the log-normal priors on K, B, J, Tc (a factor)
BLOCKS = ("motor", "friction", "trace", "sensor", "driver")
PRIOR_KINDS = ("normal", "lognormal", "half_normal")
# a half-normal's Laplace width in θ = log(value): its log-density in θ, θ − e^{2θ}/(2s²),
# has curvature 2 at its mode whatever its scale s; the width a posterior's Laplace sd is
# compared with, when the data say nothing more
HALF_NORMAL_LAPLACE_SD = float(1.0 / np.sqrt(2.0))
TRANSFORMS = ("log", "identity")


@dataclass(frozen=True)
class Prior:
    """A prior: ``kind``, ``centre`` (SI), ``scale`` and where it comes from.

    - ``normal``: Gaussian in value, ``scale`` its SI sd (of a positive, log-fitted
      quantity: renormalised over the positive values);
    - ``lognormal``: Gaussian in the natural log, ``scale`` that log's sd;
    - ``half_normal``: a positive quantity that may be as good as none (a voltage drop):
      the positive half of a Gaussian in value centred on zero (``centre`` 0), ``scale``
      its SI sd; fitted in log."""

    kind: str
    centre: float
    scale: float
    source: str = ""

    def __post_init__(self):
        if self.kind not in PRIOR_KINDS:
            raise ValueError(f"prior kind {self.kind!r}; use one of {PRIOR_KINDS}")
        if not (np.isfinite(self.centre) and np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"prior centre {self.centre!r} and scale {self.scale!r} must be "
                             "finite, the scale positive")
        if self.kind == "half_normal" and self.centre != 0:
            raise ValueError(f"a half-normal prior is centred on 0, not {self.centre!r}")

    @property
    def in_value(self) -> bool:
        """Whether the prior is Gaussian in the value (not in its logarithm)."""
        return self.kind != "lognormal"

    @property
    def typical(self) -> float:
        """A typical value under the prior (SI): its centre, or a half-normal's scale."""
        return self.scale if self.kind == "half_normal" else self.centre

    def width_in_log(self) -> float:
        """The prior's sd in log space: linearised for a Gaussian in value, and for a
        half-normal its Laplace width at its mode in log."""
        if self.kind == "lognormal":
            return self.scale
        if self.kind == "half_normal":
            return HALF_NORMAL_LAPLACE_SD
        return self.scale / abs(self.centre)

    def log_positive_mass(self) -> float:
        """``log P(value > 0)`` under the prior: the normaliser a positive (log-fitted)
        quantity's prior takes, since the fit's log-density integrates to this over θ
        (log 1/2 for a half-normal; about zero for a bench value many sd above zero)."""
        if self.kind == "lognormal":
            return 0.0
        return float(norm.logcdf(self.centre / self.scale))


@dataclass(frozen=True)
class ParamSpec:
    """One fitted parameter.

    Attributes
    ----------
    name : unique name, e.g. ``"Ra"`` or ``"delay[step_12v]"``.
    unit : SI unit as written in ``summary.json`` (``"ohm"``, ``"N*m"``, ...).
    block : which part of the rig it belongs to (:data:`BLOCKS`).
    prior : its :class:`Prior`.
    seed : where the fit starts (SI).
    transform : ``"log"`` (positive quantities) or ``"identity"``.
    description : a few words for people.
    trace : the trace a per-trace parameter belongs to.
    """

    name: str
    unit: str
    block: str
    prior: Prior
    seed: float
    transform: str = "log"
    description: str = ""
    trace: str | None = None

    def __post_init__(self):
        if self.block not in BLOCKS:
            raise ValueError(f"parameter {self.name!r}: block {self.block!r}; use one of "
                             f"{BLOCKS}")
        if self.transform not in TRANSFORMS:
            raise ValueError(f"parameter {self.name!r}: transform {self.transform!r}; use one "
                             f"of {TRANSFORMS}")
        if (self.prior.kind == "half_normal") != (self.transform == "log"
                                                  and self.prior.in_value
                                                  and self.prior.centre == 0):
            raise ValueError(f"parameter {self.name!r}: a positive quantity whose prior is "
                             "centred on zero takes a half-normal prior, fitted in log")
        if self.transform == "log" and not self.seed > 0:
            raise ValueError(f"parameter {self.name!r}: a log-transformed parameter needs a "
                             f"positive seed, got {self.seed!r}")


class Registry:
    """An ordered set of :class:`ParamSpec`: the layout of θ and everything about it."""

    def __init__(self, specs):
        self.specs = tuple(specs)
        self.names = tuple(s.name for s in self.specs)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"duplicate parameter names in {self.names}")
        self._index = {n: k for k, n in enumerate(self.names)}

    def __len__(self) -> int:
        return len(self.specs)

    def __contains__(self, name) -> bool:
        return name in self._index

    def __getitem__(self, name: str) -> ParamSpec:
        return self.specs[self._index[name]]

    def index(self, name: str) -> int:
        return self._index[name]

    def units(self) -> dict[str, str]:
        return {s.name: s.unit for s in self.specs}

    def structure(self) -> tuple:
        """What compiled code depends on (not the prior's numbers, which travel as data)."""
        return tuple((s.name, s.transform, s.prior.kind) for s in self.specs)

    # -- transforms ----------------------------------------------------------------------
    def _is_log(self) -> np.ndarray:
        return np.array([s.transform == "log" for s in self.specs])

    def _value(self, theta, k: int):
        return jnp.exp(theta[k]) if self.specs[k].transform == "log" else theta[k]

    def values(self, theta) -> dict:
        """θ → ``{name: value}`` (SI), JAX-traceable: the one place θ becomes values."""
        theta = to_device(theta)
        return {n: self._value(theta, k) for k, n in enumerate(self.names)}

    def to_theta(self, values: dict) -> np.ndarray:
        """``{name: value}`` → θ (NumPy)."""
        x = np.asarray([values[n] for n in self.names], dtype=float)
        return np.where(self._is_log(), np.log(np.where(self._is_log(), x, 1.0)), x)

    def to_values(self, theta) -> np.ndarray:
        """θ (NumPy, any leading shape) → values (SI), same shape."""
        theta = np.asarray(theta, dtype=float)
        log = self._is_log()
        return np.where(log, np.exp(np.where(log, theta, 0.0)), theta)

    def seed_theta(self) -> np.ndarray:
        return self.to_theta({s.name: s.seed for s in self.specs})

    # -- priors --------------------------------------------------------------------------
    def prior_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Per parameter, the prior's centre and scale in the space it is Gaussian in:
        value for ``normal`` and ``half_normal``, log value for ``lognormal`` (passed to
        compiled code as data)."""
        centre = np.array([s.prior.centre if s.prior.in_value else np.log(s.prior.centre)
                           for s in self.specs], dtype=float)
        scale = np.array([s.prior.scale for s in self.specs], dtype=float)
        return centre, scale

    def prior_width_log(self) -> np.ndarray:
        """Per parameter, the prior sd in θ space (linearised for Gaussians in value of a
        log-transformed parameter; the sd itself for an untransformed one)."""
        return np.array([s.prior.scale if s.transform == "identity" else s.prior.width_in_log()
                         for s in self.specs], dtype=float)

    def is_log(self) -> np.ndarray:
        """Per parameter, whether θ holds its logarithm."""
        return self._is_log()

    def sd_values(self, theta, sd_theta) -> np.ndarray:
        """Standard deviations in value (SI) from those in θ at θ (linearised)."""
        return np.where(self._is_log(), self.to_values(theta) * np.asarray(sd_theta),
                        np.asarray(sd_theta))

    def prior_residuals(self, theta, centre, scale):
        """Standardised prior residuals, one per parameter (their half squared norm is the
        negative log-prior up to the log-Jacobian), for least squares."""
        theta = jnp.asarray(theta)
        x = jnp.stack([self._value(theta, k) if s.prior.in_value else theta[k]
                       for k, s in enumerate(self.specs)])
        return (x - centre) / scale

    def log_jacobian(self, theta):
        """Σ θ over log-transformed parameters with a prior Gaussian in value."""
        sel = np.array([s.prior.in_value and s.transform == "log" for s in self.specs])
        return jnp.sum(jnp.where(sel, jnp.asarray(theta), 0.0))

    def log_prior(self, theta, centre, scale):
        """Log prior density (up to a constant) at θ."""
        r = self.prior_residuals(theta, centre, scale)
        return -0.5 * jnp.sum(r * r) + self.log_jacobian(theta)


def _lognormal(value: float, source: str) -> Prior:
    return Prior("lognormal", float(value), float(np.log(PRIOR_FACTOR)), source)


def motor_registry(session: Session, seed: dict, *, coulomb: bool) -> Registry:
    """The motor's parameters: Ra, La (bench priors), K, B, J (and Tc with Coulomb
    friction).  K, B and J measured on the bench (``session.bench``) get that
    measurement as a Gaussian prior; otherwise, like Tc, a log-normal prior a factor
    :data:`PRIOR_FACTOR` wide around ``seed``.

    ``seed`` maps K, B, J, Tc to physical starting values (SI).
    """
    ra, la = session.Ra, session.La
    specs = [
        ParamSpec("Ra", "ohm", "motor", Prior("normal", ra.value, ra.sd, "bench"), ra.value,
                  description="armature resistance"),
        ParamSpec("La", "H", "motor",
                  Prior("lognormal", la.value, la.sd, "physical range") if la.source == LA_ASSUMED
                  else Prior("normal", la.value, la.sd, "bench"), la.value,
                  description="armature inductance"),
    ]
    for name, unit, block, words in (
            ("K", "V*s/rad", "motor", "torque and back-emf constant"),
            ("B", "N*m*s/rad", "friction", "viscous friction"),
            ("J", "kg*m^2", "motor", "inertia of rotor and load")):
        m = session.bench.get(name)
        prior = (Prior("normal", m.value, m.sd, "bench") if m is not None
                 else _lognormal(seed[name], "seed"))
        specs.append(ParamSpec(name, unit, block, prior, seed[name], description=words))
    if coulomb:
        specs.append(ParamSpec("Tc", "N*m", "friction", _lognormal(seed["Tc"], "seed"),
                               seed["Tc"], description="Coulomb friction torque"))
    return Registry(specs)


def identifier(text: str) -> str:
    """``text`` (a trace's name) as part of a parameter's name: every character that is
    not a letter or a digit an underscore."""
    return "".join(c if c.isalnum() else "_" for c in text)
