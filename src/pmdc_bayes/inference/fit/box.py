"""The fit of the parameters whose density is a box: where they start, and an optimum at
the box's edge.

A logged column's lead over the sample that shows its change (:mod:`..model.switch_lead`)
is such a parameter.  Where the armature's time constant is much shorter than a sample
interval, the log-posterior is flat in the lead (its prior's slope only) on either side
of a fall a time constant wide, where the first current sample after a change reads
the current risen, or not: a gradient fit started on the wrong side sees no slope
towards the right one, and the optimum, where the sample's reading lies on the fall's
edge, is a kink (its two one-sided slopes differ in sign), from which no
Levenberg–Marquardt step of all parameters together can rise.

So each such parameter starts at the best of its scan's values (:func:`scan_start`),
and a best start that stalls is :func:`settled`: its timing parameters held where it
stalled (their prior's scale shrunk by :data:`HOLD` about that point, the same compiled
step with other data), the others moved to their optimum, then all of them freed again.
An optimum from which the free step still finds no rise, with the others converged
(Newton decrement over them below the stall tolerance), is a kink: converged.

A dead time makes the same kind of kink: where the delayed step falls on a sample (a
driver or controller that acts a whole number of samples late), the current's slope
there jumps from 0 to V/La, so the log-posterior's one-sided slopes in the dead time
differ, and the optimum sits on the kink; :func:`kink_indices` names both kinds.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..._cores import usable_cores
from ..._x64 import to_device, x64
from ..model.nuisances import dead_time_name
from ..model.switch_lead import lead_scans
from .multistart import STALL_TOL, Outcome, Start, maximise

__all__ = ["scan_start", "box_indices", "kink_indices", "settled"]

HOLD = 1e-6  # a held parameter's prior scale, as a share of its own


def box_indices(model) -> np.ndarray:
    """The indices of ``model``'s box parameters (module docstring)."""
    return np.array([model.registry.index(n) for n in lead_scans(model.session)
                     if n in model.registry], dtype=int)


def kink_indices(model) -> np.ndarray:
    """The indices of ``model``'s timing parameters whose optimum may sit on a kink
    (module docstring): its leads and dead times."""
    names = [dead_time_name(tr.name, shared) for tr in model.session.traces
             for shared in (False, True)]
    dead = [model.registry.index(n) for n in dict.fromkeys(names) if n in model.registry]
    return np.union1d(box_indices(model), np.array(dead, dtype=int)).astype(int)


def scan_start(model, stepper, theta0) -> np.ndarray:
    """``theta0`` with each lead of ``model`` (:func:`..model.switch_lead.lead_scans`) at
    the value of its scan where the log-posterior (``stepper``'s) is highest; a lead
    whose scan is nowhere finite stays where it was."""
    theta = np.asarray(theta0, dtype=float).copy()
    scans = {n: v for n, v in lead_scans(model.session).items() if n in model.registry}
    if not scans:
        return theta
    with ThreadPoolExecutor(usable_cores() or 1) as pool:
        for name, values in scans.items():
            i = model.registry.index(name)
            rows = np.repeat(theta[None, :], len(values), axis=0)
            rows[:, i] = np.log(values) if model.registry.is_log()[i] else values
            lps = np.array(list(pool.map(x64(lambda r: stepper.terms(r).lp), rows)))
            if np.any(np.isfinite(lps)):
                theta[i] = rows[int(np.argmax(np.where(np.isfinite(lps), lps, -np.inf))), i]
    return theta


def _held(stepper, index, theta):
    """``stepper`` with the parameters at ``index`` held at ``theta``'s values."""
    centre = np.array(stepper.data["prior_centre"])
    scale = np.array(stepper.data["prior_scale"])
    centre[index] = theta[index]
    scale[index] *= HOLD
    return stepper.on(dict(stepper.data, prior_centre=to_device(centre),
                           prior_scale=to_device(scale)))


def _others_converged(start: Start, index) -> bool:
    """Whether the Newton decrement over the parameters not at ``index`` is below the
    stall tolerance (the curvature of the solver, restricted to them)."""
    g, H = np.asarray(start.terms.grad), np.asarray(start.at.curvature)
    keep = np.setdiff1d(np.arange(g.size), index)
    g, H = g[keep], H[np.ix_(keep, keep)]
    try:
        return 0.5 * float(g @ np.linalg.solve(H, g)) < STALL_TOL
    except np.linalg.LinAlgError:
        return False


def settled(model, stepper, start: Start) -> Start:
    """``start`` (a stalled one) moved to the kink of its timing parameters
    (:func:`kink_indices`), converged (module docstring); ``start`` itself where that
    does not succeed."""
    index = kink_indices(model)
    if start.outcome is not Outcome.STALLED or index.size == 0:
        return start
    (held,) = maximise(_held(stepper, index, np.asarray(start.theta)), [start.theta])
    if not held.converged:
        return start
    (free,) = maximise(stepper, [held.theta])
    if free.lp < start.lp:
        return start
    if free.outcome is Outcome.STALLED and _others_converged(free, index):
        free.outcome = Outcome.CONVERGED
        free.detail = ("at the edge of a lead's box" if index.size == box_indices(model).size
                       else "at a kink in a timing parameter (a lead, a dead time)")
    free.steps += start.steps + held.steps
    return free
