"""The diagnosis's rules on the steady levels (model-free, :mod:`.levels`): a trace off
the line the other levels draw, a declared drag that misses its trace's level, unit
slips, a speed-voltage line that crosses zero speed above 0 V (or at a different voltage
each way), a current left at zero speed."""

from __future__ import annotations

import numpy as np

from ...io.channel import STEADY, ChannelId
from ..model.levels import (
    LEVEL_MISS,
    direction_intercepts,
    friction_offset,
    level_outliers,
    voltage_intercept,
)
from .findings import NO_LOAD_SPEED
from .proposals import COULOMB, Proposal, said

__all__ = ["level_rules", "UNIT_RATIOS"]

UNIT_RATIOS = {"rpm given as rad/s": 60 / (2 * np.pi), "rad/s given as rpm": 2 * np.pi / 60,
               "rev/s given as rad/s": 1 / (2 * np.pi), "rad/s given as rev/s": 2 * np.pi,
               "mA given as A": 1000.0, "A given as mA": 1e-3,
               "a reversed sign (the speed counts the other way)": -1.0}
SLIP_TOLERANCE = 0.03
ASYMMETRY_Z = 4.0  # the two directions' zero-speed voltages apart by this many sd ...
ASYMMETRY_SHARE = 0.01  # ... and by this share of the largest voltage


def _unit_slips(ratios, outliers) -> dict[str, str]:
    """Traces whose settled speed is a unit ratio (or -1) times what the model or the
    other traces' levels imply: trace name -> the slip's label."""
    out = {}
    for name, r in ratios.items():
        seen = [r] + ([1 + outliers[name]] if name in outliers else [])
        for label, ratio in UNIT_RATIOS.items():
            if any(abs(x / ratio - 1) < SLIP_TOLERANCE for x in seen):
                out[name] = label
    return out


def _level_sentence(name: str, miss: float, against: str, alt: str = ""):
    """A trace that settles ``miss`` (relative) off ``against``, in words."""
    where = f"{name}: settles {100 * abs(miss):.2g} % {'below' if miss < 0 else 'above'} {against}"
    if miss < 0:
        return said(f"{where}: an unmeasured load on this trace (a brake, a generator, a "
                    f"rubbing coupling){alt}; declare its load torque, or fit it: [model] "
                    f"unknown_load = [{name!r}]", Proposal("unknown_load", name))
    return (f"{where}: this trace turned more freely than the rest of the session says (a "
            "load on the other traces that this one lacks, a coupling removed), or its "
            "voltage was higher than the session says; check the bench and the voltage")


def _declared_drag_rules(session, ratios, slips) -> list[str]:
    """Traces with a declared drag that settle off the model's level: the drag declared
    too strong (the speed settles above) or too weak (below)."""
    out = []
    for tr in session.traces:
        r = ratios.get(tr.name)
        if not tr.drag.nonzero or r is None or tr.name in slips or abs(r - 1) <= LEVEL_MISS:
            continue
        way = "strong" if r > 1 else "weak"
        text = (f"{tr.name}: settles {100 * abs(r - 1):.2g} % {'above' if r > 1 else 'below'}"
                   f" the model's speed under its declared drag: the drag is declared too "
                   f"{way} (check its curve, coefficients and units: the curve's speeds are in "
                   "the trace's speed unit, its torques in its load_torque unit)"
                   + ("" if r > 1 else ", or the trace carries a load beside it: [model] "
                      f"unknown_load = [{tr.name!r}]"))
        out.append(text if r > 1 else said(text, Proposal("unknown_load", tr.name)))
    return out


def level_rules(model, fit, preds, findings):
    """Sentences on the steady levels: unmeasured loads, unit slips, an offset."""
    session, out = model.session, []
    ratios = {}
    for tr, (_, w) in zip(session.traces, preds, strict=True):
        n_end = max(3, tr.n // 10)
        mod = float(np.mean(w[-n_end:]))
        if abs(mod) > 0:
            ratios[tr.name] = float(np.mean(tr.speed[-n_end:])) / mod
    outliers = level_outliers(session)
    if outliers is None:  # too few levels for a line: compare with the model instead
        declared = {tr.name for tr in session.traces if tr.drag.nonzero}  # said below
        misses = {k: r - 1 for k, r in ratios.items()
                  if abs(r - 1) > LEVEL_MISS and k not in declared}
        outliers = misses if len(misses) < len(ratios) else {}
        alt = ", or a voltage drop the other traces hide"
    else:
        alt = ""
    slips = _unit_slips(ratios, outliers)
    if slips and len(slips) == len(ratios) and len(set(slips.values())) == 1:
        label = next(iter(slips.values()))
        out.append(f"the logged speeds are {UNIT_RATIOS[label]:.4g} x what the rest of the "
                   f"session implies: a unit slip ({label}); check the units in session.toml")
    else:
        out += [f"{name}: its speed is {UNIT_RATIOS[label]:.4g} x what the rest of the "
                f"session implies: {label}; check this trace's units and sign in session.toml"
                for name, label in slips.items()]
    for name, m in outliers.items():
        if name in slips:
            continue
        out.append(_level_sentence(name, m, "the speed the other levels imply", alt))
    out += _declared_drag_rules(session, ratios, slips)
    icpt, offset = voltage_intercept(session), friction_offset(session)
    coulomb = (offset is not None and offset["current"] > 3 * offset["se"]
               and offset["current"] > 0.05 * offset["mean_current"])
    if coulomb and not model.coulomb:
        out.append(said(f"the steady current extrapolates to {offset['current']:.3g} A at "
                        "zero speed: a friction torque that does not grow with speed (Coulomb "
                        "friction); fit with --friction coulomb", Proposal(COULOMB)))
    elif (icpt and "Vdrop" in model.registry and any(
            f.where in (ChannelId(STEADY, "speed"), ChannelId(STEADY, "current"),
                        NO_LOAD_SPEED)
            for f in findings if f.failed)):
        out.append("the steady levels miss the model even with a fitted voltage drop "
                   f"({float(fit.values['Vdrop']):.3g} V): the session's steady numbers "
                   "disagree with each other or with the traces (see the consistency "
                   "checks), or friction or load differ between them")
    elif (icpt and icpt["voltage"] > 3 * icpt["se"]
            and icpt["voltage"] > 0.01 * icpt["largest_voltage"]):
        why = ("" if model.coulomb or offset is not None
               else ", or Coulomb friction (try --friction coulomb)")
        out.append(said(f"the steady speed-voltage line crosses zero speed at "
                        f"{icpt['voltage']:.3g} V, not 0 V: a voltage drop at the brushes or "
                        f"driver (--add voltage-drop){why}", Proposal("voltage_drop"),
                        *(() if why == "" else (Proposal(COULOMB),))))
    if "dead_zone" not in session.nuisances:
        out += _asymmetry_rule(session)
    return out


def _asymmetry_rule(session) -> list[str]:
    """The speed-voltage lines of the two directions cross zero speed at voltages
    :data:`ASYMMETRY_Z` standard errors and :data:`ASYMMETRY_SHARE` of the largest
    voltage apart: a driver that loses more of its command one way than the other (a
    dead zone), which a drop (the same both ways) cannot explain."""
    icpt = direction_intercepts(session)
    if len(icpt) < 2:
        return []
    fwd, rev = icpt[1], icpt[-1]
    gap, se = fwd["voltage"] - rev["voltage"], float(np.hypot(fwd["se"], rev["se"]))
    top = max([abs(float(v)) for tr in session.traces for v in tr.voltage.values] + [1e-300])
    if abs(gap) <= ASYMMETRY_Z * se or abs(gap) <= ASYMMETRY_SHARE * top:
        return []
    return [said(f"the steady speed reaches zero at {fwd['voltage']:.3g} V forward but at "
                 f"{-rev['voltage']:.3g} V in reverse: the driver loses more of its "
                 "command one way than the other (a dead zone), which a drop at the "
                 "brushes cannot explain; fit it: --add dead-zone (dead_zone = true under "
                 "[model])", Proposal("dead_zone"))]
