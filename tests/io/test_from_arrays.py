"""``Session.from_arrays``: data in memory (arrays, lists, a pandas DataFrame) become
the same session as its files on disk, checked as files are."""

from __future__ import annotations

import numpy as np
import pytest

import pmdc_bayes
from pmdc_bayes import Session, SessionError, UsageError
from pmdc_bayes.api import _same
from pmdc_bayes.io.bundled import session_path


def _arrays_of(session):
    """The demo's data as a user holding them in memory would pass them."""
    traces = {}
    for t in session.traces:
        data = {"time": t.time, "speed": t.speed, "kind": t.kind, "initial": t.initial,
                "voltage": np.column_stack([t.voltage.times, t.voltage.values]),
                "load_torque": np.column_stack([t.load_torque.times, t.load_torque.values])}
        if t.current is not None:
            data["current"] = t.current
        traces[t.name] = data
    steady = {s.name: {"voltage": s.voltage, "speed": s.speed, "current": s.current}
              for s in session.steady_tables}
    ops = {p.name: {"supply_voltage": p.supply_voltage, "duty": p.duty,
                    "current": p.current, "speed": p.speed}
           for p in session.operating_points}
    return dict(Ra=(session.Ra.value, session.Ra.sd), La=(session.La.value, session.La.sd),
                traces=traces, steady=steady, operating_points=ops,
                friction=session.friction, motor=session.motor)


def _comparable(session):
    import dataclasses

    return dataclasses.replace(
        session, name="x", root=None, truth=None,
        traces=tuple(dataclasses.replace(t, file=None) for t in session.traces),
        steady_tables=tuple(dataclasses.replace(s, file=None)
                            for s in session.steady_tables),
        Ra=dataclasses.replace(session.Ra, unit="", source=""),
        La=dataclasses.replace(session.La, unit="", source=""))


def test_arrays_in_memory_make_the_same_session_as_its_files():
    demo = pmdc_bayes.load_session(session_path("demo"))
    made = Session.from_arrays(**_arrays_of(demo), name="bench3")
    assert made.name == "bench3"
    assert (made.root / "session.toml").is_file()
    assert _same(_comparable(made), _comparable(demo))
    # one value changed is seen: the comparison is not vacuous
    args = _arrays_of(demo)
    args["traces"]["step_6v49"]["speed"] = demo.trace("step_6v49").speed * 1.001
    assert not _same(_comparable(Session.from_arrays(**args)), _comparable(demo))


def test_a_dataframe_is_a_trace_and_units_convert_at_the_boundary():
    pd = pytest.importorskip("pandas")
    t = np.linspace(0.0, 2.0, 201)
    rpm = 1500.0 * (1 - np.exp(-t / 0.3))
    amps = 0.1 + 1.2 * np.exp(-t / 0.3)
    frame = pd.DataFrame({"time": t, "speed": rpm, "current": amps})
    session = Session.from_arrays(
        Ra=(8.5, 0.1), traces={"step": {**frame, "voltage": 12.0,
                                        "units": {"speed": "rpm"}}})
    tr = session.trace("step")
    np.testing.assert_allclose(tr.speed, rpm * 2 * np.pi / 60, rtol=1e-15)
    np.testing.assert_array_equal(tr.voltage.values, [12.0])
    assert tr.kind == "step" and tr.initial == "rest"
    assert "not measured" in session.La.source  # La optional, as in a file


def test_a_kept_directory_holds_the_files_and_is_never_overwritten(tmp_path):
    t = np.linspace(0.0, 1.0, 51)
    traces = {"s": {"time": t, "speed": 100 * (1 - np.exp(-t / 0.2)), "voltage": 12.0}}
    session = Session.from_arrays(Ra=(8.5, 0.1), traces=traces, directory=tmp_path / "m3")
    assert session.name == "m3"
    assert pmdc_bayes.load_session(tmp_path / "m3").trace("s").n == 51
    before = (tmp_path / "m3" / "session.toml").read_bytes()
    with pytest.raises(UsageError, match="not an empty directory"):
        Session.from_arrays(Ra=(8.5, 0.1), traces=traces, directory=tmp_path / "m3")
    assert (tmp_path / "m3" / "session.toml").read_bytes() == before


@pytest.mark.parametrize("change, error, match", [
    (lambda d: d.update(speed=d["speed"][:-1]), UsageError, "different lengths"),
    (lambda d: d.pop("time"), UsageError, "no 'time' column"),
    (lambda d: d.update(temperature=np.zeros(51)), UsageError, "unknown entry 'temperature'"),
    (lambda d: d.update(voltage=[[0.0, 1.0, 2.0]]), UsageError, "time, value"),
    (lambda d: d.update(time=d["time"][::-1].copy()), SessionError, "time"),
    (lambda d: d.update(speed=np.full(51, np.nan)), UsageError, "finite"),
])
def test_data_of_the_wrong_shape_are_refused_in_one_line(change, error, match):
    t = np.linspace(0.0, 1.0, 51)
    data = {"time": t, "speed": 100 * (1 - np.exp(-t / 0.2)), "voltage": 12.0}
    change(data)
    with pytest.raises(error, match=match) as info:
        Session.from_arrays(Ra=(8.5, 0.1), traces={"s": data})
    assert "\n" not in str(info.value)


def test_no_data_and_a_bad_bench_value_are_refused():
    with pytest.raises(UsageError, match="no data"):
        Session.from_arrays(Ra=(8.5, 0.1))
    with pytest.raises(UsageError, match=r"Ra: expected \(value, sd\)"):
        Session.from_arrays(Ra=8.5, traces={"s": {"time": [0.0, 1.0], "speed": [0, 1]}})
