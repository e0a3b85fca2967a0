"""Nuisance parameters fitted with the motor on benches that have them (the richer
simulator of :mod:`pmdc_bayes.simulate.bench`, not the package's own model), and on
the ideal bench where they must come out zero."""

import dataclasses

import pytest
from conftest import fit_and_assess

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.session import Drag
from pmdc_bayes.simulate.cases import CASES, MOTOR, case_session


def _fit(case, nuisances):
    _, _, fit, verdict = fit_and_assess(case_session(case), nuisances=nuisances)
    return fit, verdict


def _within(fit, name, truth, n_sd=4.0, floor=0.0):
    return abs(fit.values[name] - truth) <= n_sd * fit.sd[name] + floor


@pytest.mark.compiles
def test_a_fitted_dead_time_recovers_the_bench_delay_and_the_motor():
    fit, a = _fit("dead time", ("dead_time",))
    delay = CASES["dead time"][0]["dead_time"]
    assert a.verdict == "adequate", a.headline()
    for name in ("dead_time_step_12v", "dead_time_step_6v"):
        assert fit.values[name] == pytest.approx(delay, rel=0.02)
    for name in ("K", "J", "La"):
        assert fit.values[name] == pytest.approx(MOTOR[name], rel=0.02)


@pytest.mark.compiles
def test_a_shared_dead_time_recovers_the_bench_delay_and_the_motor():
    """The bench simulator's one driver delay, fitted as one dead time for both traces."""
    session = dataclasses.replace(case_session("dead time"), nuisances=("dead_time",),
                                  shared_dead_time=True)
    cf = fit_seed(session)
    model = build_model(session, cf)
    assert [n for n in model.names if n.startswith("dead_time")] == ["dead_time"]
    fit = fit_map(model)
    assert assess(model, fit, cf).verdict == "adequate"
    assert fit.values["dead_time"] == pytest.approx(CASES["dead time"][0]["dead_time"],
                                                    rel=0.02)
    for name in ("K", "J", "La"):
        assert fit.values[name] == pytest.approx(MOTOR[name], rel=0.02)


@pytest.mark.compiles
def test_a_fitted_voltage_drop_recovers_the_brush_drop():
    fit, a = _fit("brush drop", ("voltage_drop",))
    assert a.verdict == "adequate", a.headline()
    assert fit.values["Vdrop"] == pytest.approx(CASES["brush drop"][0]["voltage_drop"], rel=0.02)
    assert fit.values["K"] == pytest.approx(MOTOR["K"], rel=0.02)


@pytest.mark.compiles
def test_nuisances_the_bench_lacks_come_out_zero():
    fit, a = _fit(None, ("dead_time", "voltage_drop"))
    assert a.verdict == "adequate", a.headline()
    assert _within(fit, "Vdrop", 0.0)
    for name in ("dead_time_step_12v", "dead_time_step_6v"):
        assert _within(fit, name, 0.0, floor=1e-6)


@pytest.mark.compiles
@pytest.mark.parametrize(("case", "index", "name", "kind"), [
    ("unknown load", 0, "load_step_6v", "both"),
    ("unknown viscous load", 1, "drag_step_6v", "both"),
    ("unknown viscous load", 1, "drag_step_6v", "viscous")])
def test_an_unknown_drag_on_one_trace_is_recovered(case, index, name, kind):
    """A brake on step_6v (a friction-like or a viscous drag, in the bench simulator's
    stick-slip model): fitted as that trace's unknown load (both parts, or the viscous
    part alone when the session says so), the model is adequate, the drag is recovered
    within 3 sd and the motor within 3 sd of the truth."""
    session = dataclasses.replace(case_session(case), nuisances=("unknown_load",),
                                  loaded_traces=("step_6v",),
                                  load_kinds=(("step_6v", kind),))
    cf = fit_seed(session)
    model = build_model(session, cf)
    assert ("load_step_6v" in model.names) == (kind == "both")
    assert model.coulomb_path and not model.coulomb
    fit = fit_map(model)
    a = assess(model, fit, cf)
    assert a.verdict == "adequate", a.headline()
    truth = CASES[case][0]["extra_load"]["step_6v"][index]
    assert _within(fit, name, truth, n_sd=3.0), (fit.values[name], fit.sd[name], truth)
    for motor in ("K", "B", "J", "Ra"):
        assert _within(fit, motor, MOTOR[motor], n_sd=3.0), (motor, fit.values[motor],
                                                             fit.sd[motor])
    assert "load_step_12v" not in fit.values


@pytest.mark.compiles
def test_a_speed_sensor_calibration_error_is_honest_then_recovered_with_a_bench_k():
    """A tachometer reading 5 % high with a 0.5 rad/s offset.  A gain on the speed is
    the same as a K, J and B scaled together (the armature equation sees K·ω, the
    mechanical one is homogeneous in K, J, B), so steps alone cannot tell it: the ideal
    model returns K 5 % off and tight; fitting the gain widens K to the gain's prior
    and covers the truth, and says the gain is prior-dominated.  A bench K at 1 %
    then pins the gain.  The offset is identified either way."""
    from pmdc_bayes.io.session import Measurement
    from pmdc_bayes.simulate.bench import BenchMotor, bench_session
    from pmdc_bayes.simulate.cases import STEPS

    gain, offset = 1.05, 0.5
    session = bench_session(BenchMotor(**MOTOR, speed_gain=gain), STEPS, seed=2)
    session = dataclasses.replace(session, traces=tuple(
        dataclasses.replace(tr, speed=tr.speed + offset) for tr in session.traces))
    cf = fit_seed(session)
    ideal = fit_map(build_model(session, cf))
    assert not _within(ideal, "K", MOTOR["K"])  # the ideal model is misled, confidently
    calibrated = dataclasses.replace(session, nuisances=("speed_gain", "speed_offset"))
    model = build_model(calibrated, cf)
    fit = fit_map(model)
    assert assess(model, fit, cf).verdict == "adequate"
    assert fit.sd["speed_gain"] > 0.05  # the prior's 10 %: the data say nothing of it
    assert _within(fit, "speed_offset", offset, 3.0) and fit.sd["speed_offset"] < 0.1
    for name in ("K", "J", "B"):
        assert _within(fit, name, MOTOR[name], 3.0), (name, fit.values[name], fit.sd[name])
    bench_k = {"K": Measurement(MOTOR["K"] * 1.004, 0.01 * MOTOR["K"], "V*s/rad", "bench")}
    # the ideal model against a bench K: rejected, and the diagnosis names the gain
    ideal_k = dataclasses.replace(session, bench=bench_k)
    model = build_model(ideal_k, cf)
    verdict = assess(model, fit_map(model), cf)
    assert verdict.verdict == "inadequate"
    assert any("--add speed-gain" in line for line in verdict.diagnosis), verdict.diagnosis
    with_k = dataclasses.replace(calibrated, bench=bench_k)
    model = build_model(with_k, cf)
    fit = fit_map(model)
    assert _within(fit, "speed_gain", gain, 3.0) and fit.sd["speed_gain"] < 0.02
    assert _within(fit, "J", MOTOR["J"], 3.0)


@pytest.mark.compiles
def test_a_fitted_source_resistance_splits_the_circuit_from_the_bench_ra():
    """The logged voltage is the supply's: the circuit sees Ra + Rs.  The ideal model
    puts it all in Ra (a bench conflict); fitting Rs leaves Ra at the bench value and
    recovers Rs and the motor."""
    rs = CASES["source resistance"][0]["source_resistance"]
    fit, a = _fit("source resistance", ("source_resistance",))
    assert a.verdict == "adequate", a.headline()
    assert _within(fit, "Rs", rs, 3.0) and fit.sd["Rs"] < 0.2 * rs
    for name in ("Ra", "K", "J", "La"):
        assert _within(fit, name, MOTOR[name], 3.0), (name, fit.values[name], fit.sd[name])


@pytest.mark.compiles
@pytest.mark.parametrize("case", ["unknown load", "unknown viscous load"])
def test_a_declared_speed_dependent_load_is_fitted_around(case):
    """The bench's load on one trace, declared as that trace's known drag: the model
    carries it (exact stick-slip for the constant part), is adequate and recovers the
    motor; the same session without the declaration is rejected."""
    drag = CASES[case][0]["extra_load"]["step_6v"]
    session = case_session(case)
    declared = dataclasses.replace(session, traces=tuple(
        dataclasses.replace(tr, drag=Drag(*drag)) if tr.name == "step_6v" else tr
        for tr in session.traces))
    cf = fit_seed(declared)
    model = build_model(declared, cf)
    fit = fit_map(model)
    assert assess(model, fit, cf).verdict == "adequate"
    for name in ("K", "J", "B", "La"):
        assert _within(fit, name, MOTOR[name], 3.0), (name, fit.values[name], fit.sd[name])
    cf = fit_seed(session)
    model = build_model(session, cf)
    assert assess(model, fit_map(model), cf).verdict == "inadequate"


@pytest.mark.compiles
@pytest.mark.parametrize("current_logged", [True, False])
def test_a_fitted_current_limit_recovers_the_driver_and_the_motor(current_logged):
    """The bench's driver holds the current at 2 A at the start of each step: the ideal
    model is rejected and points to the limit; with ``current_limit`` the model is
    adequate, the limit and the motor are recovered within 3 sd, from the traces'
    currents or, with speed-only traces, from the ramp of the speed (a meter's steady
    currents giving K)."""
    session = case_session("current limit")
    if not current_logged:
        session = dataclasses.replace(session, traces=tuple(
            dataclasses.replace(tr, current=None) for tr in session.traces))

    def fit_with(nuisances):
        s = dataclasses.replace(session, nuisances=nuisances)
        cf = fit_seed(s)
        model = build_model(s, cf)
        fit = fit_map(model)
        return fit, assess(model, fit, cf)

    fit, a = fit_with(())
    assert a.verdict == "inadequate"
    assert "--add current-limit" in " ".join(a.diagnosis)
    fit, a = fit_with(("current_limit",))
    assert a.verdict == "adequate", a.headline()
    limit = CASES["current limit"][0]["current_limit"]
    assert _within(fit, "Imax", limit, n_sd=3.0), (fit.values["Imax"], fit.sd["Imax"])
    for motor in ("K", "B", "J", "Ra", "La"):
        assert _within(fit, motor, MOTOR[motor], n_sd=3.0), (motor, fit.values[motor],
                                                             fit.sd[motor])
