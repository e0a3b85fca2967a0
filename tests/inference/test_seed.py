"""Where a fit starts when the paper's method cannot run: the time constant is read from
whatever response the session has (a load change, a voltage reversal, a coast-down),
over the span up to the next change, and J follows from it."""

import numpy as np
import pytest

from pmdc_bayes._errors import SessionError
from pmdc_bayes.inference.model.first_order import integral_fit
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.io.session import Schedule
from pmdc_bayes.simulate.session import simulate_session

TRUTH = {"Ra": 2.0, "La": 2e-3, "K": 0.05, "B": 2e-5, "J": 2e-5, "Tc": 0.0}
STEADY = {"name": "steady", "voltages": [4.0, 8.0, 12.0], "speed_sd": 0.1,
          "current_sd": 0.0005}


def _session(tmp_path, traces, steady=True):
    plan = {"seed": 2, "motor": {"name": "seed motor", "friction": "viscous"}, "truth": TRUTH,
            "bench": {"Ra": {"sd": 0.05, "unit": "ohm"}},
            "steady_table": [STEADY] if steady else [], "trace": traces}
    return load_session(simulate_session(plan, tmp_path / "s"))


def _trace(name, **kw):
    return {"name": name, "duration": 0.3, "rate": 2000.0, "speed_noise": 0.05,
            "current_noise": 0.0, "record_current": False, **kw}


def test_a_load_change_alone_seeds_the_time_constant(tmp_path):
    """Running at 12 V, then a brake: the speed falls with the mechanical time constant."""
    s = _session(tmp_path, [_trace("brake", kind="load_change", initial="steady",
                                   voltage=[[0.0, 12.0]],
                                   load_torque=[[0.0, 0.0], [0.05, 0.004]])])
    cf = fit_seed(s)
    assert not cf.applicable
    assert "'brake' after its change at 0.05 s" in cf.used["tau"]
    tau_m = TRUTH["J"] * TRUTH["Ra"] / (TRUTH["Ra"] * TRUTH["B"] + TRUTH["K"] ** 2)
    assert cf.tau == pytest.approx(tau_m, rel=0.1)
    assert cf.J == pytest.approx(TRUTH["J"], rel=0.15)


def test_the_largest_change_is_read_up_to_the_next_one(tmp_path):
    """+12 V from rest, then -12 V: the reversal (24 V) is the largest change; its
    response is read before anything else changes, whatever the trace's kind."""
    s = _session(tmp_path, [_trace("rev", kind="free-form", initial="rest",
                                   voltage=[[0.0, 0.0], [0.01, 12.0], [0.12, -12.0],
                                            [0.24, 0.0]])])
    cf = fit_seed(s)
    assert "'rev' after its change at 0.12 s" in cf.used["tau"]
    assert cf.J == pytest.approx(TRUTH["J"], rel=0.15)


def test_a_session_with_no_response_names_what_to_add(tmp_path):
    s = _session(tmp_path, [_trace("flat", kind="free-form", initial="steady",
                                   voltage=[[0.0, 12.0]])])
    with pytest.raises(SessionError, match="voltage or load changes, a coast-down"):
        fit_seed(s)


def test_stuck_at_no_steady_level_is_still_refused(tmp_path):
    s = _session(tmp_path, [_trace("flat", kind="free-form", initial="rest",
                                   voltage=[[0.0, 0.0]])], steady=False)
    with pytest.raises(SessionError, match="no steady speed"):
        fit_seed(s)


def _chirp(t_end=0.4, n=400):
    """A voltage sweeping 1 → 40 Hz around 6 V, as a schedule of ``n`` held levels."""
    t = np.linspace(0.0, t_end, n, endpoint=False)
    v = 6.0 + 4.0 * np.sin(2 * np.pi * (1.0 * t + 0.5 * 39.0 * t**2 / t_end))
    return [[float(a), float(round(b, 4))] for a, b in zip(t, v, strict=True)]


def _random_sequence(t_end=0.4, seed=5):
    """Two voltages, 2 and 10 V, each held 2–10 ms (the motor's τ is 16 ms): a random
    binary sequence none of whose levels settles."""
    rng = np.random.default_rng(seed)
    out, t, level = [], 0.0, 2.0
    while t < t_end:
        out.append([round(t, 6), level])
        t, level = t + float(rng.uniform(0.002, 0.01)), 12.0 - level
    return out


@pytest.mark.parametrize(("rate", "voltage"), [
    (2000.0, _chirp()), (2000.0, _chirp(n=399)), (2500.0, _chirp()), (1000.0, _chirp(n=100)),
    (5000.0, _chirp(n=60)), (2000.0, _random_sequence()), (5000.0, _random_sequence(seed=6)),
])
@pytest.mark.parametrize("steady", [True, False])
def test_a_swept_input_seeds_the_time_constant_from_its_integral_form(tmp_path, steady, rate,
                                                                      voltage):
    """A chirp (of several sample rates and numbers of held levels) or a random binary
    sequence on the independent bench: no response settles before the input next
    changes, so τ (and without a steady table the gain) come from a first-order model
    fitted to the whole trace; J follows within a few per cent of the truth."""
    plan = {"seed": 3, "motor": {"name": "chirp motor", "friction": "viscous"},
            "truth": TRUTH, "rig": {}, "bench": {"Ra": {"sd": 0.05, "unit": "ohm"}},
            "steady_table": [STEADY] if steady else [],
            "trace": [_trace("sweep", kind="free-form", initial="rest", duration=0.4,
                             rate=rate, voltage=voltage)]}
    s = load_session(simulate_session(plan, tmp_path / "s"))
    cf = fit_seed(s)
    assert "'sweep' in integral form" in cf.used["tau"]
    tau_m = TRUTH["J"] * TRUTH["Ra"] / (TRUTH["Ra"] * TRUTH["B"] + TRUTH["K"] ** 2)
    assert cf.tau == pytest.approx(tau_m, rel=0.1)
    assert cf.J == pytest.approx(TRUTH["J"], rel=0.15)
    assert cf.K == pytest.approx(TRUTH["K"], rel=0.15)


def test_the_integral_form_refuses_a_record_without_a_decay():
    """Speed that does not follow its input (a constant reading under a varying one, or
    one that runs away with none) gives no time constant rather than a negative or
    endless one."""
    t = np.linspace(0.0, 0.4, 400)
    sched = Schedule(np.array([0.0, 0.1, 0.2, 0.3]), np.array([1.0, 5.0, 2.0, 8.0]))
    assert integral_fit(t, np.full(t.size, 3.0), sched) is None
    rising = 50.0 * t**2
    assert integral_fit(t, rising, Schedule(np.array([0.0]), np.array([0.0]))) is None


def test_a_response_of_a_few_samples_is_not_judged_settled():
    """Fewer than two windows of three samples say nothing of a level reached (and
    raise no warning of an empty mean)."""
    import warnings

    from pmdc_bayes.inference.model.levels import settled

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not settled(np.array([1.0, 1.0, 1.0, 1.0, 1.0]))
        assert settled(np.ones(6))
