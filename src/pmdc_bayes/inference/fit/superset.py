"""One compiled program for many models of a session: a *superset* model holding every
non-ideality a search may try, in which a candidate is the superset with the others
switched off at run time.

A parameter switched off (``data["off"]``) sits at its neutral value inside the
prediction (:meth:`~.objective.SessionModel.switched`: no dead time, drop, dead zone
or offset, a gain of one, no lag, no limit, no source resistance, drag or Coulomb
friction) and has a standard Gaussian in θ of its own, so it moves nothing and adds
nothing to the Laplace evidence.  Which parameters are off, their neutral values and
the candidate's own priors are all data, so every candidate of a session shape runs
the superset's compiled Gauss–Newton kernel: trying one costs a fit, not a compile.
The fit is then read in the candidate's own parameters (:meth:`Superset.fit`), whose
curvature is exactly the superset's on them (nothing couples them to the parameters
switched off).
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from ..._x64 import to_device, x64
from ...physics.regimes import NO_LIMIT
from ...physics.sensor import MIN_LAG
from ..model.params import ParamSpec, Registry
from .joint import FitResult, fit_map

__all__ = ["Superset", "neutral_value", "project", "extended"]

SMALLEST = 1e-300  # a positive quantity taken as none at all (a resistance, drag, friction)


def neutral_value(spec: ParamSpec) -> float:
    """The value (SI) at which a non-ideality's parameter predicts what the model
    without it does: no limit, no lag (the shortest the solution takes), a gain of one,
    zero for a dead time, dead zone or offset, and for a positive drop, resistance,
    drag or friction the smallest positive number."""
    if spec.name == "Imax":
        return NO_LIMIT
    if spec.name.endswith("_lag"):
        return MIN_LAG
    if spec.transform == "identity":
        return 0.0
    if spec.unit == "1":
        return 1.0
    return SMALLEST


@x64
def extended(model, specs):
    """A copy of ``model`` with the parameters ``specs`` appended: what a superset holds
    beyond what one session can declare (a dead time shared by every trace beside each
    trace's own, which the prediction adds)."""
    out = copy.copy(model)
    out.registry = Registry(model.registry.specs + tuple(specs))
    out.names = out.registry.names
    out.prior_sd = out.registry.prior_width_log()
    out.data = out._collect_data()
    return out


class Superset:
    """A superset model of a session (a :class:`~.objective.SessionModel` with every
    non-ideality its candidates may hold), and its candidates' fits."""

    def __init__(self, model):
        self.model = model

    def covers(self, own) -> bool:
        """Whether ``own``, a model of the same session, is the superset with some of its
        parameters switched off: the same observations, and no parameter the superset
        lacks or holds in another form."""
        sup = self.model
        if not set(own.names) <= set(sup.names):
            return False
        if any(own.registry[n].transform != sup.registry[n].transform for n in own.names):
            return False
        same = [np.array_equal(np.asarray(a), np.asarray(b)) for a, b in
                ((own.n_obs, sup.n_obs), (own.s0, sup.s0))]
        blocks = tuple(b.key for b in own.blocks) == tuple(b.key for b in sup.blocks)
        return all(same) and blocks

    @x64
    def switched(self, own):
        """The superset as ``own``: ``own``'s priors and seeds on its parameters, every
        other parameter switched off at its neutral value (data only, so the superset's
        compiled programs serve it)."""
        sup = self.model
        specs = [own.registry[s.name] if s.name in own.registry else s for s in sup.registry.specs]
        registry = Registry(specs)
        off = np.array([s.name not in own.registry for s in specs])
        neutral = registry.to_theta({s.name: neutral_value(s) for s in specs})
        centre, scale = registry.prior_arrays()
        seed = registry.seed_theta()
        centre = np.where(off, seed, centre)
        scale = np.where(off, 1.0, scale)
        view = copy.copy(sup)
        view.registry = registry
        view.prior_sd = np.where(off, 1.0, registry.prior_width_log())
        view.data = dict(sup.data, off=to_device(off), neutral=to_device(neutral),
                         prior_centre=to_device(centre), prior_scale=to_device(scale))
        return view

    @x64
    def fit(self, own, *, seed: int = 0, alternatives=()) -> FitResult:
        """``own``'s MAP and Laplace approximation, fitted in the superset from ``own``'s
        seed and ``alternatives`` (θ of ``own``), read in ``own``'s parameters."""
        view = self.switched(own)
        index = np.array([view.registry.index(n) for n in own.names])
        base = np.asarray(view.registry.seed_theta(), dtype=float)

        def embed(theta):
            full = base.copy()
            full[index] = np.asarray(theta, dtype=float)
            return full

        full = fit_map(view, theta0=embed(own.theta_seed()), seed=seed,
                       alternatives=[embed(a) for a in alternatives])
        return project(full, own, index)


def project(fit: FitResult, own, index) -> FitResult:
    """``fit`` of a superset read in ``own``'s parameters (at ``index`` in its θ)."""
    sub = np.ix_(index, index)
    theta = np.asarray(fit.theta)[index]
    cov = np.asarray(fit.cov_log)[sub]
    sd_log = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd_log, sd_log)
    values = dict(zip(own.names, map(float, own.registry.to_values(theta)), strict=True))
    sd = dict(zip(own.names, map(float, own.registry.sd_values(theta, sd_log)), strict=True))
    cov_map = None if fit.cov_map is None else np.asarray(fit.cov_map)[sub]
    return dataclasses.replace(fit, names=tuple(own.names), theta=theta, values=values, sd=sd,
                               cov_log=cov, corr=corr, cov_map=cov_map)

