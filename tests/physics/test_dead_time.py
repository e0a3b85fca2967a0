"""A dead time is the inputs' breakpoints moved later: the experiment delayed by
``Experiment.delayed`` reads, at every sample, what the same experiment built with its
inputs moved reads, however close the input changes lie (steps before the response
settles, a voltage logged at every sample), on every solution path (viscous, Coulomb,
current limit), through sensor lags and for the angle."""

import jax.numpy as jnp
import numpy as np
import pytest

from pmdc_bayes._x64 import x64
from pmdc_bayes.physics.angle import since_first_sample
from pmdc_bayes.physics.experiment import stack_experiments
from pmdc_bayes.physics.solution import Params, simulate_padded

# the tests call the physics directly, as the package calls it inside its 64-bit context
pytestmark = pytest.mark.usefixtures("jax_x64")

P = Params(Ra=2.0, La=2e-3, K=0.05, B=1e-5, J=2e-5, Tc=2e-3)
T = np.arange(0.0, 0.2, 1e-3)
# the first trace steps twice 20 ms apart (far from settled); the second logs a
# voltage that changes at every sample after 10 ms of rest
STEPS = (np.array([0.0, 0.0105, 0.0305, 0.12]), np.array([0.0, 12.0, 6.0, -8.0]))
LOGGED = (T.copy(), np.where(T < 0.01, 0.0,
                             9.0 + np.random.default_rng(3).normal(0.0, 2.0, T.size)))
DELAYS = np.array([0.0073, 0.0035])  # 7.3 and 3.5 samples


@x64
def _run(schedules, delays, **kw):
    specs = [(T, vt, vv, None, None, "rest") for vt, vv in schedules]
    exp = stack_experiments(specs)
    if delays is not None:
        exp = exp.delayed(jnp.asarray(delays))
    ia, w, angle = simulate_padded(P, exp, with_angle=True, **kw)
    start = jnp.asarray(np.concatenate([np.arange(T.size) == 0] * len(schedules)))
    return tuple(np.asarray(x) for x in
                 (exp.unpad(ia), exp.unpad(w), since_first_sample(exp, angle, start)))


@pytest.mark.parametrize("kw", [dict(), dict(coulomb=True), dict(limit=2.5),
                                dict(coulomb=True, limit=2.5, lags=(3e-4, 4e-3))],
                         ids=["viscous", "coulomb", "limit", "coulomb-limit-lags"])
def test_a_delayed_experiment_reads_as_its_inputs_moved_later(kw):
    delayed = _run([STEPS, LOGGED], DELAYS, **kw)
    moved = _run([(vt + d, vv) for (vt, vv), d in zip([STEPS, LOGGED], DELAYS, strict=True)],
                 None, **kw)
    for got, want in zip(delayed, moved, strict=True):
        np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())
    plain = _run([STEPS, LOGGED], None, **kw)
    # and the delay matters: many samples of the logged trace differ by far more
    assert np.abs(delayed[1] - plain[1]).max() > 0.1 * np.abs(plain[1]).max()


@pytest.mark.parametrize("kw", [dict(), dict(coulomb=True), dict(coulomb=True, drop=1.0)],
                         ids=["viscous", "coulomb", "coulomb-drop"])
def test_a_negative_dead_time_leads_the_inputs(kw):
    """12 V, then 0 V from 0.15 s; the response leads by 50 ms, so the rotor's stop
    (and, under a drop, the current's end) falls after the trace's last input, where it
    is still located."""
    lead = 0.05
    schedule = (np.array([0.0, 0.06, 0.15]), np.array([0.0, 12.0, 0.0]))
    delayed = _run([schedule], np.array([-lead]), **kw)
    moved = _run([(schedule[0] - lead, schedule[1])], None, **kw)
    for got, want in zip(delayed, moved, strict=True):
        np.testing.assert_allclose(got, want, atol=1e-9 * np.abs(want).max())


@x64
def _shifted(schedules, shifts, delays, **kw):
    """``schedules`` simulated with each segment starting ``shifts[trace][j]`` earlier
    (its ``j``-th breakpoint's change) and each trace ``delays`` later."""
    specs = [(T, vt, vv, None, None, "rest") for vt, vv in schedules]
    exp = stack_experiments(specs)
    t0, trace = np.asarray(exp.seg_t0), np.asarray(exp.seg_trace)
    shift = np.zeros(t0.size)
    for k, ((vt, _), s) in enumerate(zip(schedules, shifts, strict=True)):
        for when, by in zip(vt, s, strict=True):
            shift[(trace == k) & np.isclose(t0, when)] = by
    exp = exp.delayed(jnp.asarray(delays), jnp.asarray(shift))
    ia, w, angle = simulate_padded(P, exp, with_angle=True, **kw)
    start = jnp.asarray(np.concatenate([np.arange(T.size) == 0] * len(schedules)))
    return tuple(np.asarray(x) for x in
                 (exp.unpad(ia), exp.unpad(w), since_first_sample(exp, angle, start)))


@pytest.mark.parametrize("kw", [dict(), dict(coulomb=True, limit=2.5, lags=(3e-4, 4e-3))],
                         ids=["viscous", "coulomb-limit-lags"])
def test_each_change_shifted_earlier_reads_as_its_breakpoint_moved(kw):
    """A logged column's changes, each made its own time before the sample that shows it
    (``Experiment.delayed``'s ``shift``, per segment), and a dead time on top: the same
    as the inputs' breakpoints moved by as much, each by its own."""
    steps = (np.array([0.0, 0.011, 0.031, 0.12]), np.array([0.0, 12.0, 6.0, -8.0]))
    shifts = [np.array([0.0, 7e-4, 2e-4, 9e-4])]
    for delay in (0.0, 0.0035):
        got = _shifted([steps], shifts, np.array([delay]), **kw)
        want = _run([(steps[0] - shifts[0] + delay, steps[1])], None, **kw)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_allclose(g, w, atol=1e-9 * np.abs(w).max())
    # one shift for every change, the trace's start too, is the trace led by as much
    same = [np.full(4, 6e-4)]
    got = _shifted([steps], same, np.array([0.0]), **kw)
    want = _run([steps], np.array([-6e-4]), **kw)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, atol=1e-9 * np.abs(w).max())
