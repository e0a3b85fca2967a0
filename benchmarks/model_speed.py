"""Model evaluation speed: log-posterior evaluations per second on four solution paths.

Run from the repository root::

    python benchmarks/model_speed.py            # full run, updates reports/benchmarks.md
    python benchmarks/model_speed.py --quick    # smoke run: small traces, report untouched

Paths timed, each jit-compiled with x64 on (see ``benchmarks/README.md``):

* ``exact``       ``jax.jit(model.log_posterior)``, one parameter vector (general branch);
* ``exact xW``    ``jax.jit(model.log_posterior_batch)`` on W = 8, 32, 64, 256 perturbed
  vectors;
* ``zoh scan``    :func:`pmdc_bayes.physics.ode.simulate_scan` per trace, same log-posterior;
* ``diffrax``     :func:`pmdc_bayes.physics.ode.simulate_ode` per trace, same log-posterior
  (its default tolerances, rtol 1e-10, atol 1e-12; ``diffrax loose``: rtol 1e-8, atol 1e-10).

The scan and diffrax log-posteriors are built from the session model's own channels,
noise scales and priors, and are checked to agree with the exact path at the truth.
"""

from __future__ import annotations

import jax

jax.config.update("jax_enable_x64", True)

import argparse  # noqa: E402
import datetime  # noqa: E402
import logging  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from importlib.metadata import version  # noqa: E402
from pathlib import Path  # noqa: E402

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import replace_section  # noqa: E402  (benchmarks/ is on sys.path)

from pmdc_bayes.inference.model.objective import NU0, build_model  # noqa: E402
from pmdc_bayes.io.bundled import bundled_session_dir  # noqa: E402
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.paper.closed_form import closed_form  # noqa: E402
from pmdc_bayes.physics.ode import simulate_ode, simulate_scan  # noqa: E402
from pmdc_bayes.physics.solution import experiment_from_trace, real_modes  # noqa: E402
from pmdc_bayes.simulate.session import simulate_session  # noqa: E402

SECTION = "Model evaluation speed"
REPORT = Path(__file__).resolve().parents[1] / "reports" / "benchmarks.md"
TARGET = 5_000.0  # vectors/s, batched exact path on 3 x 10,000 samples
BATCHES = (8, 32, 64, 256)
PERTURBATION = 0.01  # sd of the batch around the truth, in log space
LOOSE = {"rtol": 1e-8, "atol": 1e-10}  # the "diffrax loose" row; simulate_ode's default
# is rtol 1e-10, atol 1e-12
TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4}


# -- sessions --------------------------------------------------------------------------
def _plan(friction: str, duration: float) -> dict:
    """Three 100 Hz traces of ``duration`` s: two steps from rest and a load change."""
    tc = 2.5e-3 if friction == "coulomb" else 0.0
    common = {"rate": 100.0, "duration": duration, "speed_unit": "rad/s",
              "record_current": True, "speed_noise": 0.3, "current_noise": 0.005}
    return {
        "seed": 1, "motor": {"name": f"benchmark motor ({friction})", "friction": friction},
        "truth": {**TRUTH, "Tc": tc},
        "bench": {"Ra": {"sd": 0.1, "unit": "ohm"}, "La": {"sd": 0.2, "unit": "mH"}},
        "operating_point": [{"name": "chopper", "supply_voltage": 24.0, "duty": 0.7,
                             "load_torque": 0.0, "speed_sd": 0.5, "current_sd": 0.002}],
        "trace": [
            {"name": "step_12v97", "kind": "step", "voltage": [[0.0, 0.0], [0.5, 12.97]],
             "initial": "rest", **common},
            {"name": "step_6v49", "kind": "step", "voltage": [[0.0, 0.0], [0.5, 6.49]],
             "initial": "rest", **common},
            {"name": "load_change", "kind": "load_change", "voltage": [[0.0, 12.97]],
             "load_torque": [[0.0, 0.0], [0.5 * duration, 0.01]], "initial": "steady",
             **common},
        ],
    }


def _sessions(tmp: Path, quick: bool) -> list[tuple[str, object]]:
    """(label, SessionModel) pairs: synthetic viscous and Coulomb, and the demo."""
    duration = 9.99 if quick else 99.99  # 1,000 or 10,000 samples at 100 Hz
    out = []
    for friction in ("viscous", "coulomb"):
        session = load_session(simulate_session(_plan(friction, duration), tmp / friction))
        n = " + ".join(f"{tr.n:,}" for tr in session.traces)
        label = f"3 traces ({n}), {friction}"
        out.append((label, build_model(session, closed_form(session))))
    demo = load_session(bundled_session_dir("demo"))
    n = " + ".join(f"{tr.n:,}" for tr in demo.traces)
    for coulomb in (True, False):
        label = f"demo ({n}), {'coulomb' if coulomb else 'viscous model'}"
        out.append((label, build_model(demo, closed_form(demo), coulomb=coulomb)))
    return out


# -- the same log-posterior through another simulator ----------------------------------
def _per_trace_log_posterior(model, simulate_trace):
    """``θ -> log-posterior`` with the traces simulated one by one by ``simulate_trace(p,
    exp)``; channels, noise scales and priors are the session model's."""
    index = {c.name: k for k, c in enumerate(model.channels)}
    traces = [(experiment_from_trace(tr), jnp.asarray(tr.speed),
               None if tr.current is None else jnp.asarray(tr.current),
               index[f"{tr.name}: speed"], index.get(f"{tr.name}: current"))
              for tr in model.session.traces]
    d = model.data
    n_ch = len(model.channels)

    def log_posterior(theta):
        p = model.params(theta)
        ss = jnp.zeros(n_ch)
        for exp, speed, current, c_w, c_i in traces:
            ia, w = simulate_trace(p, exp)
            ss = ss.at[c_w].add(jnp.sum((speed - w) ** 2))
            if current is not None:
                ss = ss.at[c_i].add(jnp.sum((current - ia) ** 2))
        st, tau = d["steady"], d["tau"]
        i, w = model.steady_prediction(p, st["v"], st["tl"])
        tail = jnp.stack([jnp.sum(jnp.where(st["w_mask"], st["w"] - w, 0.0) ** 2),
                          jnp.sum(jnp.where(st["i_mask"], st["i"] - i, 0.0) ** 2),
                          jnp.sum((tau["tau"] - model.tau_prediction(p)) ** 2)])
        ss = ss.at[n_ch - 3:].add(tail)
        n, s0 = d["n_obs"], d["s0"]
        ll = jnp.sum(jnp.where(n > 0, -0.5 * (n + NU0) * jnp.log(NU0 * s0**2 + ss), 0.0))
        lp = model.log_prior(theta) + ll
        return jnp.where(jnp.isfinite(lp), lp, -jnp.inf)

    return log_posterior


def _paths(model, batches):
    """(name, function, argument, vectors per call) of every path that applies."""
    theta0 = np.asarray(model.theta(model.session.truth))
    rng = np.random.default_rng(0)
    big = theta0 + PERTURBATION * rng.standard_normal((max(batches), theta0.size))
    single = jnp.asarray(big[0])
    out = [("exact", model.log_posterior, single, 1)]
    out += [(f"exact x{b}", model.log_posterior_batch, jnp.asarray(big[:b]), b) for b in batches]
    if not model.coulomb:
        out.append(("zoh scan", _per_trace_log_posterior(model, simulate_scan), single, 1))
    ode = _per_trace_log_posterior(
        model, lambda p, exp: simulate_ode(p, exp, coulomb=model.coulomb))
    out.append(("diffrax", ode, single, 1))
    loose = _per_trace_log_posterior(
        model, lambda p, exp: simulate_ode(p, exp, coulomb=model.coulomb, **LOOSE))
    out.append(("diffrax loose", loose, single, 1))
    return out, big


# -- timing ----------------------------------------------------------------------------
def _measure(fn, arg, *, min_time: float, min_reps: int = 3):
    """Compile time (lower + compile), then the median wall time of one call over
    repeated calls lasting at least ``min_time`` s, after one warm-up call."""
    t0 = time.perf_counter()
    compiled = jax.jit(fn).lower(arg).compile()
    compile_s = time.perf_counter() - t0
    value = jax.block_until_ready(compiled(arg))  # warm-up
    times, start = [], time.perf_counter()
    while len(times) < min_reps or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(arg))
        times.append(time.perf_counter() - t0)
    return compile_s, statistics.median(times), len(times), np.asarray(value)


def _failure(exc: Exception) -> str:
    """The one informative line of a runtime error raised inside compiled code."""
    lines = [ln.strip() for ln in str(exc).splitlines() if "Error:" in ln or "steps" in ln]
    text = lines[-1] if lines else str(exc).splitlines()[0]
    return text.split("Error: ", 1)[-1][:160]


def _machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    return {"platform": platform.platform(), "cpu": cpu,
            "cores": f"{os.cpu_count()} logical, {usable} usable",
            "python": platform.python_version(), "jax": jax.__version__,
            "jaxlib": version("jaxlib"), "diffrax": version("diffrax"),
            "device": str(jax.devices()[0]), "x64": bool(jax.config.jax_enable_x64),
            "load": _load()}


def _load() -> str:
    """The 1-minute load average: other processes running slow the figures down."""
    return f"{os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else "unknown"


# -- output ----------------------------------------------------------------------------
def _fmt_rate(x: float) -> str:
    return f"{x:,.0f}" if x >= 100 else f"{x:,.2f}" if x >= 1 else f"{x:.3g}"


def _tables(results: dict) -> list[str]:
    lines = ["| session | path | vectors per call | compile (s) | time per call (ms) "
             "| evaluations/s | repeats |", "|---|---|---:|---:|---:|---:|---:|"]
    for label, rows in results.items():
        for r in rows:
            if "failed" in r:
                lines.append(f"| {label} | {r['path']} | {r['batch']} | | | failed: "
                             f"{r['failed']} | |")
                continue
            lines.append(f"| {label} | {r['path']} | {r['batch']} | {r['compile_s']:.2f} | "
                         f"{1e3 * r['call_s']:.3g} | {_fmt_rate(r['rate'])} | {r['reps']} |")
    refs = ("diffrax", "diffrax loose", "zoh scan")
    lines += ["", "Ratios of evaluations/s, batched exact path over each reference path "
              "(x64, and the fastest batch if another):", "",
              "| session | batched | " + " | ".join(f"/ {r}" for r in refs) + " |",
              "|---|---|" + "---:|" * len(refs)]
    for label, rows in results.items():
        rate = {r["path"]: r["rate"] for r in rows if "failed" not in r}
        batched = [p for p in rate if p.startswith("exact x")]
        if not batched:
            continue
        best = max(batched, key=rate.get)
        for p in dict.fromkeys(q for q in ("exact x64", best) if q in rate):
            cells = [_fmt_rate(rate[p] / rate[r]) if r in rate else "n/a" for r in refs]
            lines.append(f"| {label} | {p} | " + " | ".join(cells) + " |")
    return lines


def _target_lines(results: dict, quick: bool) -> list[str]:
    """PASS/MISS of every batched exact row on the 3-trace sessions."""
    out = []
    for label, rows in results.items():
        if not label.startswith("3 traces"):
            continue
        for r in rows:
            if not r["path"].startswith("exact x"):
                continue
            if "failed" in r:
                out.append(f"- MISS: {label}, {r['path']} failed")
                continue
            verdict = "PASS" if r["rate"] >= TARGET else "MISS"
            if quick:
                verdict += " (--quick sizes, not the target's)"
            out.append(f"- {verdict}: {label}, {r['path']}: {_fmt_rate(r['rate'])} vectors/s")
    return out


def _section(machine: dict, results: dict, checks: list[str], quick: bool) -> str:
    today = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    m = machine
    lines = [
        f"## {SECTION}", "",
        f"Measured {today} by `python benchmarks/model_speed.py{' --quick' if quick else ''}`"
        " (what each figure means: `benchmarks/README.md`).", "",
        f"Machine: {m['cpu']}, {m['cores']} cores; {m['platform']}; Python {m['python']}, "
        f"jax {m['jax']}, jaxlib {m['jaxlib']}, diffrax {m['diffrax']}; device {m['device']}; "
        f"x64 {'on' if m['x64'] else 'off'}.  1-minute load average {m['load']} at the start "
        f"and {m['load_end']} at the end (above the core count, other processes competed "
        "for the CPU and the figures are pessimistic).", "",
        "Log-posterior evaluations per second (one evaluation = one parameter vector on the "
        "whole session: every trace, steady point and prior).  Median of repeated calls "
        "after a warm-up, at least 1 s of calls per figure; compile time is "
        "`jit(...).lower(...).compile()`.  The zero-order-hold scan is the viscous model "
        "only, so it has no Coulomb rows.  `diffrax` uses `simulate_ode`'s default tolerances "
        "(rtol 1e-10, atol 1e-12), `diffrax loose` rtol 1e-8, atol 1e-10.  A path that "
        "fails is listed with its error.", "",
        *_tables(results), "",
        "Agreement with the exact path at a perturbed truth (|Δ log-posterior|):", "",
        *checks, "",
        "Target: at least 5,000 vectors/s for the batched exact path on 3 × 10,000 samples.",
        "",
        *_target_lines(results, quick), "",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: 3 x 1,000 samples, 0.2 s per figure; report untouched")
    ap.add_argument("--report", type=Path, default=REPORT,
                    help=f"markdown file whose '{SECTION}' section is replaced ({REPORT})")
    ap.add_argument("--no-report", action="store_true", help="print only")
    args = ap.parse_args(argv)
    # A failed solve is reported in one line below, not as jax's callback traceback.
    logging.getLogger("jax._src.callback").setLevel(logging.CRITICAL)
    min_time = 0.2 if args.quick else 1.0

    machine = _machine()
    print("Machine:")
    for k, v in machine.items():
        print(f"  {k:9s} {v}")
    results, checks = {}, []
    with tempfile.TemporaryDirectory(prefix="pmdc-speed-") as tmp:
        sessions = _sessions(Path(tmp), args.quick)
    for label, model in sessions:
        print(f"\n{label}: {len(model.names)} parameters, "
              f"{int(sum(c.n for c in model.channels))} observations")
        paths, big = _paths(model, BATCHES)
        fast = bool(jnp.all(jax.vmap(lambda t, m=model: real_modes(m.params(t)))(
            jnp.asarray(big))))
        rows, ref = [], None
        for name, fn, arg, batch in paths:
            try:
                compile_s, call_s, reps, value = _measure(fn, arg, min_time=min_time)
            except jax.errors.JaxRuntimeError as exc:
                reason = _failure(exc)
                rows.append({"path": name, "batch": batch, "failed": reason})
                print(f"  {name:10s} FAILED: {reason}")
                continue
            rate = batch / call_s
            rows.append({"path": name, "batch": batch, "compile_s": compile_s,
                         "call_s": call_s, "rate": rate, "reps": reps})
            note = " (fast real-eigenvalue branch)" if name.startswith("exact x") and fast else ""
            print(f"  {name:10s} compile {compile_s:7.2f} s   {1e3 * call_s:10.3f} ms/call"
                  f"   {_fmt_rate(rate):>10s} evaluations/s   ({reps} calls){note}")
            v = float(np.ravel(value)[0])
            if name == "exact":
                ref = v
            elif batch == 1:
                checks.append(f"- {label}, {name}: {abs(v - ref):.2e} (exact {ref:.6f})")
                print(f"  {'':10s} log-posterior {v:.6f}, exact {ref:.6f}, "
                      f"|difference| {abs(v - ref):.2e}")
        results[label] = rows

    machine["load_end"] = _load()
    print(f"\n1-minute load average at the end: {machine['load_end']}")
    section = _section(machine, results, checks, args.quick)
    print("\n" + section)
    if args.quick or args.no_report:
        print(f"{args.report}: not written ({'--quick' if args.quick else '--no-report'})")
    else:
        replace_section(args.report, SECTION, section)
        print(f"{args.report}: section '{SECTION}' updated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
