"""A catalogue of benches for testing the adequacy checks: one small motor with each
non-ideality of real rigs switched on alone, and motors drawn over the range of small
bench motors that the ideal model describes exactly."""

from __future__ import annotations

import dataclasses

import numpy as np

from .bench import BenchMotor, StepSpec, bench_session

__all__ = ["MOTOR", "STEPS", "CASES", "SPEED_ONLY", "case_session", "random_motor"]

MOTOR = dict(Ra=2.0, La=2e-3, K=0.05, B=2e-5, J=2e-5)  # tau ~ 15 ms, La/Ra = 1 ms
STEPS = (StepSpec("step_12v", 12.0, 0.12, 2e-4), StepSpec("step_6v", 6.0, 0.12, 2e-4))
STEADY_VOLTAGES = (4.0, 8.0, 12.0)

#: case -> (BenchMotor fields, words the diagnosis must contain)
CASES = {
    "dead time": (dict(dead_time=3e-3), ("dead time",)),
    "sensor lag": (dict(speed_lag=3e-3), ("lag in the speed sensor",)),
    "brush drop": (dict(voltage_drop=1.0), ("voltage drop",)),
    "source resistance": (dict(source_resistance=0.6), ("source resistance",)),
    "current limit": (dict(current_limit=2.0), ("current-limited",)),
    "unknown load": (dict(extra_load={"step_6v": (1.5e-2, 0.0)}),
                     ("step_6v", "unmeasured load")),
    "unknown viscous load": (dict(extra_load={"step_6v": (0.0, 1.5e-4)}),
                             ("step_6v", "unmeasured load")),
    "encoder speed": (dict(encoder_counts_per_rev=200), ("encoder",)),
}


#: case -> words the diagnosis must contain when no current is logged anywhere; None
#: where speed alone cannot reveal the case (a source resistance only adds to Ra, which
#: speed data do not separate from the inertia)
SPEED_ONLY = {"dead time": ("dead time",), "sensor lag": ("lag",),
              "brush drop": ("voltage drop",), "source resistance": None,
              "current limit": ("current-limited",),
              "unknown load": ("step_6v", "unmeasured load"),
              "unknown viscous load": ("step_6v", "unmeasured load"),
              "encoder speed": ("encoder",)}


def case_session(case: str | None = None, *, seed: int = 0, speed_only: bool = False,
                 steady_current: bool = True):
    """The session of ``case`` (a key of :data:`CASES`; None for the ideal bench) on
    :data:`MOTOR`: two steps and a steady table at 4, 8 and 12 V; ``speed_only`` drops
    the steps' current channels, ``steady_current=False`` the table's currents."""
    extra = {} if case is None else CASES[case][0]
    steps = STEPS
    if speed_only:
        steps = tuple(dataclasses.replace(s, log_current=False) for s in steps)
    session = bench_session(BenchMotor(**MOTOR, **extra), steps, seed=seed,
                            steady_voltages=STEADY_VOLTAGES)
    if not steady_current:
        session = dataclasses.replace(session, steady_tables=tuple(
            dataclasses.replace(t, current=None) for t in session.steady_tables))
    return session


def random_motor(rng: np.random.Generator) -> tuple[BenchMotor, tuple]:
    """A motor drawn over the range of small bench motors (Ra 0.5–10 Ω, K 0.01–0.2
    N·m/A, La/Ra 0.2–2 ms, mechanical time constant 20–500 ms, viscous friction 2–30 %
    of the damping), with noise 0.2 % of the final speed and stall current, and two
    steps (12 V, 6 V) of one shape (600 samples over six mechanical time constants) so
    every fit shares one compiled program."""
    Ra = float(np.exp(rng.uniform(np.log(0.5), np.log(10.0))))
    K = float(np.exp(rng.uniform(np.log(0.01), np.log(0.2))))
    La = Ra * float(np.exp(rng.uniform(np.log(2e-4), np.log(2e-3))))
    tau_m = float(np.exp(rng.uniform(np.log(0.02), np.log(0.5))))
    damping = float(rng.uniform(0.02, 0.3))
    B = damping * K * K / Ra / (1 - damping)
    J = tau_m * (K * K + Ra * B) / Ra
    w_final = K * 12.0 / (Ra * B + K * K)
    motor = BenchMotor(Ra=Ra, La=La, K=K, B=B, J=J, speed_noise=2e-3 * w_final,
                       current_noise=2e-3 * 12.0 / Ra)
    dur = 6 * tau_m
    steps = (StepSpec("step_12v", 12.0, dur, dur / 600),
             StepSpec("step_6v", 6.0, dur, dur / 600))
    return motor, steps
