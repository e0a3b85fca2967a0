"""The bundled ``data/bench`` session: a realistic rig, simulated by the independent
bench simulator (:mod:`.bench`), written as a user would log it.

The rig: an encoder of :data:`COUNTS_PER_REV` counts per turn read every 0.5 ms (no
current sensor on the traces), a driver with a dead time, a voltage drop at brushes
and driver and a current limit (each step starts clamped), Coulomb friction, an
eddy-current brake on one trace nobody measured, a multimeter's steady speed and
current at four voltages, a bench Ra and no La (no LCR meter), no chopper point.
``session.toml`` declares the model that describes it in ``[model]``.

Regenerate (byte-for-byte, same seed)::

    python -m pmdc_bayes.simulate.bundled_bench data/bench
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .bench import BenchMotor, StepSpec, bench_session

__all__ = ["MOTOR", "RIG", "STEPS", "SEED", "COUNTS_PER_REV", "BRAKED", "write_bench",
           "truth"]

MOTOR = dict(Ra=2.0, La=2e-3, K=0.05, B=2e-5, J=2e-5, Tc=1e-3)
BRAKED = "step_9v_braked"
RIG = dict(dead_time=2e-3, voltage_drop=0.8, current_limit=2.0,
           extra_load={BRAKED: (0.0, 1e-4)})
COUNTS_PER_REV = 400
STEPS = (StepSpec("step_12v", 12.0, 0.15, 5e-4, t_step=0.01, log_current=False),
         StepSpec("step_6v", 6.0, 0.15, 5e-4, t_step=0.01, log_current=False),
         StepSpec(BRAKED, 9.0, 0.15, 5e-4, t_step=0.01, log_current=False))
STEADY_VOLTAGES = (3.0, 6.0, 9.0, 12.0)
SEED = 7


def truth() -> dict:
    """The true motor and rig (SI), under the names the fit reports."""
    out = dict(MOTOR)
    out.update({"Vdrop": RIG["voltage_drop"], "Imax": RIG["current_limit"],
                f"drag_{BRAKED}": RIG["extra_load"][BRAKED][1]})
    out["dead_time"] = RIG["dead_time"]  # one driver and logger: shared by every trace
    return out


def _num(x: float) -> str:
    return repr(float(x))


def write_bench(root: Path) -> Path:
    """Write the session into ``root`` (created; files there of the same names are
    replaced, nothing else touched)."""
    motor = BenchMotor(**MOTOR, **RIG, encoder_counts_per_rev=COUNTS_PER_REV,
                       encoder_output="position")
    s = bench_session(motor, STEPS, seed=SEED, steady_voltages=STEADY_VOLTAGES,
                      friction="coulomb", name="bench")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    q = 2.0 * np.pi / COUNTS_PER_REV
    toml = ['[motor]\nname = "simulated bench motor (SIMULATED data, see README.md)"\n'
            'friction = "coulomb"\n',
            f'[bench.Ra]\nvalue = {_num(s.Ra.value)}\nsd = {_num(s.Ra.sd)}\nunit = "ohm"\n']
    tab = s.steady_tables[0]
    (root / "steady.csv").write_text("voltage_V,speed_rad_s,current_A\n" + "".join(
        f"{_num(v)},{w:.6g},{i:.6g}\n"
        for v, w, i in zip(tab.voltage, tab.speed, tab.current, strict=True)))
    toml.append('[[steady_table]]\nname = "steady"\nfile = "steady.csv"\n'
                'columns = { voltage = "voltage_V", speed = "speed_rad_s", '
                'current = "current_A" }\n')
    for tr, spec in zip(s.traces, STEPS, strict=True):
        counts = np.rint(tr.position / q).astype(np.int64)
        (root / f"{tr.name}.csv").write_text("time_s,counts\n" + "".join(
            f"{t:.4f},{c}\n" for t, c in zip(tr.time, counts, strict=True)))
        toml.append(f'[[trace]]\nname = "{tr.name}"\nkind = "step"\nfile = "{tr.name}.csv"\n'
                    'columns = { time = "time_s", position = "counts" }\n'
                    f'units = {{ position = "counts" }}\ncounts_per_rev = {COUNTS_PER_REV}\n'
                    f'voltage = [[0.0, 0.0], [{_num(spec.t_step)}, {_num(spec.voltage)}]]\n')
    toml.append(f'[model]\ndead_time = "shared"\nvoltage_drop = true\ncurrent_limit = true\n'
                f'unknown_load = {{ {BRAKED} = "viscous" }}\n')
    (root / "session.toml").write_text("\n".join(toml))
    (root / "truth.json").write_text(json.dumps(truth(), indent=2) + "\n")
    return root


if __name__ == "__main__":
    write_bench(Path(sys.argv[1] if len(sys.argv) > 1 else "data/bench"))
