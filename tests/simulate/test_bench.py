"""The non-ideal bench simulator against the motor's analytic behaviour."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import expm

from pmdc_bayes.io.session import Schedule, Session
from pmdc_bayes.paper.closed_form import closed_form
from pmdc_bayes.simulate.bench import BenchMotor, StepSpec, bench_session, steady_point

RA, LA, K, B, J = 2.0, 2e-3, 0.05, 2e-5, 2e-5
DEN = RA * B + K**2
TAU = J * RA / DEN  # ≈ 15.7 ms
V = 12.0
W_FINAL = K * V / DEN  # ≈ 236 rad/s
QUIET = BenchMotor(RA, LA, K, B, J, speed_noise=0.0, current_noise=0.0)


def one(motor: BenchMotor, duration=16 * TAU, dt=5e-4, **kw):
    """The single trace of a one-step session."""
    return bench_session(motor, [StepSpec("s", V, duration, dt, **kw)]).traces[0]


def t63(tr, t0=0.0):
    """Time after ``t0`` at which the speed first reaches 63.2 % of its final value."""
    k = int(np.argmax(tr.speed >= (1 - np.exp(-1)) * tr.speed[-1]))
    t, y, y63 = tr.time, tr.speed, (1 - np.exp(-1)) * tr.speed[-1]
    return t[k - 1] + (y63 - y[k - 1]) * (t[k] - t[k - 1]) / (y[k] - y[k - 1]) - t0


def test_ideal_motor_matches_the_exact_linear_solution():
    tr = one(QUIET, duration=0.1)
    A = np.array([[-RA / LA, -K / LA], [K / J, -B / J]])
    b = np.array([V / LA, 0.0])
    x = np.array([np.linalg.solve(A, (expm(A * t) - np.eye(2)) @ b) for t in tr.time]).T
    assert np.max(np.abs(tr.current - x[0])) < 1e-6
    assert np.max(np.abs(tr.speed - x[1])) < 1e-4 * W_FINAL


def test_final_speed_and_current_are_the_steady_state_within_noise():
    motor = replace(QUIET, speed_noise=0.05, current_noise=0.002)
    tr = one(motor)
    tail = slice(-100, None)
    assert abs(tr.speed[tail].mean() - W_FINAL) < 4 * 0.05 / 10
    assert abs(tr.current[tail].mean() - B * V / DEN) < 4 * 0.002 / 10
    assert np.std(tr.speed[tail]) == pytest.approx(0.05, rel=0.25)


def test_rise_time_is_the_mechanical_time_constant_when_la_is_small():
    tr = one(replace(QUIET, La=1e-4), dt=1e-4)
    assert t63(tr) == pytest.approx(TAU, rel=0.05)


def test_dead_time_shifts_the_response():
    t_step, dead, dt = 0.01, 0.005, 5e-4
    ref = one(QUIET, dt=dt, t_step=t_step)
    late = one(replace(QUIET, dead_time=dead), dt=dt, t_step=t_step)
    k = int(round(dead / dt))
    assert np.all(late.speed[late.time <= t_step + dead] == 0.0)
    assert np.max(np.abs(late.speed[k:] - ref.speed[:-k])) < 1e-4 * W_FINAL
    assert np.max(np.abs(late.current[k:] - ref.current[:-k])) < 1e-6
    assert np.array_equal(late.voltage.times, [0.0, t_step])  # the session declares no delay


def test_brush_drop_lowers_the_final_speed_by_the_analytic_amount():
    drop = 0.8
    ref, dropped = one(QUIET), one(replace(QUIET, voltage_drop=drop))
    assert ref.speed[-1] - dropped.speed[-1] == pytest.approx(K * drop / DEN, rel=1e-3)
    assert dropped.current[-1] == pytest.approx(B * (V - drop) / DEN, rel=1e-3)


def test_source_resistance_acts_as_extra_armature_resistance():
    rs = 0.6
    sourced = one(replace(QUIET, source_resistance=rs), duration=0.1)
    heavier = one(replace(QUIET, Ra=RA + rs), duration=0.1)
    assert np.max(np.abs(sourced.speed - heavier.speed)) < 1e-4 * W_FINAL
    assert np.max(np.abs(sourced.current - heavier.current)) < 1e-6
    ia, w = steady_point(replace(QUIET, source_resistance=rs), V)
    den = (RA + rs) * B + K**2
    assert (w, ia) == pytest.approx((K * V / den, B * V / den), rel=1e-12)


def test_current_limit_gives_a_flat_top_of_the_analytic_length():
    limit, dt = 2.0, 1e-4
    free = one(QUIET, dt=dt, duration=0.1)
    assert free.current.max() > 2 * limit
    noisy = one(replace(QUIET, current_limit=limit, current_noise=0.002), dt=dt, duration=0.1)
    assert noisy.current.max() < limit + 5 * 0.002
    tr = one(replace(QUIET, current_limit=limit), dt=dt, duration=0.2)
    assert tr.current.max() <= limit * (1 + 1e-6)
    at_limit = tr.time[np.abs(tr.current - limit) < 1e-3 * limit]
    # Held at the limit: J·dω/dt = K·I − B·ω until the back-emf leaves V − Ra·I.
    t_exit = -J / B * np.log(1 - (V - RA * limit) / K * B / (K * limit))
    assert at_limit[0] < 1e-3
    assert at_limit[-1] == pytest.approx(t_exit, abs=1e-3)
    assert at_limit.size == pytest.approx((at_limit[-1] - at_limit[0]) / dt + 1, abs=1)
    assert tr.speed[-1] == pytest.approx(W_FINAL, rel=1e-3)  # the limit only slows the start


def test_sensor_lag_delays_the_logged_speed_by_the_lag():
    lag, dt = 2e-3, 1e-4
    ref, lagged = one(QUIET, dt=dt), one(replace(QUIET, speed_lag=lag), dt=dt)
    assert t63(lagged) - t63(ref) == pytest.approx(lag, rel=0.15)
    # First-order filter of a step response: ∫(ω − ω_logged) dt = lag · ω_final.
    gap = ref.speed - lagged.speed
    area = np.sum((gap[1:] + gap[:-1]) / 2) * dt
    assert area == pytest.approx(lag * W_FINAL, rel=1e-3)


def test_extra_load_lowers_only_its_own_trace_and_is_not_declared():
    const, visc = 2e-3, 1e-5
    motor = replace(QUIET, extra_load={"loaded": (const, visc)})
    steps = [StepSpec("plain", V, 16 * TAU, 5e-4), StepSpec("loaded", V, 16 * TAU, 5e-4)]
    s = bench_session(motor, steps, steady_voltages=(V,))
    plain, loaded = s.traces
    assert plain.speed[-1] == pytest.approx(W_FINAL, rel=1e-3)
    expected = (K * V - RA * const) / (RA * (B + visc) + K**2)
    assert loaded.speed[-1] == pytest.approx(expected, rel=1e-3)
    assert np.array_equal(loaded.load_torque.values, [0.0])
    assert s.steady_tables[0].speed[0] == pytest.approx(W_FINAL, rel=0.015)


def test_encoder_speed_is_quantised_and_integrates_to_the_angle():
    counts, dt = 500, 1e-3
    tr = one(replace(QUIET, encoder_counts_per_rev=counts, speed_noise=0.05), dt=dt)
    quantum = 2 * np.pi / counts / dt
    n = tr.speed / quantum
    assert np.allclose(n, np.round(n), atol=1e-9)
    assert len(np.unique(np.round(n[-50:]))) >= 2  # the estimate dithers between levels
    exact = one(QUIET, dt=dt)
    angle = np.sum((exact.speed[1:] + exact.speed[:-1]) / 2) * dt
    assert np.sum(tr.speed) * dt == pytest.approx(angle, abs=2 * np.pi / counts + 1e-3)


def test_speed_gain_scales_the_logged_speed_and_the_steady_table():
    gain = 1.05
    s = bench_session(replace(QUIET, speed_gain=gain), [StepSpec("s", V, 16 * TAU, 5e-4)],
                      steady_voltages=(6.0, V))
    assert s.traces[0].speed[-1] == pytest.approx(gain * W_FINAL, rel=1e-3)
    table = s.steady_tables[0]
    assert table.speed == pytest.approx(gain * K * table.voltage / DEN, rel=0.015)
    assert table.current == pytest.approx(B * table.voltage / DEN, rel=0.015)


def test_coulomb_friction_running_and_stuck():
    tc = 1e-3
    tr = one(replace(QUIET, Tc=tc))
    assert tr.speed[-1] == pytest.approx((K * V - RA * tc) / DEN, rel=1e-3)
    low = 0.5 * tc * RA / K  # the driving torque K·V/Ra is half the Coulomb torque
    s = bench_session(replace(QUIET, Tc=tc), [StepSpec("s", low, 0.05, 5e-4)])
    assert np.all(s.traces[0].speed == 0.0)
    assert s.traces[0].current[-1] == pytest.approx(low / RA, rel=1e-6)
    assert steady_point(replace(QUIET, Tc=tc), low) == (pytest.approx(low / RA), 0.0)


def test_steady_table_has_brush_drop_but_not_extra_load():
    motor = replace(QUIET, voltage_drop=0.5, extra_load={"s": (1e-3, 0.0)})
    s = bench_session(motor, [StepSpec("s", V, 0.02, 1e-3)], steady_voltages=(4.0, 8.0))
    table = s.steady_tables[0]
    assert table.speed == pytest.approx(K * (table.voltage - 0.5) / DEN, rel=0.015)
    assert np.array_equal(table.load_torque, [0.0, 0.0])


def test_same_seed_same_data():
    motor = replace(QUIET, speed_noise=0.05, current_noise=0.002)
    steps = [StepSpec("a", V, 0.05, 1e-3), StepSpec("b", 6.0, 0.05, 1e-3, t_step=0.01)]
    s1, s2 = (bench_session(motor, steps, seed=3, steady_voltages=(V,)) for _ in range(2))
    s3 = bench_session(motor, steps, seed=4, steady_voltages=(V,))
    assert s1.Ra == s2.Ra and s1.La == s2.La
    for a, b in zip(s1.traces, s2.traces, strict=True):
        assert np.array_equal(a.speed, b.speed) and np.array_equal(a.current, b.current)
    assert np.array_equal(s1.steady_tables[0].speed, s2.steady_tables[0].speed)
    assert not np.array_equal(s1.traces[0].speed, s3.traces[0].speed)
    assert s1.Ra.value != s3.Ra.value


def test_session_layout():
    steps = [StepSpec("up", V, 0.05, 1e-3, t_step=0.01, load=1e-3),
             StepSpec("speed_only", 6.0, 0.05, 1e-3, log_current=False)]
    s = bench_session(BenchMotor(RA, LA, K, B, J), steps, seed=1,
                      La_bench=(1.9e-3, 1e-4), friction="coulomb", name="rig")
    assert isinstance(s, Session) and s.name == "rig" and s.friction == "coulomb"
    assert s.truth == {"Ra": RA, "La": LA, "K": K, "B": B, "J": J, "Tc": 0.0}
    assert s.Ra.sd == pytest.approx(0.03 * RA) and abs(s.Ra.value - RA) < 5 * s.Ra.sd
    assert (s.La.value, s.La.sd, s.La.unit) == (1.9e-3, 1e-4, "H")
    assert s.steady_tables == () and s.operating_points == ()
    up, only = s.traces
    assert (up.kind, up.initial, str(up.file)) == ("step", "rest", "up.csv")
    assert isinstance(up.voltage, Schedule) and up.voltage.values.dtype == float
    assert np.array_equal(up.voltage.times, [0.0, 0.01])
    assert np.array_equal(up.voltage.values, [0.0, V])
    assert np.array_equal(up.load_torque.values, [1e-3])
    assert np.array_equal(only.voltage.times, [0.0]) and only.current is None
    assert up.n == 51 and up.dt == pytest.approx(1e-3)


def test_closed_form_reads_an_ideal_session():
    steps = [StepSpec("s6", 6.0, 16 * TAU, 5e-4, t_step=0.01),
             StepSpec("s12", V, 16 * TAU, 5e-4, t_step=0.01)]
    s = bench_session(BenchMotor(RA, LA, K, B, J), steps, Ra_bench=(RA, 0.01),
                      steady_voltages=(6.0, V))
    cf = closed_form(s)
    assert cf.K == pytest.approx(K, rel=1e-3)
    assert cf.B == pytest.approx(B, rel=0.05)
    assert cf.J == pytest.approx(J, rel=0.15)  # τ read off a step that has La in it


def test_bad_specs_are_refused():
    with pytest.raises(ValueError, match="duplicate"):
        bench_session(QUIET, [StepSpec("a", V, 0.01, 1e-3)] * 2)
    with pytest.raises(ValueError, match="extra_load"):
        bench_session(replace(QUIET, extra_load={"b": (1e-3, 0.0)}),
                      [StepSpec("a", V, 0.01, 1e-3)])
    with pytest.raises(ValueError, match="t_step"):
        bench_session(QUIET, [StepSpec("a", V, 0.01, 1e-3, t_step=0.02)])
