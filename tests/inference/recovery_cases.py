"""Synthetic motors with known truth, and the plan of a bench session for each.

A table of motors from a 2 W hobby motor to a 200 W servo (:data:`MOTORS`), each
paired with one of a few session *structures* (:data:`STRUCTURES`): which friction
model, whether the traces log the current, whether there is a load-change trace.
:func:`plan_for` turns a motor into a simulation plan (see ``data/demo/plan.toml``)
whose traces are scaled to the motor's own time constants.

How the values were chosen
--------------------------
Each motor has a nominal test voltage V.  From it and the parameters follow the
figures a datasheet would give, which we kept plausible for the motor's size:

- peak mechanical power ``P = V²/(4·Ra)`` (stall torque K·V/Ra times no-load speed
  V/K, over 4) sets the size class;
- no-load speed ``ω0 ≈ V/K`` (a few thousand to ~17,000 rpm);
- stall current ``Is = V/Ra``;
- friction: the torque ``B·ω0 + Tc`` at no load is 0.1–5 % of the stall torque
  ``K·Is`` (no-load current a few % of the stall current, ~0.1 % for the servos;
  13 % for the paper's rig, from its Table II);
- rotor inertia from the frame size (1 g·cm² = 1e-7 kg·m² for a 130-size can
  motor, ~500 g·cm² for a 200 W servo), so the mechanical time constant
  ``τm = J·Ra/(K² + B·Ra)`` (equation (9)) is 10–40 ms, except the reference paper's
  rig, whose flywheel makes it ~1.2 s;
- ``La`` a fraction of a mH to a few mH: electrical time constant ``τe = La/Ra``
  0.1–2 ms.

Sessions of one structure share compiled functions (``SessionModel.compiled``): every
trace has :data:`N_INTERVALS` + 1 samples whatever the motor, its rate set so the
trace lasts 8·τm (or 8·τe for the fast current capture), and every input change
falls half a sample after sample :data:`STEP_INDEX` (or :data:`LOAD_INDEX`), so
the piecewise-constant segments hold the same number of samples for every motor.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Motor", "Structure", "MOTORS", "STRUCTURES", "plan_for", "time_constants",
           "steady_voltages", "N_INTERVALS", "N_STEADY", "STEP_INDEX", "LOAD_INDEX",
           "SPEED_NOISE", "CURRENT_NOISE", "STEADY_NOISE"]

N_INTERVALS = 400  # samples per trace, minus one
STEP_INDEX = 20  # the voltage step (and the first load change) after this sample
LOAD_INDEX = 220  # the second load change after this sample
# Steady table: N_STEADY voltages from 0.25·V to V.  Not fewer: each channel (here the
# steady currents) has its own noise level, integrated out, and with only ~5 readings
# the MAP noise level comes out well below the truth (the parameters absorb part of
# the residuals), so the Laplace sd of K and B was ~2× too small (RMS z ≈ 2.1 over 16
# seeds of toy-5W with 4 voltages, ≈ 1.0 with 20); see test_recovery.py.
N_STEADY = 20
SPEED_NOISE = 0.002  # trace speed noise sd, fraction of the no-load speed V/K
CURRENT_NOISE = 0.005  # trace current noise sd, fraction of the stall current V/Ra
STEADY_NOISE = 0.001  # steady readings (averaged): the same fractions, smaller
RA_SD = 0.01  # bench Ra: 1 % (four-wire ohmmeter)
LA_SD = 0.05  # bench La: 5 % (LC meter)


@dataclass(frozen=True)
class Structure:
    """What a session holds besides its numbers (sessions of one structure share
    compiled code).

    friction : ``"viscous"`` or ``"coulomb"``.
    current : the traces log the armature current; then a fast current capture
        (8·τe long) is added, which makes La identifiable from the data.
    load : a load-change trace (0 → 20 % → 10 % of the stall torque, from steady).
    """

    name: str
    friction: str
    current: bool
    load: bool


STRUCTURES = {s.name: s for s in (
    Structure("viscous+current", "viscous", current=True, load=False),
    Structure("viscous+load", "viscous", current=False, load=True),
    Structure("coulomb+current+load", "coulomb", current=True, load=True),
    Structure("coulomb", "coulomb", current=False, load=False),
)}


@dataclass(frozen=True)
class Motor:
    """A synthetic motor: the true parameters (SI), its test voltage V and a structure."""

    name: str
    V: float  # V
    Ra: float  # ohm
    La: float  # H
    K: float  # V*s/rad = N*m/A
    B: float  # N*m*s/rad
    J: float  # kg*m^2
    Tc: float  # N*m
    structure: str
    note: str = ""

    @property
    def truth(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ("Ra", "La", "K", "B", "J", "Tc")}


# Figures in the notes: P = V²/(4Ra), ω0 = V/K, τm, τe; friction as % of stall torque.
MOTORS = (
    Motor("hobby-2W", V=9.0, Ra=10.0, La=1.0e-3, K=0.005, B=1.2e-7, J=1.0e-7, Tc=0.0,
          structure="viscous+current",
          note="130-size can motor: P 2.0 W, ω0 1800 rad/s (17 krpm), τm 38 ms, "
               "τe 0.1 ms, friction 5 %"),
    Motor("micro-0.5W", V=3.0, Ra=5.0, La=0.15e-3, K=0.002, B=2.0e-8, J=2.0e-8, Tc=0.0,
          structure="viscous+load",
          note="coreless micro motor: P 0.45 W, ω0 1500 rad/s, τm 24 ms, τe 0.03 ms, "
               "friction 2.5 %"),
    Motor("toy-5W", V=12.0, Ra=7.0, La=1.2e-3, K=0.012, B=6.0e-7, J=6.0e-7, Tc=0.0,
          structure="viscous+load",
          note="370-size motor: P 5.1 W, ω0 1000 rad/s, τm 28 ms, τe 0.17 ms, friction 3 %"),
    Motor("micro-3W", V=6.0, Ra=3.0, La=0.5e-3, K=0.006, B=2.0e-8, J=2.0e-7, Tc=2.0e-4,
          structure="coulomb",
          note="280-size motor with brush friction: P 3 W, ω0 1000 rad/s, τm 17 ms, "
               "τe 0.17 ms, Tc 1.7 % + viscous 0.2 %"),
    Motor("tool-20W", V=12.0, Ra=1.8, La=0.4e-3, K=0.018, B=4.0e-6, J=3.0e-6, Tc=0.0,
          structure="viscous+current",
          note="540-size drill motor: P 20 W, ω0 670 rad/s, τm 16 ms, τe 0.22 ms, "
               "friction 2.2 %"),
    Motor("paper-rig", V=12.97, Ra=8.5, La=5.6e-3, K=0.062, B=4.5e-5, J=5.9e-4, Tc=2.5e-3,
          structure="coulomb+current+load",
          note="the reference paper's rig with flywheel (data/demo/plan.toml): P 4.9 W at "
               "12.97 V, ω0 210 rad/s, τm 1.2 s, τe 0.66 ms, friction 10 % + 2.6 %"),
    Motor("gearmotor-40W", V=24.0, Ra=3.5, La=2.0e-3, K=0.045, B=1.0e-5, J=1.5e-5,
          Tc=5.0e-3, structure="coulomb+current+load",
          note="24 V gearmotor, gearbox friction reflected: P 41 W, ω0 530 rad/s, "
               "τm 25 ms, τe 0.57 ms, Tc 1.6 % + viscous 1.7 %"),
    Motor("robot-80W", V=24.0, Ra=1.6, La=0.8e-3, K=0.035, B=5.0e-6, J=2.0e-5, Tc=0.0,
          structure="viscous+load",
          note="robot drive motor: P 90 W, ω0 690 rad/s, τm 26 ms, τe 0.5 ms, "
               "friction 0.7 %"),
    Motor("servo-100W", V=24.0, Ra=1.2, La=1.5e-3, K=0.07, B=8.0e-6, J=4.0e-5, Tc=0.01,
          structure="coulomb",
          note="brushed servo: P 120 W, ω0 340 rad/s, τm 9.8 ms, τe 1.25 ms, "
               "Tc 0.7 % + viscous 0.2 %"),
    Motor("servo-200W", V=24.0, Ra=0.5, La=1.0e-3, K=0.1, B=1.0e-5, J=1.0e-4, Tc=0.0,
          structure="viscous+current",
          note="200 W servo with a coupled load inertia: P 290 W, ω0 240 rad/s, τm 5 ms, "
               "τe 2 ms: τm < 4·τe, so the (ia, ω) modes are complex (underdamped)"),
)


def time_constants(m: Motor) -> tuple[float, float]:
    """``(τm, τe)`` (s): equation (9) and La/Ra."""
    return m.J * m.Ra / (m.K ** 2 + m.B * m.Ra), m.La / m.Ra


def _trace(name, kind, tau, V, *, current, speed_sd, current_sd, load=None):
    """A trace of ``N_INTERVALS`` intervals lasting 8·tau; inputs change half a sample
    after sample ``STEP_INDEX`` (and ``LOAD_INDEX``)."""
    duration = 8.0 * tau
    rate = N_INTERVALS / duration
    t1, t2 = (STEP_INDEX + 0.5) / rate, (LOAD_INDEX + 0.5) / rate
    spec = {"name": name, "kind": kind, "duration": duration, "rate": rate,
            "speed_unit": "rad/s", "record_current": current, "speed_noise": speed_sd,
            "current_noise": current_sd}
    if load is None:
        spec.update(voltage=[[0.0, 0.0], [t1, V]], initial="rest")
    else:
        spec.update(voltage=[[0.0, V]], initial="steady",
                    load_torque=[[0.0, 0.0], [t1, load], [t2, 0.5 * load]])
    return spec


def steady_voltages(V: float, n: int = N_STEADY) -> list[float]:
    """``n`` voltages evenly spaced from 0.25·V to V."""
    return [V * (0.25 + 0.75 * k / (n - 1)) for k in range(n)]


def plan_for(m: Motor, *, seed: int, structure: str | None = None,
             n_steady: int = N_STEADY) -> dict:
    """The simulation plan of a bench session of motor ``m`` (see the module notes).

    The session: bench Ra and La; a chopper operating point at 0.7·V with current
    (the closed form's equation (20)); a steady table of ``n_steady`` voltages from
    0.25·V to V with speed and current; a 0 → V step from rest lasting 8·τm; with
    ``structure.load`` a load-change trace; with ``structure.current`` current in the
    traces and a fast capture of a step lasting 8·τe.
    """
    st = STRUCTURES[structure or m.structure]
    tau_m, tau_e = time_constants(m)
    w0, i_stall = m.V / m.K, m.V / m.Ra
    speed_sd, current_sd = SPEED_NOISE * w0, CURRENT_NOISE * i_stall
    steady = {"speed_sd": STEADY_NOISE * w0, "current_sd": STEADY_NOISE * i_stall}
    noise = {"current": st.current, "speed_sd": speed_sd, "current_sd": current_sd}
    traces = [_trace("step", "step", tau_m, m.V, **noise)]
    if st.load:
        traces.append(_trace("load", "load_change", tau_m, m.V, load=0.2 * m.K * i_stall,
                             **noise))
    if st.current:
        traces.append(_trace("capture", "step", tau_e, m.V, **noise))
    truth = m.truth
    if st.friction == "viscous":
        truth["Tc"] = 0.0
    return {
        "seed": seed,
        "motor": {"name": m.name, "friction": st.friction},
        "truth": truth,
        "bench": {"Ra": {"sd": RA_SD * m.Ra, "unit": "ohm"},
                  "La": {"sd": LA_SD * m.La * 1e3, "unit": "mH"}},
        "operating_point": [{"name": "chopper", "supply_voltage": m.V, "duty": 0.7,
                             **steady}],
        "steady_table": [{"name": "sweep", "voltages": steady_voltages(m.V, n_steady),
                          **steady}],
        "trace": traces,
    }
