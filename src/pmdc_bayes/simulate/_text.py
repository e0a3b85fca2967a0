"""The fixed text of generated files (numbers, strings, CSV, inline tables, a known
load's entry) and each plan item's own random streams."""

from __future__ import annotations

import json
import zlib

import numpy as np

from ..io.units import from_si

__all__ = ["stream", "number", "string", "csv_text", "pairs", "inline", "drag_entry",
           "trace_block"]


def stream(seed: int, section: str, name: str, n: int = 1):
    """``n`` independent generators for one plan item, keyed by its section and name.

    Equivalent to a child of ``SeedSequence(seed).spawn(...)`` whose spawn key is a
    hash of the item's name instead of its position.
    """
    key = zlib.crc32(f"{section}:{name}".encode())
    children = np.random.SeedSequence(seed, spawn_key=(key,)).spawn(n)
    return [np.random.default_rng(c) for c in children]


def drag_entry(tr) -> str:
    """A trace's known load as ``session.toml`` declares it: the coefficients SI, the
    curve's speeds in the trace's speed unit and its torques in N·m."""
    d = tr.drag
    coefficients = (("constant", d.constant), ("viscous", d.viscous), ("quadratic", d.quadratic))
    parts = [f"{k} = {number(v)}" for k, v in coefficients if v]
    if d.curve:
        points = ", ".join(f"[{number(from_si(w, 'speed', tr.speed_unit))}, {number(t)}]"
                           for w, t in d.curve)
        parts.append(f"curve = [{points}]")
    return "{ " + ", ".join(parts) + " }"


def number(x) -> str:
    """The fixed number format of every generated file (``-0`` written as ``0``)."""
    return format(float(x) + 0.0, ".10g")


def string(text: str) -> str:
    return json.dumps(text, ensure_ascii=False)  # a valid TOML basic string


def csv_text(columns: dict[str, np.ndarray]) -> str:
    rows = zip(*columns.values(), strict=True)
    return "\n".join([",".join(columns), *(",".join(map(number, r)) for r in rows)]) + "\n"


def pairs(pairs) -> str:
    return "[" + ", ".join(f"[{number(a)}, {number(b)}]" for a, b in pairs) + "]"


def inline(table: dict[str, str]) -> str:
    return "{ " + ", ".join(f"{k} = {v}" for k, v in table.items()) + " }"


def trace_block(lines: list[str], name: str) -> range:
    """The line numbers of trace ``name``'s ``[[trace]]`` block in a rendered
    ``session.toml`` split into ``lines``: from its name to the first blank line."""
    named = f"name = {string(name)}"
    start = next(k for k in range(1, len(lines))
                 if lines[k] == named and lines[k - 1] == "[[trace]]")
    end = next((k for k in range(start, len(lines)) if not lines[k].strip()), len(lines))
    return range(start, end)
