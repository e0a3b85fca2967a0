"""A session from arrays in memory (NumPy arrays, lists, pandas columns): written out as
an ordinary session directory (``session.toml`` and one CSV file per trace and steady
table) and read back by :func:`~pmdc_bayes.io.loader.load_session`, so that it is checked
as a session on disk is, and a run written from it carries its files.

Used through :meth:`pmdc_bayes.Session.from_arrays`.
"""

from __future__ import annotations

import atexit
import json
import math
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._errors import UsageError
from .drag import Drag
from .units import from_si

__all__ = ["session_from_arrays"]

_TRACE_COLUMNS = ("time", "speed", "position", "current", "voltage", "load_torque",
                  "direction")
_TRACE_KEYS = ("kind", "initial", "units", "counts_per_rev", "edges", "drag", "time_wrap")
_STEADY_COLUMNS = ("voltage", "speed", "current", "load_torque")
_OP_KEYS = ("supply_voltage", "duty", "current", "speed", "load_torque")
_BENCH = ("Ra", "La", "K", "J", "B")
_SI_UNIT = {"Ra": "ohm", "La": "H", "K": "V*s/rad", "J": "kg*m^2", "B": "N*m*s/rad"}
_temporary: list[Path] = []


def _toml_value(value, where: str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if not math.isfinite(value):
            raise UsageError(f"{where}: {value!r} is not a finite number")
        return repr(float(value))
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=True)
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_toml_value(v, f'{where}.{k}')}"
                                for k, v in value.items()) + " }"
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ", ".join(_toml_value(v, where) for v in value) + "]"
    raise UsageError(f"{where}: {type(value).__name__} is not a number, text, list or "
                     "mapping")


def _table(header: str, entries: Mapping, where: str) -> str:
    lines = [header]
    lines += [f"{key} = {_toml_value(value, f'{where}.{key}')}"
              for key, value in entries.items() if value is not None]
    return "\n".join(lines) + "\n"


def _columns(data, allowed, where: str) -> tuple[dict, dict]:
    """The 1-D columns of ``data`` (a mapping or DataFrame) and its other entries."""
    if not hasattr(data, "keys") or not hasattr(data, "__getitem__"):
        raise UsageError(f"{where}: expected a mapping of column name to values (a dict or "
                         f"a pandas DataFrame), got {type(data).__name__}")
    columns, rest = {}, {}
    for key in data.keys():
        value = data[key]
        if key in allowed and np.ndim(value) == 1:
            try:
                columns[key] = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise UsageError(f"{where}: column {key!r} holds values that are not "
                                 "numbers") from None
            bad = np.flatnonzero(~np.isfinite(columns[key]))
            if bad.size:
                raise UsageError(f"{where}: column {key!r}: value {bad[0]} is not a finite "
                                 "number; drop the sample or fill it in")
        else:
            rest[key] = value
    lengths = {k: len(v) for k, v in columns.items()}
    if len(set(lengths.values())) > 1:
        raise UsageError(f"{where}: columns of different lengths ({lengths}); give one value "
                         "per sample in each")
    return columns, rest


def _bench_entry(key: str, value) -> dict:
    where = f"from_arrays: {key}"
    if isinstance(value, Mapping):
        return dict(value)
    try:
        v, sd = (float(x) for x in value)
    except (TypeError, ValueError):
        raise UsageError(f"{where}: expected (value, sd) in SI ({_SI_UNIT[key]}) or a "
                         "mapping with value, unit, sd and source") from None
    return {"value": v, "unit": _SI_UNIT[key], "sd": sd}


def _write_csv(path: Path, columns: dict) -> None:
    names = list(columns)
    rows = np.column_stack([columns[n] for n in names])
    text = ",".join(names) + "\n" + "".join(
        ",".join(repr(float(x)) for x in row) + "\n" for row in rows)
    path.write_text(text, encoding="utf-8")


def _trace(name: str, data, directory: Path, file: str) -> str:
    where = f"from_arrays: traces[{name!r}]"
    columns, rest = _columns(data, _TRACE_COLUMNS, where)
    unknown = [k for k in rest if k not in (*_TRACE_KEYS, "voltage", "load_torque")]
    if unknown:
        raise UsageError(f"{where}: unknown entry {unknown[0]!r}; give the columns "
                         f"{', '.join(_TRACE_COLUMNS)} and the settings "
                         f"{', '.join(_TRACE_KEYS)}")
    if "time" not in columns:
        raise UsageError(f"{where}: no 'time' column; give the sample times (s)")
    entry = {"name": name, "kind": rest.get("kind", "step"), "file": file,
             "columns": {c: c for c in columns}}
    for key in ("voltage", "load_torque"):  # a schedule: a constant or (time, value) pairs
        if key in rest:
            pairs = np.asarray(rest[key], dtype=float)
            if pairs.ndim == 0:
                pairs = np.array([[columns["time"][0], float(pairs)]])
            if pairs.ndim != 2 or pairs.shape[1] != 2:
                raise UsageError(f"{where}: {key} is neither one value per sample, a "
                                 "constant, nor (time, value) pairs")
            entry[key] = pairs.tolist()
    entry.update({k: rest[k] for k in _TRACE_KEYS if k in rest and k != "kind"})
    if isinstance(entry.get("drag"), Drag) and not entry["drag"].nonzero:
        del entry["drag"]  # a trace's record of no drag
    if isinstance(entry.get("drag"), Drag):  # a trace's own record (SI): the same table
        d = entry["drag"]
        entry["drag"] = {k: getattr(d, k) for k in ("constant", "viscous", "quadratic")
                         if getattr(d, k)}
        if d.curve:  # in the trace's units, as session.toml reads a curve
            units = entry.get("units") or {}
            entry["drag"]["curve"] = [[from_si(w, "speed", units.get("speed", "rad/s")),
                                       from_si(x, "torque", units.get("load_torque", "N*m"))]
                                      for w, x in d.curve]
    _write_csv(directory / file, columns)
    return _table("[[trace]]", entry, where)


def _steady(name: str, data, directory: Path, file: str) -> str:
    where = f"from_arrays: steady[{name!r}]"
    columns, rest = _columns(data, _STEADY_COLUMNS, where)
    if set(rest) - {"units"}:
        raise UsageError(f"{where}: unknown entry {sorted(set(rest) - {'units'})[0]!r}; give "
                         f"the columns {', '.join(_STEADY_COLUMNS)} (and units)")
    _write_csv(directory / file, columns)
    entry = {"name": name, "file": file, "columns": {c: c for c in columns},
             "units": rest.get("units")}
    return _table("[[steady_table]]", entry, where)


def _directory(directory, name) -> Path:
    if directory is None:  # a temporary directory, removed when Python exits
        parent = Path(tempfile.mkdtemp(prefix="pmdc-bayes-"))
        if not _temporary:
            atexit.register(lambda: [shutil.rmtree(p, ignore_errors=True) for p in _temporary])
        _temporary.append(parent)
        path = parent / (name or "session")
        try:
            path.mkdir()
        except OSError:
            raise UsageError(f"from_arrays: name {name!r} cannot name a directory; use "
                             "letters, digits, '-' and '_'") from None
        return path
    if name is not None:
        raise UsageError("from_arrays: give name= or directory= (the session is named "
                         "after its directory), not both")
    path = Path(directory)
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise UsageError(f"{path}: already exists and is not an empty directory; choose a "
                         "new directory for the session's files")
    path.mkdir(parents=True, exist_ok=True)
    return path


def session_from_arrays(*, Ra, traces=None, La=None, K=None, J=None, B=None,
                        motor: str = "motor", friction: str = "viscous", steady=None,
                        operating_points=None, model=None, directory=None, name=None):
    """Write the arrays as a session directory and load it (see
    :meth:`pmdc_bayes.Session.from_arrays`)."""
    bench = {"Ra": Ra, "La": La, "K": K, "J": J, "B": B}
    entries = {k: _bench_entry(k, v) for k, v in bench.items() if v is not None}
    traces, steady = dict(traces or {}), dict(steady or {})
    if not traces and not steady and not operating_points:
        raise UsageError("from_arrays: no data; give traces= (and/or steady=, "
                         "operating_points=)")
    path = _directory(directory, name)
    parts = [_table("[motor]", {"name": motor, "friction": friction}, "from_arrays")]
    parts += [_table(f"[bench.{k}]", e, f"from_arrays: {k}") for k, e in entries.items()]
    if model:
        parts.append(_table("[model]", dict(model), "from_arrays: model"))
    for op_name, op in dict(operating_points or {}).items():
        unknown = set(op) - set(_OP_KEYS) - {"units"}
        if unknown:
            raise UsageError(f"from_arrays: operating_points[{op_name!r}]: unknown entry "
                             f"{sorted(unknown)[0]!r}; give {', '.join(_OP_KEYS)}")
        parts.append(_table("[[operating_point]]", {"name": op_name, **op},
                            f"from_arrays: operating_points[{op_name!r}]"))
    parts += [_steady(n, d, path, f"steady{i + 1}.csv") for i, (n, d) in enumerate(steady.items())]
    parts += [_trace(n, d, path, f"trace{i + 1}.csv") for i, (n, d) in enumerate(traces.items())]
    (path / "session.toml").write_text("\n".join(parts), encoding="utf-8")
    from .loader import load_session

    return load_session(path)
