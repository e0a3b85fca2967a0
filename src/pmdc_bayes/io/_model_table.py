"""The ``[model]`` table of ``session.toml``: which of the rig's non-idealities the fit
carries, and on which traces (``docs/session-format.md``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .session import LOAD_KINDS, NUISANCES
from .toml_tables import Table as _Table
from .toml_tables import describe as _describe

__all__ = ["ModelTable", "read_model_table"]


@dataclass(frozen=True)
class ModelTable:
    """What ``[model]`` declares, as the :class:`~.session.Session` fields of those names
    hold it (all empty or off without the table)."""

    nuisances: tuple[str, ...] = ()
    loaded_traces: tuple[str, ...] = ()
    load_kinds: tuple[tuple[str, str], ...] = ()
    current_limit_setting: float | None = None
    shared_dead_time: bool = False
    coloured_traces: tuple[str, ...] = ()


def read_model_table(mt: _Table | None, traces, coast_downs) -> ModelTable:
    """``[model]`` read and checked against the session's driven ``traces`` and
    ``coast_downs``; every bad entry a one-line error naming its key."""
    if mt is None:
        return ModelTable()
    mt.check_keys(NUISANCES)
    loaded, kinds = _loaded_traces(mt, traces)
    limit_setting = _limit_setting(mt)
    shared = _shared_dead_time(mt)
    coloured = _coloured_traces(mt, traces + coast_downs)
    for key in NUISANCES:
        flag = mt.data.get(key, False)
        if key not in ("unknown_load", "current_limit", "dead_time", "coloured_noise") \
                and not isinstance(flag, bool):
            mt.fail(key, f"expected true or false, got {_describe(flag)}; write e.g. "
                    f"{key} = true")
    return ModelTable(tuple(k for k in NUISANCES if mt.data.get(k, False)), loaded, kinds,
                      limit_setting, shared, coloured)


def _limit_setting(mt) -> float | None:
    """``[model] current_limit``: true (fitted, its level unknown), false, or the
    driver's setting in A (fitted, the prior centred on it)."""
    value = mt.data.get("current_limit", False)
    if isinstance(value, bool):
        return None
    if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        mt.fail("current_limit", f"expected true, false or the driver's limit in A (> 0), "
                f"got {_describe(value)}; write e.g. current_limit = 2.5")
    return float(value)


def _shared_dead_time(mt) -> bool:
    """``[model] dead_time``: true or ``"per_trace"`` (one per driven trace), ``"shared"``
    (one for all of them: the same driver and logger), or false; whether it is shared."""
    value = mt.data.get("dead_time", False)
    if isinstance(value, bool) or value == "per_trace":
        return False
    if value != "shared":
        mt.fail("dead_time", f"expected true, false, \"per_trace\" or \"shared\", got "
                f"{_describe(value)}; write e.g. dead_time = \"shared\"")
    return True


def _loaded_traces(mt: _Table, traces) -> tuple[tuple[str, ...], tuple[tuple[str, str], ...]]:
    """``[model] unknown_load``: true (every driven trace), false, a list of names of
    driven traces, or a table of such names to the parts of the drag to fit
    (:data:`LOAD_KINDS`: ``{ step_9v = "viscous" }``); the names given (empty for true
    or false) and, for a table, each name's kind."""
    value = mt.data.get("unknown_load", False)
    if isinstance(value, bool):
        return (), ()
    names = [t.name for t in traces]
    if isinstance(value, dict) and value:
        for name, kind in value.items():
            if name not in names:
                mt.fail(f"unknown_load.{name}", f"names no driven trace (of "
                        f"{', '.join(map(repr, names))}); use a trace's name")
            if kind not in LOAD_KINDS:
                mt.fail(f"unknown_load.{name}", f"expected one of {', '.join(LOAD_KINDS)}, "
                        f"got {_describe(kind)}; write e.g. {name} = \"viscous\"")
        return tuple(value), tuple(value.items())
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, str) and v in names for v in value)):
        example = f"[{names[0]!r}]" if names else "true"
        mt.fail("unknown_load", f"expected true, false, a list of driven trace names "
                f"(of {', '.join(map(repr, names))}) or a table of them to \"constant\", "
                f"\"viscous\" or \"both\", got {_describe(value)}; write e.g. "
                f"unknown_load = {example}")
    return tuple(dict.fromkeys(value)), ()


def _coloured_traces(mt: _Table, traces) -> tuple[str, ...]:
    """``[model] coloured_noise``: true (every trace), false, or a list of trace names
    (driven traces and coast-downs)."""
    value = mt.data.get("coloured_noise", False)
    if isinstance(value, bool):
        return ()
    names = [t.name for t in traces]
    if (not isinstance(value, list) or not value
            or not all(isinstance(v, str) and v in names for v in value)):
        example = f"[{names[0]!r}]" if names else "true"
        mt.fail("coloured_noise", f"expected true, false or a list of trace names (of "
                f"{', '.join(map(repr, names))}), got {_describe(value)}; write e.g. "
                f"coloured_noise = {example}")
    return tuple(dict.fromkeys(value))
