"""Controller-design export: the identified model as plain JSON matrices (always) and
as python-control objects (when the optional ``control`` package is installed)."""

from __future__ import annotations

import numpy as np

from ..physics.motor import gain, state_space, tf_full, time_constant

__all__ = ["controller_model", "to_control"]


def controller_model(ctx) -> dict:
    """The identified model, JSON-ready.

    The parameters are the posterior mean (the MAP without a posterior) with their
    covariance (of the draws; Laplace otherwise).  State ``x = [ω, ia]``, inputs
    ``u = [TL, Va]``, output ``y = ω``: equations (11)–(14).  ``transfer_function`` is
    ω(s)/Va(s), equation (7); ``first_order`` is (8).
    """
    v = ctx.best
    A, Bu, C, D = state_space(v["Ra"], v["La"], v["K"], v["B"], v["J"])
    num, den = tf_full(v["Ra"], v["La"], v["K"], v["B"], v["J"])
    return {
        "source": ctx.best_label,
        "run": str(ctx.run_dir),
        "session": ctx.summary["session"]["name"],
        "names": list(ctx.names),
        "units": {n: ctx.summary["parameters"][n]["unit"] for n in ctx.names},
        "parameters": {n: float(v[n]) for n in ctx.names},
        "covariance": ctx.covariance().tolist(),
        "state": ["omega (rad/s)", "ia (A)"],
        "input": ["TL (N*m)", "Va (V)"],
        "output": ["omega (rad/s)"],
        "A": A.tolist(), "B": Bu.tolist(), "C": C.tolist(), "D": D.tolist(),
        "transfer_function": {"input": "Va (V)", "output": "omega (rad/s)",
                              "num": [float(x) for x in num], "den": [float(x) for x in den]},
        "first_order": {"gain": float(gain(v["Ra"], v["K"], v["B"])),
                        "tau": float(time_constant(v["Ra"], v["K"], v["B"], v["J"]))},
        "coulomb_friction": float(v.get("Tc", 0.0)),
        "notes": ("Linear model of equations (11)-(14); Coulomb friction Tc (N*m), when "
                  "identified, acts as a constant load torque opposing the motion and is "
                  "not part of A, B, C, D. The parameter covariance is in SI units, in the "
                  "order of 'names'."),
    }


def to_control(model: dict):
    """``(StateSpace, TransferFunction)`` of python-control from :func:`controller_model`.

    Raises ImportError with the install hint when ``control`` is missing.
    """
    try:
        import control
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("python-control is not installed; pip install "
                          "'pmdc-bayes[control]'") from exc
    ss = control.ss(np.asarray(model["A"]), np.asarray(model["B"]), np.asarray(model["C"]),
                    np.asarray(model["D"]), inputs=["TL", "Va"], outputs=["omega"],
                    states=["omega", "ia"])
    tf = control.tf(model["transfer_function"]["num"], model["transfer_function"]["den"],
                    inputs="Va", outputs="omega")
    return ss, tf
