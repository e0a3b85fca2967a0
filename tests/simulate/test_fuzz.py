"""The session fuzzer: every shape it promises appears in valid sessions the loader reads,
the truth is recorded (the motor's, and the rig's for a non-ideality), the same seed
gives the same bytes, and the formats plans cannot say (a voltage column, a step
reading) hold what the rig did."""

import json

import numpy as np
import pytest

from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.fuzz import (
    EXCITATION_SHAPES,
    NON_IDEALITIES,
    TRACE_SHAPES,
    column_reading,
    fuzz_files,
    fuzz_motor,
    fuzz_plan,
    fuzz_session,
)
from pmdc_bayes.simulate.plan import check_plan

MOTOR = ("Ra", "La", "K", "B", "J", "Tc")
FEATURES = {"quantised speed", "encoder position", "encoder edges", "voltage column",
            "noisy voltage column", "no trace current"}


def _labels(seed) -> set:
    """What the plan of ``seed`` holds, read off the plan alone (cheap)."""
    plan, extras = fuzz_plan(seed)
    out = set(extras["shapes"])
    for tr in plan["trace"]:
        enc = tr.get("encoder", {}).get("output")
        out |= {f"encoder {enc}"} if enc else set()
        out |= {"quantised speed"} if tr.get("speed_quantum") else set()
        out |= {"rpm"} if tr.get("speed_unit") == "rpm" else set()
    out |= {"voltage column"} if extras["columns"] else set()
    if any(column_reading(seed, name, plan) for name in extras["columns"]):
        out.add("noisy voltage column")
    out |= {"step reading"} if extras["step_reading"] else set()
    for tab in plan.get("steady_table", []):
        out.add("steady table" if "current_sd" in tab else "steady table without current")
    out |= {"operating point"} if "operating_point" in plan else set()
    if not any(t.get("record_current") for t in plan["trace"] if t["kind"] != "coast-down"):
        out.add("no trace current")
    return out


WANTED = set(TRACE_SHAPES) | FEATURES | {"steady table", "steady table without current",
                                         "operating point", "step reading", "rpm"}


def _covering_seeds() -> list[int]:
    """The first seed of each thing the fuzzer promises."""
    seeds, seen = [], set()
    for seed in range(400):
        new = (_labels(seed) & WANTED) - seen
        if new:
            seeds.append(seed)
            seen |= new
        if seen == WANTED:
            return seeds
    raise AssertionError(f"no seed below 400 draws {WANTED - seen}")


def test_every_shape_loads_with_its_truth(tmp_path):
    seen = set()
    for seed in _covering_seeds():
        f = fuzz_session(seed, out=tmp_path / f"s{seed}")
        s = load_session(f.path)
        seen |= set(f.shapes) | f.features
        assert {k: s.truth[k] for k in MOTOR} == {k: f.truth[k] for k in MOTOR}
        assert all(f.truth[k] > 0 for k in MOTOR if k != "Tc")
        assert len(s.traces) + len(s.coast_downs) == sum(x in TRACE_SHAPES for x in f.shapes)
        for tr in s.traces:
            assert tr.n >= 3 and np.all(np.diff(tr.time) > 0)
            if tr.speed_logged:
                assert np.all(np.isfinite(tr.speed))
        labels = _labels(seed)
        assert ("steady table" in labels) == any(t.current is not None
                                                 for t in s.steady_tables)
        assert ("operating point" in labels) == bool(s.operating_points)
        assert ("step reading" in labels) >= bool(s.step_readings)
        if "rpm" in labels:
            assert 'speed = "rpm"' in (f.path / "session.toml").read_text()
    assert (set(TRACE_SHAPES) | FEATURES) - {"step reading"} <= seen


@pytest.mark.parametrize("shape", EXCITATION_SHAPES)
def test_an_excitation_holds_no_level_long_enough_to_read_a_step_from(shape, tmp_path):
    """A sweep or a random sequence loads as a driven trace whose voltage stays within
    the motor's nominal range, changes many times and holds each level for well under
    the mechanical time constant on the median, and takes both signs in some sessions."""
    reversed_ = 0
    for seed in range(6):
        plan, _ = fuzz_plan(seed, shapes=(shape,))
        truth = plan["truth"]
        tau_m = truth["J"] * truth["Ra"] / (truth["K"] ** 2 + truth["Ra"] * truth["B"])
        rng = np.random.default_rng(seed)  # the plan's first draws: its motor
        nominal = fuzz_motor(rng, rng.uniform() < 0.3)[1]
        f = fuzz_session(seed, shapes=(shape,), out=tmp_path / f"{shape}{seed}")
        for tr in load_session(f.path).traces:
            changes = tr.voltage.change_times()
            assert changes.size >= 5
            assert np.median(np.diff(changes)) < tau_m
            assert np.all(np.abs(tr.voltage.values) <= nominal * (1.0 + 1e-9))
            reversed_ += bool(tr.voltage.values.min() < 0.0 < tr.voltage.values.max())
    assert reversed_ > 0


def test_a_shape_the_fuzzer_does_not_know_is_refused_naming_those_it_does():
    with pytest.raises(ValueError, match="unknown trace shape 'random'.*'random sequence'"):
        fuzz_plan(0, shapes=("random",))


def test_sizes_rates_and_noise_span_the_promised_ranges():
    ra, power, rates, noise = [], [], [], []
    for seed in range(120):
        plan, _ = fuzz_plan(seed)
        t = plan["truth"]
        ra.append(t["Ra"])
        w0 = max(tr["initial"]["speed"] for tr in plan["trace"] if tr["kind"] == "coast-down"
                 ) if any(tr["kind"] == "coast-down" for tr in plan["trace"]) else None
        power.append(t["K"] ** 2 / t["Ra"])  # stall torque per rad/s: the motor's size
        for tr in plan["trace"]:
            rates.append(tr["rate"])
            if "speed_noise" in tr and w0 is None:
                noise.append(tr["speed_noise"])
    assert np.log10(max(power) / min(power)) >= 4.0  # four decades of size and more
    assert min(rates) < 400 and max(rates) > 10_000
    assert len(noise) > 50


def test_same_seed_same_bytes(tmp_path):
    a, _, _ = fuzz_files(7)
    b, _, _ = fuzz_files(7)
    assert a == b
    fuzz_session(7, out=tmp_path / "x")
    fuzz_session(7, out=tmp_path / "y")
    for name in a:
        assert (tmp_path / "x" / name).read_bytes() == (tmp_path / "y" / name).read_bytes()
    assert fuzz_files(8)[0] != a


@pytest.mark.parametrize("key", NON_IDEALITIES)
def test_a_non_ideality_keeps_the_draw_and_records_its_truth(key, tmp_path):
    seed = 3
    clean = fuzz_session(seed, out=tmp_path / "clean")
    bad = fuzz_session(seed, misspecified=key, out=tmp_path / "bad")
    assert {k: bad.truth[k] for k in MOTOR} == {k: clean.truth[k] for k in MOTOR}
    assert bad.shapes == clean.shapes
    recorded = {"dead time": "dead_time", "speed lag": "speed_lag", "voltage drop": "Vdrop",
                "source resistance": "Rs", "current limit": "Imax", "speed gain": "speed_gain",
                "speed offset": "speed_offset", "dead zone": "Vdz_fwd"}
    if key in recorded:
        name = recorded[key]
        assert bad.truth[name] != clean.truth.get(name, 1.0 if "gain" in name else 0.0)
    elif key == "unknown load":
        assert any(k.startswith("drag_") and v > 0 for k, v in bad.truth.items())
    elif key == "coloured noise":  # every analogue speed through a filtering sensor
        plan, _ = fuzz_plan(seed, misspecified=key)
        noisy = [t for t in plan["trace"] if "speed_noise" in t]
        assert noisy and all(0.8 <= t["speed_noise_correlation"] <= 0.97 for t in noisy)
        assert "AR(1)" in (bad.path / "session.toml").read_text()
    elif key == "open at zero":  # every trace driven by a schedule stops, the rotor coasting
        plan, _ = fuzz_plan(seed, misspecified=key)
        clean_plan, _ = fuzz_plan(seed)
        assert plan["rig"]["freewheel_voltage"] > 0
        for t, c in zip(plan["trace"], clean_plan["trace"], strict=True):
            if c["kind"] in ("step", "free-form") and c["voltage"][-1][1] != 0.0:
                assert t["voltage"][-1][1] == 0.0 and c["duration"] == t["duration"]
                assert c["voltage"][-1][0] < t["voltage"][-1][0] < t["duration"]
            else:
                assert t == c
    else:  # every driven trace's speed is the encoder's counts differenced
        plan, _ = fuzz_plan(seed, misspecified=key)
        assert all(t["encoder"] == {"counts_per_rev": 64, "output": "speed"}
                   for t in plan["trace"] if t["kind"] != "coast-down")
    load_session(bad.path)
    with pytest.raises(ValueError, match="unknown non-ideality"):
        fuzz_plan(seed, misspecified="gremlins")


def test_a_rig_carries_several_non_idealities_at_once(tmp_path):
    keys = ("dead time", "voltage drop", "speed offset")
    clean = fuzz_session(5, out=tmp_path / "clean")
    bad = fuzz_session(5, misspecified=keys, out=tmp_path / "bad")
    assert {k: bad.truth[k] for k in MOTOR} == {k: clean.truth[k] for k in MOTOR}
    assert bad.truth["dead_time"] > 0 and bad.truth["Vdrop"] > 0
    assert bad.truth["speed_offset"] != 0
    one = fuzz_session(5, misspecified="dead time", out=tmp_path / "one")
    assert one.truth["Vdrop"] == 0 and one.truth["speed_offset"] == 0
    assert fuzz_plan(5, misspecified=("dead time",))[0] == fuzz_plan(5, misspecified="dead time")[0]
    load_session(bad.path)
    with pytest.raises(ValueError, match="unknown non-ideality"):
        fuzz_plan(5, misspecified=("dead time", "gremlins"))


def spec_rate(spec, name):
    return next(t for t in spec.traces if t.name == name).rate


def _first_noisy_column():
    return next(s for s in range(60) for name in fuzz_plan(s)[1]["columns"]
                if column_reading(s, name, fuzz_plan(s)[0]))


def _first_staircase_column():
    return next(s for s in range(60) if any("staircase" in c for c in fuzz_plan(s)[1]["columns"]))


@pytest.mark.parametrize("seed", ["staircase", 212, "noisy"])
def test_voltage_column_holds_the_rigs_voltage(tmp_path, seed):
    """The column switches at the very sample the rig switched at (a sample late would
    be a one-sample dead time: La off by 7 sd on a staircase at 540 Hz), also late in a
    long trace (seed 212: 23 s at 508 Hz), where a sample time written with ten
    significant digits reads a few nanoseconds before the switch the rig made at it; a
    column read with noise is read back as the rig's levels, within their error."""
    seed = {"staircase": _first_staircase_column, "noisy": _first_noisy_column}.get(
        seed, lambda: seed)()
    plan, extras = fuzz_plan(seed)
    spec = check_plan(plan)
    s = load_session(fuzz_session(seed, out=tmp_path / "v").path)
    for name in extras["columns"]:
        tr = next(t for t in s.traces if t.name == name)
        sched = next(t for t in spec.traces if t.name == name).voltage
        times = np.array([a for a, _ in sched])
        k = np.rint(times * spec_rate(spec, name)).astype(int)  # switches at samples k
        want = np.array([b for _, b in sched])[np.searchsorted(k, np.arange(tr.n),
                                                               side="right") - 1]
        if column_reading(seed, name, plan):
            se = tr.voltage.se[np.searchsorted(tr.voltage.times, tr.time, side="right") - 1]
            assert np.all(np.abs(tr.voltage.at(tr.time) - want) < 5 * se + 1e-3)
            assert tr.voltage.times.size == np.count_nonzero(np.diff(want)) + 1
        else:
            assert np.array_equal(tr.voltage.at(tr.time), want)
        assert "voltage = [[" not in (tmp_path / "v" / "session.toml").read_text().split(
            f'name = "{name}"')[1].split("[[")[0]


def test_a_column_between_samples_shows_each_change_at_the_first_sample_after_it(tmp_path):
    """``between_samples``: the rig switches off the sample grid (every other draw of
    the seed the same), and its logged column shows each change at the first sample at
    or after it, as a rig whose switching the logger's clock does not time."""
    plan, extras = fuzz_plan(16, between_samples=True)
    on_grid, _ = fuzz_plan(16)
    name = extras["columns"][0]
    sched = next(t for t in plan["trace"] if t["name"] == name)["voltage"]
    grid = next(t for t in on_grid["trace"] if t["name"] == name)["voltage"]
    rate = next(t for t in plan["trace"] if t["name"] == name)["rate"]
    offsets = [a * rate - round(a * rate) for a, _ in sched[1:]]
    assert all(abs(x) > 1e-3 for x in offsets)
    assert [b for _, b in sched] == [b for _, b in grid]
    assert all(abs(a - g) <= 0.5 / rate for (a, _), (g, _) in zip(sched, grid, strict=True))
    tr = next(t for t in load_session(fuzz_session(16, out=tmp_path / "b",
                                                   between_samples=True).path).traces
              if t.name == name)
    for a, b in sched[1:]:
        k = int(np.searchsorted(tr.time, a - 1e-12))  # the first sample at or after it
        assert tr.voltage.at(tr.time[k:k + 1])[0] == pytest.approx(b, abs=1e-3)
        assert tr.voltage.at(tr.time[k - 1:k])[0] != pytest.approx(b, abs=1e-3)


def test_step_reading_is_the_rigs_time_constant(tmp_path):
    seed = next(s for s in range(200) if fuzz_plan(s)[1]["step_reading"]
                and "step reading" in fuzz_session(s).shapes)
    f = fuzz_session(seed, out=tmp_path / "r")
    s = load_session(f.path)
    (r,) = s.step_readings
    t = f.truth
    tau = t["J"] * t["Ra"] / (t["K"] ** 2 + t["Ra"] * t["B"])
    assert abs(r.tau / tau - 1) < 0.05 + 5 * 0.01  # La/Ra < 5 % of tau; 1 % reading error
    assert json.loads((f.path / "truth.json").read_text())["J"] == t["J"]


@pytest.mark.parametrize("seed, unit, shapes", [(24, "ms", None), (1, "us", None),
                                                (13, "ms", ("coast-down", "step from rest"))])
def test_a_coarse_clock_rounds_the_stamps_only(tmp_path, seed, unit, shapes):
    """``coarse_clock``: a trace's times written as a microcontroller's integer stamps
    (whole milliseconds at a few hundred hertz, else micros() on a 4 µs tick) and its
    schedules in that unit; loaded, each sample keeps its time to within the clock's
    rounding (a steady rate's millisecond stamps read at the rate's times, a coast-down's
    too) and sees the same voltage and load as the session's exact stamps."""
    files, plan, _ = fuzz_files(seed, coarse_clock=True, shapes=shapes)
    name = plan["trace"][0]["name"]
    stamps = [r.split(",")[0] for r in files[f"{name}.csv"].splitlines()[1:]]
    assert all(s.isdigit() for s in stamps)
    assert f'units = {{ time = "{unit}"' in files["session.toml"].split(f'name = "{name}"')[1]
    coarse = load_session(fuzz_session(seed, out=tmp_path / "c", coarse_clock=True,
                                       shapes=shapes).path)
    exact = load_session(fuzz_session(seed, out=tmp_path / "e", shapes=shapes).path)
    pairs = list(zip(coarse.traces + coarse.coast_downs, exact.traces + exact.coast_downs,
                     strict=True))
    assert len(pairs) == len(plan["trace"])
    for c, e in pairs:
        step = float(np.median(np.diff(e.time)))
        assert np.max(np.abs(c.time - e.time)) < (2.1e-6 if unit == "us" else 0.05 * step)
        assert np.array_equal(c.voltage.at(e.time), e.voltage.at(e.time))
        assert np.array_equal(c.load_torque.at(e.time), e.load_torque.at(e.time))


@pytest.mark.parametrize("shapes", [None, ("sweep",), ("random sequence",)])
def test_a_stop_falls_inside_the_last_level_and_the_record(shapes):
    """Stopped traces (excitations whose last level lasts a sample or less among them)
    keep schedules the loader reads: times strictly increasing, the stop on the sample
    grid and a sample or more before the record's end."""
    stopped = 0
    for seed in range(30):
        plan, _ = fuzz_plan(seed, shapes=shapes, stopped=True)
        clean, _ = fuzz_plan(seed, shapes=shapes)
        for t, c in zip(plan["trace"], clean["trace"], strict=True):
            times = [a for a, _ in t.get("voltage", ())]
            assert all(b > a for a, b in zip(times, times[1:], strict=False))
            if len(times) > len(c.get("voltage", ())):
                stop = times[-1]
                assert t["voltage"][-1][1] == 0.0 and t["voltage"][:-1] == c["voltage"]
                assert stop <= t["duration"] - 1.0 / t["rate"]
                assert abs(stop * t["rate"] - round(stop * t["rate"])) < 1e-6
                stopped += 1
    assert stopped >= 30
