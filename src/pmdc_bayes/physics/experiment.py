"""Experiments prepared for the model: input segments and a padded sample layout.

A trace's piecewise-constant inputs split its time axis into constant segments; its
samples are laid out in equal-length chunks, each inside one segment, so that the
model can evaluate every sample of every trace at once without gathers.  Everything
here is NumPy, done once per session.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import to_device
from ..io.session import Trace
from .load import drag_cuts, with_drags

__all__ = [
    "INITIAL_MODES",
    "Experiment",
    "make_experiment",
    "stack_experiments",
    "experiment_from_trace",
    "experiment_from_traces",
    "with_drags",
]

INITIAL_MODES = {"rest": 0, "steady": 1, "given": 2}


class Experiment(NamedTuple):
    """Inputs and sample times of one or more traces, prepared for :func:`simulate` (SI).

    The inputs are split into constant segments (``seg_*``): voltage ``seg_va``, load
    ``seg_tl``, starting at ``seg_t0`` and lasting ``seg_len`` (to the next segment, or
    the trace's last sample).  ``seg_first`` marks the first segment of each trace,
    where the state restarts from that trace's initial condition (``seg_mode``: 0 rest,
    1 steady, 2 given ``seg_x0``).  The samples are laid out in ``C`` chunks of ``L``
    (padded): chunk ``c`` lies in segment ``chunk_seg[c]`` of trace ``chunk_trace[c]``,
    its samples ``tau[c]`` seconds after the segment's start, real where ``mask``.
    ``index`` maps the samples, trace after trace and in time order, into the flattened
    ``(C, L)`` layout; ``counts`` holds each trace's number of samples.  The layout lets
    every sample of every trace be evaluated at once, without gathers.  ``seg_b`` and
    ``seg_tc``, when set, add a viscous (N·m·s/rad) and a friction-like constant
    (N·m) drag per segment to the motor's own (an unknown load on a trace).
    ``seg_q``, ``seg_kw`` and ``seg_kt``, when set, are the curved part of each segment's
    known drag (:mod:`.load`: its ``quadratic``, its curve's speeds and torques), which the
    solution replaces by its tangent at the segment's starting speed; a trace with one is
    cut into short segments (:func:`.load.linearisation_cuts`).
    ``seg_clock`` is each segment's start on one clock that runs through the traces in
    order (each trace's times moved past the previous trace's end), so that a time
    finds its segment by one search.  A dead time (:meth:`delayed`) sets
    ``sample_seg``, the segment each sample is evaluated in (``tau`` then counts from
    that segment's start), and ``tau_pre``, how long before its trace's first segment
    a sample lies (≤ 0; ``tau`` is then 0 there).
    """

    seg_t0: jax.Array
    seg_len: jax.Array
    seg_va: jax.Array
    seg_tl: jax.Array
    seg_first: jax.Array
    seg_mode: jax.Array
    seg_x0: jax.Array
    chunk_seg: jax.Array
    chunk_trace: jax.Array
    tau: jax.Array
    mask: jax.Array
    index: jax.Array
    counts: jax.Array
    seg_b: jax.Array | None = None
    seg_tc: jax.Array | None = None
    tau_pre: jax.Array | None = None
    seg_clock: jax.Array | None = None
    sample_seg: jax.Array | None = None
    seg_q: jax.Array | None = None
    seg_kw: jax.Array | None = None
    seg_kt: jax.Array | None = None

    @property
    def curve(self):
        """Each segment's curved drag ``(q, speeds, torques)``, or None."""
        return None if self.seg_q is None else (self.seg_q, self.seg_kw, self.seg_kt)

    @property
    def seg_trace(self) -> jax.Array:
        """The trace of each segment (NumPy when the experiment is concrete)."""
        xp = jnp if isinstance(self.seg_first, jax.core.Tracer) else np
        return xp.cumsum(xp.asarray(self.seg_first).astype(xp.int32)) - 1

    @property
    def sample_segments(self) -> jax.Array:
        """The segment each sample is evaluated in: ``(C, 1)`` (a chunk's own), or
        ``(C, L)`` under a dead time."""
        return self.chunk_seg[:, None] if self.sample_seg is None else self.sample_seg

    def delayed(self, delay, shift=None) -> Experiment:
        """The experiment with each trace's response ``delay[trace]`` (s) later than its
        inputs: each sample evaluated at its time less its trace's delay, in the segment
        that time lies in (exact: the inputs' breakpoints move), held at the trace's
        starting state before its first segment.  A response that leads (a negative
        delay) runs past the trace's last input: its last segment is lengthened by as
        much, so that events there (a stop, a zero crossing) are still located.
        ``shift`` (s, per segment) starts each segment that much earlier, the segment
        before it ending there (a change of a logged column before the sample that
        shows it)."""
        n = self.seg_clock.shape[0]
        idx = jnp.arange(n)
        # each segment's trace's first and last segment
        first = jax.lax.cummax(jnp.where(self.seg_first, idx, 0))
        ends = jnp.concatenate([self.seg_first[1:], jnp.ones(1, bool)])
        last = jax.lax.cummin(jnp.where(ends, idx, n), reverse=True)
        clock, seg_len = self.seg_clock, self.seg_len
        if shift is not None:  # kept in order: a segment never starts after the next
            clock = jax.lax.cummin(self.seg_clock - shift, reverse=True)
            end = jnp.where(ends, self.seg_clock + self.seg_len, jnp.roll(clock, -1))
            seg_len = jnp.maximum(end - clock, 0.0)
        c = self.chunk_seg
        t = self.seg_clock[c][:, None] + self.tau - delay[self.chunk_trace][:, None]
        seg = jnp.searchsorted(clock, t, side="right") - 1
        seg = jnp.clip(seg, first[c][:, None], last[c][:, None])
        shifted = t - clock[seg]
        lead = jnp.maximum(-delay, 0.0)[self.seg_trace]
        return self._replace(tau=jnp.maximum(shifted, 0.0), tau_pre=jnp.minimum(shifted, 0.0),
                             sample_seg=seg, seg_len=seg_len + jnp.where(ends, lead, 0.0))

    @property
    def voltage_reverses(self) -> bool:
        """Whether any trace's voltage takes both signs."""
        va, trace = np.asarray(self.seg_va), np.asarray(self.seg_trace)
        return any(bool((va[trace == k] > 0).any() and (va[trace == k] < 0).any())
                   for k in np.unique(trace))

    @property
    def time(self) -> np.ndarray:
        """Sample times of all traces, concatenated (s)."""
        t = np.asarray(self.seg_t0)[np.asarray(self.chunk_seg)][:, None] + np.asarray(self.tau)
        return t.reshape(-1)[np.asarray(self.index)]

    def pad(self, values) -> jax.Array:
        """Place per-sample values (traces concatenated) into the padded layout (NumPy
        when nothing is traced: a host-side array needs no compiled scatter)."""
        if any(isinstance(x, jax.core.Tracer) for x in (values, self.index, self.tau)):
            flat = jnp.zeros(self.tau.size).at[self.index].set(jnp.asarray(values))
            return flat.reshape(self.tau.shape)
        flat = np.zeros(self.tau.size)
        flat[np.asarray(self.index)] = np.asarray(values)
        return flat.reshape(self.tau.shape)

    def unpad(self, padded) -> jax.Array:
        """Per-sample values (traces concatenated, time order) from the padded layout."""
        return padded.reshape(padded.shape[:-2] + (-1,))[..., self.index]

    def split(self, values) -> list:
        """Split concatenated per-sample values into one array per trace."""
        edges = np.cumsum(np.asarray(self.counts))[:-1]
        return np.split(np.asarray(values), edges, axis=-1)


def _chunk_length(counts: np.ndarray) -> int:
    """Chunk length that keeps padding plus per-chunk overhead small."""
    best, best_cost = 1, None
    length = 1
    while length <= max(1, int(counts.max())) * 2:
        chunks = np.ceil(counts / length).sum()
        cost = chunks * length + 16 * chunks
        if best_cost is None or cost < best_cost:
            best, best_cost = length, cost
        length *= 2
    return best


def _segments(t, va_t, va_v, tl_t, tl_v, cuts=None):
    """A trace's constant segments: where its inputs change, and at ``cuts``."""
    cuts = np.zeros(0) if cuts is None else np.asarray(cuts, dtype=np.float64)
    inner = np.concatenate([va_t, tl_t, cuts])
    inner = inner[(inner > t[0]) & (inner < t[-1])]
    seg_t0 = np.unique(np.concatenate([[t[0]], inner]))

    def held(bt, bv, at):
        idx = np.searchsorted(bt, at, side="right") - 1
        return bv[np.clip(idx, 0, len(bv) - 1)]

    seg_va = held(va_t, va_v, seg_t0)
    seg_tl = held(tl_t, tl_v, seg_t0)
    keep = np.ones(seg_t0.size, dtype=bool)
    keep[1:] = (np.diff(seg_va) != 0) | (np.diff(seg_tl) != 0) | np.isin(seg_t0[1:], cuts)
    seg_t0, seg_va, seg_tl = seg_t0[keep], seg_va[keep], seg_tl[keep]
    seg_len = np.append(seg_t0[1:], t[-1]) - seg_t0
    sample_seg = np.searchsorted(seg_t0, t, side="right") - 1
    return seg_t0, seg_len, seg_va, seg_tl, sample_seg


def stack_experiments(specs) -> Experiment:
    """One :class:`Experiment` for several traces.

    ``specs`` is a sequence of ``(time, va_times, va_values, tl_times, tl_values,
    initial)``, optionally followed by ``cuts``, times where a segment ends although the
    inputs do not change; ``initial`` is ``"rest"``, ``"steady"`` or a pair ``(ia, ω)``.
    """
    segs, per_trace = [], []
    for time, va_t, va_v, tl_t, tl_v, initial, *cuts in specs:
        t = np.asarray(time, dtype=np.float64)
        if tl_t is None:
            tl_t, tl_v = np.array([t[0]]), np.array([0.0])
        parts = _segments(t, *(np.asarray(a, dtype=np.float64) for a in (va_t, va_v, tl_t, tl_v)),
                          cuts[0] if cuts else None)
        segs.append(parts)
        per_trace.append((t, initial))
    all_counts = np.concatenate([np.bincount(p[4], minlength=p[0].size) for p in segs])
    length = _chunk_length(all_counts[all_counts > 0])
    cols = {k: [] for k in ("t0", "len", "va", "tl", "first", "mode", "x0")}
    chunk_seg, chunk_trace, taus, masks, index = [], [], [], [], []
    seg_offset = 0
    for k, ((seg_t0, seg_len, seg_va, seg_tl, sample_seg), (t, initial)) in enumerate(
            zip(segs, per_trace, strict=True)):
        if isinstance(initial, str):
            mode, x0 = INITIAL_MODES[initial], (0.0, 0.0)
        else:
            mode, x0 = INITIAL_MODES["given"], tuple(float(v) for v in initial)
        n_seg = seg_t0.size
        cols["t0"].append(seg_t0), cols["len"].append(seg_len)
        cols["va"].append(seg_va), cols["tl"].append(seg_tl)
        cols["first"].append(np.arange(n_seg) == 0)
        cols["mode"].append(np.full(n_seg, mode)), cols["x0"].append(np.tile(x0, (n_seg, 1)))
        counts = np.bincount(sample_seg, minlength=n_seg)
        start = 0
        for s, n in enumerate(counts):
            if n == 0:
                continue
            tau_s = t[start:start + n] - seg_t0[s]
            n_chunks = -(-n // length)
            padded = np.concatenate([tau_s, np.full(n_chunks * length - n, tau_s[-1])])
            index.append(len(chunk_seg) * length + np.arange(n))
            chunk_seg.extend([seg_offset + s] * n_chunks)
            chunk_trace.extend([k] * n_chunks)
            taus.append(padded.reshape(n_chunks, length))
            masks.append((np.arange(n_chunks * length) < n).reshape(n_chunks, length))
            start += n
        seg_offset += n_seg
    cat = {k: np.concatenate(v) for k, v in cols.items()}
    # one clock through the traces: each trace starts a second after the previous ends
    clock, shift = [], 0.0
    for seg_t0, (t, _) in zip(cols["t0"], per_trace, strict=True):
        shift -= float(t[0])
        clock.append(seg_t0 + shift)
        shift += float(t[-1]) + 1.0
    return Experiment(
        to_device(cat["t0"]), to_device(cat["len"]), to_device(cat["va"]),
        to_device(cat["tl"]), to_device(cat["first"]),
        to_device(cat["mode"].astype(np.int32)), to_device(cat["x0"]),
        to_device(np.array(chunk_seg, dtype=np.int32)),
        to_device(np.array(chunk_trace, dtype=np.int32)),
        to_device(np.concatenate(taus)), to_device(np.concatenate(masks)),
        to_device(np.concatenate(index)),
        to_device(np.array([p[0].size for p in per_trace], dtype=np.int64)),
        seg_clock=to_device(np.concatenate(clock)),
    )


def make_experiment(time, va_times, va_values, tl_times=None, tl_values=None, *,
                    initial="rest") -> Experiment:
    """Build an :class:`Experiment` from sample times and piecewise-constant inputs.

    ``initial`` is ``"rest"``, ``"steady"`` (steady state of the inputs at the first
    sample) or a pair ``(ia, ω)``.
    """
    return stack_experiments([(time, va_times, va_values, tl_times, tl_values, initial)])


def _trace_spec(trace: Trace, delay: float = 0.0):
    init = trace.initial if isinstance(trace.initial, str) else tuple(trace.initial)
    cuts = None
    if trace.drag.curved:
        breaks = np.concatenate([trace.voltage.times, trace.load_torque.times])
        cuts = drag_cuts(trace.drag, trace.time, breaks, trace.speed) - delay
    return (trace.time - delay, trace.voltage.times, trace.voltage.values,
            trace.load_torque.times, trace.load_torque.values, init, cuts)


def experiment_from_trace(trace: Trace, *, delay: float = 0.0) -> Experiment:
    """The :class:`Experiment` of a session trace (inputs, sample times, initial state,
    known drag)."""
    return with_drags(stack_experiments([_trace_spec(trace, delay)]), [trace.drag])


def experiment_from_traces(traces) -> Experiment:
    """One stacked :class:`Experiment` for all of a session's traces, with their known
    drags (``Trace.drag``) per segment when any trace has one."""
    return with_drags(stack_experiments([_trace_spec(tr) for tr in traces]),
                      [tr.drag for tr in traces])
