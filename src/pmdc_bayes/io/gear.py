"""A gearmotor measured at its output shaft: ``[motor] gear_ratio`` (part of the loader).

With ``gear_ratio = N`` (motor turns per turn of the output shaft) every speed, angle and
load torque the session gives is the output shaft's; the loader turns them into the
motor shaft's, where the model lives: speeds and angles times N, torques divided by N
(a known drag's coefficients accordingly).  The fitted J, B and Coulomb friction are
then the motor's with the gearbox and load reflected to its shaft, and K is the motor's
own.  Bench measurements of K, J and B are read as the motor shaft's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .drag import Drag
from .session import OperatingPoint, SteadyTable, StepReading, Trace

__all__ = ["motor_shaft_trace", "motor_shaft_point", "motor_shaft_table",
           "motor_shaft_reading", "motor_shaft_drag"]


def motor_shaft_drag(drag: Drag, n: float) -> Drag:
    """The output shaft's drag ``T(ω_out)`` seen at the motor shaft: ``T(ω/n)/n``."""
    return Drag(constant=drag.constant / n, viscous=drag.viscous / n**2,
                quadratic=drag.quadratic / n**3,
                curve=tuple((w * n, x / n) for w, x in drag.curve))


def motor_shaft_trace(tr: Trace, n: float) -> Trace:
    """A trace (driven or coast-down) logged at the output shaft, at the motor shaft."""
    if n == 1.0:
        return tr
    initial = tr.initial
    if isinstance(initial, tuple):
        initial = (initial[0], initial[1] * n)
    held = tr.load_torque
    load = dataclasses.replace(
        held, values=np.asarray(held.values) / n,
        se=None if held.se is None else np.asarray(held.se) / n,
        noise=None if held.noise is None else held.noise / n)
    return dataclasses.replace(
        tr, speed=np.asarray(tr.speed) * n, load_torque=load, initial=initial,
        position=None if tr.position is None else np.asarray(tr.position) * n,
        encoder_step=tr.encoder_step * n, drag=motor_shaft_drag(tr.drag, n))


def motor_shaft_point(op: OperatingPoint, n: float) -> OperatingPoint:
    return dataclasses.replace(op, speed=op.speed * n, load_torque=op.load_torque / n)


def motor_shaft_table(tab: SteadyTable, n: float) -> SteadyTable:
    return dataclasses.replace(tab, speed=np.asarray(tab.speed) * n,
                               load_torque=np.asarray(tab.load_torque) / n)


def motor_shaft_reading(sr: StepReading, n: float) -> StepReading:
    return dataclasses.replace(sr, final_speed=sr.final_speed * n,
                               initial_speed=sr.initial_speed * n)
