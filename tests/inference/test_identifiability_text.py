"""The identifiability findings name each parameter in the coordinates the fit uses:
``log K`` for a positive parameter, the parameter itself for one that may be zero or
negative (a dead time, a sensor offset)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pmdc_bayes.inference.identifiability import identifiability

NAMES = ("Ra", "La", "K", "B", "J", "dead_time_step")


def _spec(transform):
    return SimpleNamespace(transform=transform, prior=SimpleNamespace(source="prior"))


def test_a_weak_direction_names_a_dead_time_without_a_log():
    corr = np.eye(6)
    corr[4, 5] = corr[5, 4] = 0.99995  # J and the dead time: one barely constrained sum
    fit = SimpleNamespace(names=NAMES, corr=corr, cov_log=np.diag([1e-4] * 6),
                          values={"La": 1e-3, "Ra": 2.0})
    model = SimpleNamespace(
        prior_sd=np.ones(6),
        registry={n: _spec("identity" if n == "dead_time_step" else "log") for n in NAMES},
        session=SimpleNamespace(traces=[SimpleNamespace(current=np.zeros(3), dt=1e-4)],
                                coast_downs=(), nuisances=()))
    (finding,) = [f for f in identifiability(model, fit)["findings"] if "barely" in f]
    assert "·log J" in finding and "·dead_time_step" in finding
    assert "log dead_time_step" not in finding
