"""Benchmark against the baseline: the one command behind the figures of issue 7.

Run from the repository root::

    python benchmarks/run.py            # full run (~10-15 min on 2 cores), updates the report
    python benchmarks/run.py --quick    # smoke run (~1-2 min): small sizes, report untouched

On one session simulated by ``pmdc-bayes simulate`` (3 traces of 10,000 samples,
viscous friction; 1,000 samples with ``--quick``) it measures, in float64:
log-likelihood agreement of the baseline (``benchmarks/baseline.py``: SciPy LSODA +
plain Python) with the exact path; log-posterior evaluations per second of the
baseline, the diffrax path and the exact path (one θ and batched); value-and-gradient
time; MAP fit time after compilation; compile times; effective samples per second of
K, B and J for the project's sampler and the baseline's emcee (a short run,
extrapolated); end-to-end ``pmdc-bayes fit`` on ``data/demo`` (cold and warm
compilation cache, split by stage, peak memory); and how the cost scales with samples
per trace and with the number of traces.  What each figure means:
``benchmarks/README.md``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import emcee  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from _common import REPORT, ROOT, cli_command, load_baseline, replace_section, run_measured  # noqa: E402
from model_speed import _fmt_rate, _load, _machine, _measure, _per_trace_log_posterior  # noqa: E402

from pmdc_bayes.inference.fit.joint import fit_map  # noqa: E402
from pmdc_bayes.inference.model.objective import build_model  # noqa: E402
from pmdc_bayes.inference.sampling.arviz_import import az  # noqa: E402
from pmdc_bayes.inference.sampling.ensembles import ENSEMBLES  # noqa: E402
from pmdc_bayes.inference.sampling.moves import (  # noqa: E402
    SHARE_TRUSTED,
    LaplaceIndependenceMove,
    LaplaceMixture,
)
from pmdc_bayes.inference.sampling.posterior import (  # noqa: E402
    default_moves,
    sample_posterior,
    to_inference_data,
)
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.io.session import Measurement, Schedule, Session, Trace  # noqa: E402
from pmdc_bayes.paper.closed_form import closed_form  # noqa: E402
from pmdc_bayes.physics.ode import simulate_ode  # noqa: E402

SECTION = "Benchmark against the baseline"
TRUTH = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4}
ESS_PARAMS = ("K", "B", "J")
TARGET_ESS, TARGET_RATIO, TARGET_E2E = 400.0, 1000.0, 15.0
AGREEMENT = 1e-3  # |Δ log-likelihood| allowed between the baseline and the exact path
TIGHT = {"rtol": 1e-9, "atol": 1e-11}  # a baseline tight enough to show the formula agrees
DIFFRAX_TOL = {"rtol": 1e-6, "atol": 1e-8}  # the baseline's tolerances, for a like-for-like row
TARGET_NO_MCMC, TARGET_WARM, TARGET_SAMPLING, TARGET_LOT = 5.0, 5.0, 60.0, 10.0
FULL = {"duration": 99.99, "min_time": 1.0, "budget": 90.0, "motors": 10,
        "shapes": (("data/demo", "data/demo", ()),
                   ("data/demo --no-mcmc", "data/demo", ("--no-mcmc",)),
                   ("simulated 3 × 10,000", "SIMULATED", ()),
                   ("data/bench", "data/bench", ())),
        "sizes": (1_000, 10_000, 100_000, 1_000_000), "traces": (1, 2, 4, 8, 16)}
QUICK = {"duration": 9.99, "min_time": 0.2, "budget": 8.0, "motors": 0,
         "shapes": (("paper", "paper", ()), ("simulated 3 × 1,000", "SIMULATED", ())),
         "sizes": (1_000, 10_000), "traces": (1, 2)}


# -- the session -------------------------------------------------------------------------
def _plan_toml(duration: float) -> str:
    """The plan of ``model_speed.py``'s viscous session: three 100 Hz traces (two steps
    from rest, a load change from the steady state) and a chopper operating point."""
    trace = (f"rate = 100.0\nduration = {duration!r}\nspeed_unit = \"rad/s\"\n"
             "record_current = true\nspeed_noise = 0.3\ncurrent_noise = 0.005\n")
    truth = "\n".join(f"{k} = {v!r}" for k, v in TRUTH.items())
    return f"""seed = 1

[motor]
name = "benchmark motor (viscous)"
friction = "viscous"

[truth]
{truth}
Tc = 0.0

[bench.Ra]
sd = 0.1
unit = "ohm"

[bench.La]
sd = 0.2
unit = "mH"

[[operating_point]]
name = "chopper"
supply_voltage = 24.0
duty = 0.7
load_torque = 0.0
speed_sd = 0.5
current_sd = 0.002

[[trace]]
name = "step_12v97"
kind = "step"
voltage = [[0.0, 0.0], [0.5, 12.97]]
initial = "rest"
{trace}
[[trace]]
name = "step_6v49"
kind = "step"
voltage = [[0.0, 0.0], [0.5, 6.49]]
initial = "rest"
{trace}
[[trace]]
name = "load_change"
kind = "load_change"
voltage = [[0.0, 12.97]]
load_torque = [[0.0, 0.0], [{0.5 * duration!r}, 0.01]]
initial = "steady"
{trace}"""


def simulate_viscous(tmp: Path, duration: float) -> Path:
    """The viscous benchmark session (:func:`_plan_toml`) simulated into ``tmp/session``."""
    plan = tmp / "plan.toml"
    plan.write_text(_plan_toml(duration), encoding="utf-8")
    out = tmp / "session"
    subprocess.run([*cli_command(), "simulate", str(plan), "--out", str(out)], check=True,
                   stdout=subprocess.DEVNULL)
    return out


# -- timing ------------------------------------------------------------------------------
def _time_python(fn, arg, *, min_time: float, min_reps: int = 3):
    """Median wall time of one call of a plain Python function, after a warm-up call."""
    fn(arg)
    times, start = [], time.perf_counter()
    while len(times) < min_reps or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        fn(arg)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), len(times)


def _with_data(model, method: str):
    """``f((θ, data))`` for a model method, data as an argument (as the sampler calls it)."""
    return lambda a: getattr(model, method)(a[0], data=a[1])


def _likelihood_rates(model, base, tight, thetas, min_time) -> list[dict]:
    rows = []

    def add(path, batch, compile_s, call_s, reps):
        rows.append({"path": path, "batch": batch, "compile_s": compile_s, "call_s": call_s,
                     "rate": batch / call_s, "reps": reps})
        c = "" if compile_s is None else f"compile {compile_s:6.2f} s  "
        print(f"  {path:42s} {c}{1e3 * call_s:10.3f} ms/call  {_fmt_rate(batch / call_s):>9s}"
              f" evaluations/s  ({reps} calls)")

    th = np.asarray(thetas[0])
    call, reps = _time_python(base.log_posterior, th, min_time=2 * min_time)
    add(f"baseline: LSODA rtol {base.rtol:g}, atol {base.atol:g}", 1, None, call, reps)
    call, reps = _time_python(tight.log_posterior, th, min_time=2 * min_time)
    add(f"baseline: LSODA rtol {tight.rtol:g}, atol {tight.atol:g}", 1, None, call, reps)
    ode = _per_trace_log_posterior(model, lambda p, exp: simulate_ode(p, exp, **DIFFRAX_TOL))
    c, call, reps, _ = _measure(ode, jnp.asarray(th), min_time=min_time)
    add(f"diffrax Kvaerno5, rtol {DIFFRAX_TOL['rtol']:g}, atol {DIFFRAX_TOL['atol']:g}",
        1, c, call, reps)
    c, call, reps, _ = _measure(_with_data(model, "log_posterior"),
                                (jnp.asarray(th), model.data), min_time=min_time)
    add("exact, one θ", 1, c, call, reps)
    for b in (8, 32):
        c, call, reps, _ = _measure(_with_data(model, "log_posterior_batch"),
                                    (jnp.asarray(thetas[:b]), model.data), min_time=min_time)
        add(f"exact, batch of {b}", b, c, call, reps)
    def value_and_grad(a):  # one array out: value, then gradient
        v, g = jax.value_and_grad(lambda t: model.log_posterior(t, data=a[1]))(a[0])
        return jnp.concatenate([v[None], g])

    c, call, reps, _ = _measure(value_and_grad, (jnp.asarray(th), model.data),
                                min_time=min_time)
    add("exact, value and gradient, one θ", 1, c, call, reps)
    return rows


def _agreement(model, base, tight, thetas: dict) -> list[dict]:
    out = []
    for label, th in thetas.items():
        exact = float(model.log_likelihood(jnp.asarray(th)))
        row = {"at": label, "exact": exact, "base": base.log_likelihood(th) - exact,
               "tight": tight.log_likelihood(th) - exact}
        out.append(row)
        print(f"  {label:22s} exact {exact:16.6f}   Δ baseline {row['base']:+.2e}   "
              f"Δ tight baseline {row['tight']:+.2e}")
    return out


# -- sampling ----------------------------------------------------------------------------
def _ess(idata) -> dict:
    ess = az.ess(idata, method="bulk", var_names=list(ESS_PARAMS))
    return {n: float(ess[n]) for n in ESS_PARAMS}


def _project_sampler(model, fit) -> dict:
    """Two identical runs (same seed, same draws): the first compiles, the second not."""
    t0 = time.perf_counter()
    sample_posterior(model, fit, seed=0, progress=False)
    cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    post = sample_posterior(model, fit, seed=0, progress=False)
    warm = time.perf_counter() - t0
    t0 = time.perf_counter()
    to_inference_data(model, post.draws_log, post.log_prob, post.acceptance)
    record = time.perf_counter() - t0
    walkers = post.draws.shape[0]
    res = {"cold": cold, "warm": warm, "record": record, "ess": _ess(post.idata),
           "walkers": walkers, "steps": post.n_steps, "burn": post.burn_in,
           "kept": post.draws.shape[0] * post.draws.shape[1], "message": post.message,
           "evaluations": walkers * (post.n_steps + 1), "tau": post.tau,
           "share": post.idata.posterior.attrs.get("independence_share")}
    print(f"  {post.message}; {walkers} walkers, burn-in {post.burn_in}, "
          f"{res['kept']:,} kept draws")
    print(f"  wall: {cold:.2f} s cold (compiling), {warm:.2f} s warm, of which the ArviZ "
          f"record {record:.2f} s")
    for n in ESS_PARAMS:
        e = res["ess"][n]
        print(f"  {n}: bulk ESS {e:,.0f}: {e / warm:,.0f} /s warm, {e / cold:,.0f} /s cold, "
              f"{e / (warm - record):,.0f} /s without the record")
    return res


def _baseline_sampler(bl, base, fit, budget: float, walkers: int, base_rate: float,
                      project: dict) -> dict:
    rng = np.random.default_rng(0)
    p0 = rng.multivariate_normal(np.asarray(fit.theta), np.asarray(fit.cov_log),
                                 size=walkers, method="eigh")
    # the project's moves, at the share its run ended with (the baseline has no pilot)
    share = project["share"] if project["share"] is not None else 0.5
    moves = [(LaplaceMixture(LaplaceIndependenceMove(fit.theta, fit.cov_log), share=share), 1.0)]
    chain, wall, steps = bl.run_emcee(base.log_posterior, p0, budget_s=budget, seed=0,
                                      moves=moves)
    tau = emcee.autocorr.integrated_time(chain, tol=0)
    names = list(base.names)
    res = {"wall": wall, "steps": steps, "walkers": walkers, "tau": {}, "ess": {}, "rate": {},
           "per_eval_rate": {}}
    for n in ESS_PARAMS:
        k = names.index(n)
        res["tau"][n] = float(tau[k])
        res["ess"][n] = steps * walkers / float(tau[k])
        res["rate"][n] = res["ess"][n] / wall
        # The same sampler on the same density mixes the same per evaluation: the
        # project's ESS per log-posterior evaluation times the baseline's evaluations/s.
        res["per_eval_rate"][n] = project["ess"][n] / project["evaluations"] * base_rate
        print(f"  {n}: τ ≈ {tau[k]:.1f} steps over a {steps}-step run → "
              f"{res['rate'][n]:.3g} ESS/s (short run); {res['per_eval_rate'][n]:.3g} ESS/s "
              "(project's ESS per evaluation × baseline evaluations/s)")
    return res


def _user_script(bl, base, cf, budget: float, walkers: int, project: dict) -> dict:
    """The user's script (``baseline.user_script``): least squares from the closed form,
    then emcee's stretch move; ESS/s of the second half of the chain over the whole
    wall time (least squares and every emcee step)."""
    theta0 = np.log([cf.Ra, cf.La, cf.K, cf.B, cf.J])
    out = bl.user_script(base, theta0, budget_s=budget, walkers=walkers)
    chain, steps = out["chain"], out["steps"]
    kept = chain[steps // 2:]
    tau = emcee.autocorr.integrated_time(kept, tol=0)
    wall = out["least_squares_wall"] + out["wall"]
    names = list(base.names)
    res = {"wall": wall, "ls_wall": out["least_squares_wall"], "nfev": out["least_squares_nfev"],
           "steps": steps, "walkers": walkers, "tau": {}, "ess": {}, "rate": {}}
    print(f"  least squares {out['least_squares_wall']:.1f} s ({out['least_squares_nfev']} "
          f"evaluations), emcee {out['wall']:.0f} s ({steps} steps)")
    for n in ESS_PARAMS:
        k = names.index(n)
        res["tau"][n] = float(tau[k])
        res["ess"][n] = kept.shape[0] * walkers / float(tau[k])
        res["rate"][n] = res["ess"][n] / wall
        ratio = project["ess"][n] / project["warm"] / res["rate"][n]
        print(f"  {n}: τ ≈ {tau[k]:.1f} steps over the kept {kept.shape[0]} steps → "
              f"{res['rate'][n]:.3g} ESS/s; project {_fmt_rate(ratio)}× it")
    return res


# -- end to end --------------------------------------------------------------------------
def _end_to_end(tmp: Path, session: str, label: str, extra=()) -> dict:
    """``pmdc-bayes fit session`` twice on one fresh compilation cache: cold, then warm."""
    slug = _slug(label)
    cache = tmp / f"e2e-cache-{slug}"  # fresh: the cold run compiles everything
    out = {}
    for state in ("cold", "warm"):
        run_dir = tmp / f"e2e-{slug}-{state}"
        log = tmp / f"e2e-{slug}-{state}.log"
        r = run_measured([*cli_command(), "fit", session, "--out", str(run_dir), *extra],
                         env={"PMDC_BAYES_CACHE": str(cache)}, cwd=ROOT, log=log)
        summary = run_dir / "summary.json"
        if summary.exists():
            diag = json.loads(summary.read_text())["diagnostics"]
            r["stages"], r["compile"] = diag.get("wall_s", {}), diag.get("compile_s", {})
        else:
            tail = log.read_text().strip().splitlines()[-1:]
            r["error"] = tail[0] if tail else "no output"
        out[state] = r
        stages = ", ".join(f"{k} {v:.2f} s (compiling {r['compile'].get(k, 0.0):.2f} s)"
                           for k, v in r.get("stages", {}).items())
        print(f"  {label}, {state}: {r['wall']:.2f} s wall, exit {r['returncode']}, peak "
              f"{r['peak_mib']:,.0f} MiB ({r['peak_how']}); stages: {stages or r.get('error')}",
              flush=True)
    return out


def _slug(label: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "-", label).strip("-")


def _shapes(tmp: Path, cfg, simulated: Path) -> dict:
    """Cold and warm end-to-end runs: the demo (with and without MCMC) and two sessions
    of other shapes (the simulated viscous session; the bundled bench rig)."""
    runs = {}
    for label, session, extra in cfg["shapes"]:
        session = str(simulated) if session == "SIMULATED" else session
        runs[label] = _end_to_end(tmp, session, label, extra)
    return runs


def _hard_case(tmp: Path) -> dict:
    """The sampler on a non-Gaussian Coulomb posterior (``hard_posteriors.py``'s
    small-Coulomb case): a warm whole run with a 60 s sampling limit."""
    import hard_posteriors

    r = hard_posteriors.case(str(hard_posteriors.small_coulomb(tmp / "small-coulomb")), tmp,
                             "small-coulomb", extra=("--max-sampling-seconds",
                                                     str(hard_posteriors.SAMPLING_LIMIT)))
    print(f"  exit {r['exit']}, sampling {r['mcmc_s']:.1f} s, {r['steps']} steps, τ_max "
          f"{r['tau']:.0f} ({r['worst']}), gates {'passed' if r['passed'] else 'failed'}, "
          f"truth in the 94 % HDI: {len(r['covered'])} of {len(r['tried'])}", flush=True)
    return r


def _lot(tmp: Path, motors: int, cache: Path) -> dict:
    """``pmdc-bayes fit LOT`` on ``motors`` demo-shaped motors (``lot.py``), with MCMC and
    reports, on the compilation cache of the demo's end-to-end runs (the same shape)."""
    import lot

    lot.make_lot(tmp / "lot", motors)
    m = lot.run(tmp / "lot", tmp / "lot-runs", cache, True, tmp / "lot.log")
    print(f"  {m['wall']:.1f} s for {m['n']} motors: {m['per_minute']:.2f} motors/min, "
          f"{m['ok']} ok", flush=True)
    return m


# -- scaling -----------------------------------------------------------------------------
def _synthetic_session(n_traces: int, n: int, rng) -> Session:
    """``n_traces`` 100 Hz steps 0 → 12.97 V at 0.5 s from rest, ``n`` samples each: a
    first-order response plus noise (the data's values do not change the cost)."""
    t = np.arange(n) * 0.01
    den = TRUTH["K"] ** 2 + TRUTH["Ra"] * TRUTH["B"]
    tau_m = TRUTH["J"] * TRUTH["Ra"] / den
    rise = np.where(t >= 0.5, 1.0 - np.exp(-np.clip(t - 0.5, 0.0, None) / tau_m), 0.0)
    speed_ss, current_ss = TRUTH["K"] * 12.97 / den, TRUTH["B"] * 12.97 / den
    traces = []
    for k in range(n_traces):
        traces.append(Trace(
            f"step{k}", "step", Path(f"step{k}.csv"), t,
            speed_ss * rise + 0.3 * rng.standard_normal(n),
            current_ss * rise + 0.005 * rng.standard_normal(n),
            Schedule(np.array([0.0, 0.5]), np.array([0.0, 12.97])),
            Schedule(np.array([0.0]), np.array([0.0])), initial="rest"))
    return Session("scaling", Path("."), "synthetic", Measurement(8.5, 0.1, "ohm"),
                   Measurement(5.6e-3, 2e-4, "H"), traces=tuple(traces))


def _scaling(config, min_time: float, batch: int = 32) -> list[dict]:
    rng = np.random.default_rng(2)
    seed = SimpleNamespace(K=TRUTH["K"], B=TRUTH["B"], J=TRUTH["J"])
    cases = list(dict.fromkeys([(1, n) for n in config["sizes"]]
                               + [(k, 10_000) for k in config["traces"]]))
    rows = []
    for n_traces, n in cases:
        model = build_model(_synthetic_session(n_traces, n, rng), seed)
        theta0 = np.log([TRUTH[k] for k in model.names])
        thetas = jnp.asarray(theta0 + 0.01 * rng.standard_normal((batch, theta0.size)))
        c, call, reps, _ = _measure(_with_data(model, "log_posterior_batch"),
                                    (thetas, model.data), min_time=min_time)
        total = n_traces * n
        row = {"traces": n_traces, "n": n, "total": total, "compile_s": c, "call_s": call,
               "rate": batch / call, "ns": 1e9 * call / (batch * total), "reps": reps}
        rows.append(row)
        print(f"  {n_traces:2d} × {n:>9,}: compile {c:5.2f} s, {1e3 * call:9.2f} ms per batch of "
              f"{batch}, {_fmt_rate(row['rate']):>8s} evaluations/s, "
              f"{row['ns']:.2f} ns per sample and θ")
        del model
    return rows


# -- report ------------------------------------------------------------------------------
def _verdict(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def _section(m: dict, r: dict, quick: bool) -> str:
    today = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    cmd = "python benchmarks/run.py" + (" --quick" if quick else "")
    proj, bs, fitr = r["project"], r["baseline"], r["fit"]
    L = [f"## {SECTION}", "",
         f"Measured {today} by `{cmd}` in {r['elapsed'] / 60:.1f} min (what each figure "
         "means: `benchmarks/README.md`).", "",
         f"Machine: {m['cpu']}, {m['cores']} cores; {m['platform']}; Python {m['python']}, "
         f"jax {m['jax']}, jaxlib {m['jaxlib']}, diffrax {m['diffrax']}, emcee "
         f"{emcee.__version__}; device {m['device']}; x64 {'on' if m['x64'] else 'off'}.  "
         f"1-minute load average {m['load']} at the start and {m['load_end']} at the end "
         "(above the core count, other processes competed for the CPU and every figure "
         "is pessimistic).", "",
         f"Session: {r['session_label']}, simulated by `pmdc-bayes simulate` (viscous "
         f"friction, 5 parameters, {r['n_obs']:,} observations in {r['n_channels']} "
         "channels).", ""]
    if quick:
        L += ["**`--quick` smoke run: sizes are not the targets'; verdicts do not count.**", ""]
    # agreement
    worst_base = max(abs(a["base"]) for a in r["agreement"])
    worst_tight = max(abs(a["tight"]) for a in r["agreement"])
    L += ["### Log-likelihood agreement", "",
          "Baseline (`benchmarks/baseline.py`) minus exact path, same θ, same channels, "
          "noise scales and priors:", "",
          "| θ | exact log-likelihood | Δ baseline (rtol 1e-6, atol 1e-8) "
          "| Δ baseline (rtol 1e-9, atol 1e-11) |", "|---|---:|---:|---:|"]
    L += [f"| {a['at']} | {a['exact']:.6f} | {a['base']:+.2e} | {a['tight']:+.2e} |"
          for a in r["agreement"]]
    L += ["", f"- {_verdict(worst_tight <= AGREEMENT)}: the baseline computes the same "
          f"log-likelihood to {worst_tight:.1e} (≤ {AGREEMENT:g}) when LSODA is run at "
          "rtol 1e-9, atol 1e-11.",
          f"- {_verdict(worst_base <= AGREEMENT)}: at the issue's tolerances (rtol 1e-6, "
          f"atol 1e-8) the difference is up to {worst_base:.1e}: LSODA's own error "
          "(speeds of ~200 rad/s carried to ~1e-4 rad/s over 10,000 samples), shrinking "
          "about tenfold per decade of tolerance.  The timings below use these faster "
          "tolerances, which favours the baseline.", ""]
    # evaluations
    base_rate = r["rates"][0]["rate"]
    L += ["### Log-posterior evaluations per second", "",
          "| path | θ per call | compile (s) | time per call (ms) | evaluations/s "
          "| × baseline |", "|---|---:|---:|---:|---:|---:|"]
    for row in r["rates"]:
        c = "—" if row["compile_s"] is None else f"{row['compile_s']:.2f}"
        L.append(f"| {row['path']} | {row['batch']} | {c} | {1e3 * row['call_s']:.3g} | "
                 f"{_fmt_rate(row['rate'])} | {_fmt_rate(row['rate'] / base_rate)} |")
    L += ["", "MAP fit (`fit_map`, 8 starts, Levenberg–Marquardt around the compiled "
          f"Gauss–Newton kernel): "
          f"{fitr['warm']:.2f} s after compilation, {fitr['cold']:.2f} s on the first call "
          f"({fitr['message']}).", ""]
    # compile
    L += ["### Compile times", "",
          "| what | seconds |", "|---|---:|"]
    for row in r["rates"]:
        if row["compile_s"] is not None:
            L.append(f"| {row['path']} (`jit(...).lower(...).compile()`) | "
                     f"{row['compile_s']:.2f} |")
    L += [f"| MAP fit: first call − second call | {fitr['cold'] - fitr['warm']:.2f} |",
          f"| sampler: first `sample_posterior` − second | {proj['cold'] - proj['warm']:.2f} |"]
    for label, runs in r["e2e"].items():
        L.append(f"| end to end, {label}: cold-cache run − warm-cache run | "
                 f"{runs['cold']['wall'] - runs['warm']['wall']:.2f} |")
    L.append("")
    # ESS
    L += ["### Effective samples per second", "",
          f"Project: `sample_posterior` (emcee, {proj['walkers']} walkers, "
          f"{_moves_label(proj.get('share'))}, batched exact log-posterior) from the MAP's Laplace "
          f"approximation; {proj['message']}; {proj['kept']:,} kept draws after a burn-in of "
          f"{proj['burn']} steps.  ESS: ArviZ bulk ESS of the kept draws (walkers as "
          "chains).  Times: the whole `sample_posterior` call (initial ensemble, emcee "
          "steps, τ checks, the ArviZ record with its pointwise log-likelihood), "
          f"{proj['warm']:.2f} s with every function already compiled and "
          f"{proj['cold']:.2f} s on the first call, which compiles; the ArviZ record alone "
          f"(`to_inference_data`, timed again on its own) takes {proj['record']:.2f} s.", "",
          f"Baseline: emcee with the same {bs['walkers']} walkers and moves (the "
          "independence share fixed at the one the project's run ended with), one Python "
          f"log-probability call per walker and step, run for a fixed "
          f"{bs['wall']:.0f} s budget ({bs['steps']} steps) from the same start.  "
          "**Extrapolated**: τ from `emcee.autocorr.integrated_time(chain, tol=0)` on this "
          "short run, ESS = draws / τ, as if a long run kept mixing at that rate (no "
          "burn-in charged; a τ estimated from a short chain is biased low, so this "
          "flatters the baseline).  Second estimate: the project's ESS per log-posterior "
          "evaluation (same algorithm, same density) times the baseline's evaluations/s.  "
          "The ratio divides the project's warm ESS/s (whole call) by each of the two; the "
          "target is judged on the smaller ratio.", "",
          "| parameter | project ESS | ESS/s: sampling only, warm | ESS/s: whole call, warm "
          "| ESS/s: whole call, incl. compile | baseline τ (steps) "
          "| baseline ESS/s, short run (extrapolated) "
          "| baseline ESS/s, per evaluation (extrapolated) | ratio: short run "
          "| ratio: per evaluation |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for n in ESS_PARAMS:
        e = proj["ess"][n]
        rate = e / proj["warm"]
        L.append(f"| {n} | {e:,.0f} | {e / (proj['warm'] - proj['record']):,.0f} | "
                 f"{rate:,.0f} | {e / proj['cold']:,.0f} | {bs['tau'][n]:.1f} | "
                 f"{bs['rate'][n]:.3g} | {bs['per_eval_rate'][n]:.3g} | "
                 f"{_fmt_rate(rate / bs['rate'][n])} | "
                 f"{_fmt_rate(rate / bs['per_eval_rate'][n])} |")
    L += ["", "\"Sampling only\" is the whole warm call minus the ArviZ record measured on "
          "its own (the initial ensemble, the emcee steps and the τ checks).", ""]
    us = r["user"]
    L += ["**The user's script** (`baseline.user_script`): what a careful user writes "
          "without this project: the same LSODA model (rtol 1e-6), "
          "`scipy.optimize.least_squares` on the noise-scaled residuals from the closed "
          f"form ({us['ls_wall']:.1f} s, {us['nfev']} evaluations), then emcee with its "
          f"default stretch move, {us['walkers']} walkers started in a 1e-4 ball around "
          f"the least-squares solution, for {us['wall'] - us['ls_wall']:.0f} s "
          f"({us['steps']} steps). ESS from τ of the second half of the chain (the first "
          "half is burn-in), over the whole wall time.", "",
          "| parameter | τ (steps) | user's ESS/s | project ESS/s, whole call, warm "
          "| ratio |", "|---|---:|---:|---:|---:|"]
    for n in ESS_PARAMS:
        rate = proj["ess"][n] / proj["warm"]
        L.append(f"| {n} | {us['tau'][n]:.1f} | {us['rate'][n]:.3g} | {rate:,.0f} | "
                 f"{_fmt_rate(rate / us['rate'][n])}× |")
    L.append("")
    # end to end
    L += ["### End to end: `pmdc-bayes fit` on sessions of several shapes", "",
          "Wall time of the whole command (subprocess: interpreter start, imports, fit, "
          "posterior, writing), with `PMDC_BAYES_CACHE` set to a fresh directory (cold: "
          "everything compiles) and then to the same directory again (warm: compiled "
          "functions from the cache).  Stages from `summary.json`'s "
          "`diagnostics.wall_s`, in brackets the seconds of it spent making JAX programs "
          "(tracing, lowering, compiling or loading them from the cache: "
          "`diagnostics.compile_s`, in any thread, so the programs of the later stages, "
          "which a thread makes while the MAP runs, count in the MAP's row; they can "
          "exceed the wall time; where the model search ran, its row holds the closed "
          "form, MAP and adequacy of the model it chose, which the run goes on from); "
          "\"other\" is the process wall time minus their total "
          "(start-up, imports, writing the run directory).  The shapes: `data/demo` (4 "
          "traces, 10,204 samples, Coulomb friction, speed and current), the simulated "
          "session above (3 traces × 10,000 samples, viscous), `data/bench` (4 traces of "
          "encoder counts, no current, a shared dead time, a voltage drop, a current "
          "limit, a brake's drag; a 60 s sampling limit).", ""]
    stage_keys = list(dict.fromkeys(k for runs in r["e2e"].values() for v in runs.values()
                                    for k in v.get("stages", {}) if k != "total"))
    L += ["| session | run | wall (s) | " + " | ".join(f"{k} (s)" for k in stage_keys)
          + " | other (s) | exit | peak memory (MiB) |",
          "|---|---|---:|" + "---:|" * len(stage_keys) + "---:|---:|---:|"]
    for session, runs in r["e2e"].items():
        for label, v in runs.items():
            st, co = v.get("stages", {}), v.get("compile", {})
            cells = [(f"{st[k]:.2f}" + (f" ({co[k]:.2f})" if k in co else ""))
                     if k in st else "—" for k in stage_keys]
            other = f"{v['wall'] - st['total']:.2f}" if "total" in st else "—"
            L.append(f"| {session} | {label} | {v['wall']:.2f} | " + " | ".join(cells)
                     + f" | {other} | {v['returncode']} | {v['peak_mib']:,.0f} |")
    how = next(iter(next(iter(r["e2e"].values())).values()))["peak_how"]
    L += ["", f"Peak memory: maximum resident set size of the process ({how}).", ""]
    if "hard" in r:
        h = r["hard"]
        L += ["### The sampler on a non-Gaussian Coulomb posterior", "",
              "`hard_posteriors.py`'s small-Coulomb case (the demo's plan with a tenth of "
              "its Coulomb torque, so that Tc trades against B): a whole warm `pmdc-bayes "
              f"fit` with a 60 s sampling limit: exit {h['exit']}, "
              f"{h['mcmc_s']:.1f} s of sampling (the stage), {h['steps']} steps, τ_max "
              f"{h['tau']:.0f} steps ({h['worst']}), gates "
              f"{'passed' if h['passed'] else 'failed'}, truth in the 94 % HDI for "
              f"{len(h['covered'])} of {len(h['tried'])} parameters.  The harder cases "
              "(data/bench): `## The sampler on hard posteriors`.", ""]
    if "lot" in r:
        m = r["lot"]
        L += ["### A lot of motors", "",
              f"`pmdc-bayes fit LOT` on {m['n']} demo-shaped simulated motors (`lot.py`'s "
              "lot), MCMC and reports, in one process, on the compilation cache the demo's "
              f"runs filled: {m['wall']:.1f} s, **{m['per_minute']:.2f} motors per "
              f"minute**, {m['ok']} of {m['n']} ok; per motor, the first "
              f"{m['per_motor'][0]:.1f} s and the later ones "
              f"{statistics.median(m['per_motor'][1:]):.1f} s (median).", ""]
    # scaling
    L += ["### Scaling", "",
          "Batched exact log-posterior (32 θ per call, data as an argument, as the sampler "
          "calls it) on synthetic sessions of 100 Hz step traces; cost per sample and θ = "
          "time per call ÷ (32 × samples).  A constant cost per sample means the cost "
          "grows linearly.", "",
          "| traces × samples | samples | compile (s) | time per call (ms) | evaluations/s "
          "| ns per sample and θ |", "|---|---:|---:|---:|---:|---:|"]
    for s in r["scaling"]:
        L.append(f"| {s['traces']} × {s['n']:,} | {s['total']:,} | {s['compile_s']:.2f} | "
                 f"{1e3 * s['call_s']:.3g} | {_fmt_rate(s['rate'])} | {s['ns']:.2f} |")
    L += ["", *_scaling_notes(r["scaling"]), ""]
    L += ["### Targets", "", *_targets(r, quick), ""]
    return "\n".join(L)


def _moves_label(share: float | None = None) -> str:
    """The sampler's default moves (they need a fit only for their centre and scale),
    and the independence proposals' share of the steps the run ended with."""
    stand_in = SimpleNamespace(theta=np.zeros(1), cov_log=np.eye(1))
    (mix, _), = default_moves(stand_in)
    end = "" if share is None else f", {share:g} in the run measured"
    return (f"{ENSEMBLES} independent ensembles, {type(mix).__name__}: "
            f"{type(mix.independence).__name__} on {mix.share:g} of the steps "
            f"({SHARE_TRUSTED:g} once trusted{end}), {type(mix.other).__name__} on the rest")


def _scaling_notes(rows) -> list[str]:
    """Step by step: how much the time per call grows against the samples (1 = linear)."""
    out = []
    for key, label in (("n", "samples per trace (1 trace)"),
                       ("traces", "traces (10,000 samples each)")):
        group = [s for s in rows if (s["traces"] == 1 if key == "n" else s["n"] == 10_000)]
        if len(group) < 2:
            continue
        steps = [f"{b['total'] / a['total']:g}× samples → {b['call_s'] / a['call_s']:.3g}× "
                 "time" for a, b in zip(group, group[1:], strict=False)]
        ns = [s["ns"] for s in group]
        out.append(f"- Over {label}: " + "; ".join(steps) + f".  Cost per sample and θ "
                   f"{min(ns):.3g} to {max(ns):.3g} ns.")
    ns = sorted(s["ns"] for s in rows)
    if len(ns) >= 2:
        first, last = min(rows, key=lambda s: s["total"]), max(rows, key=lambda s: s["total"])
        out.append(f"- All sizes: {last['total'] / first['total']:,.0f}× the samples cost "
                   f"{last['call_s'] / first['call_s']:,.0f}× the time per call; the cost per "
                   f"sample and θ stays between {ns[0]:.3g} and {ns[-1]:.3g} ns (median "
                   f"{statistics.median(ns):.3g} ns).  Linear growth keeps it constant; "
                   "under load, single figures vary by up to 2-3× from run to run.")
    return out


def _targets(r: dict, quick: bool) -> list[str]:
    proj, bs, e2e = r["project"], r["baseline"], r["e2e"]
    tag = " (--quick sizes, not the target's)" if quick else ""
    out = []
    for n in ESS_PARAMS:
        rate = proj["ess"][n] / proj["warm"]
        only = proj["ess"][n] / (proj["warm"] - proj["record"])
        out.append(f"- {_verdict(rate >= TARGET_ESS)}{tag}: {n}: {rate:,.0f} effective "
                   f"samples/s (whole `sample_posterior` call, warm; "
                   f"{proj['ess'][n] / proj['cold']:,.0f} including compilation; "
                   f"{only:,.0f} sampling only, without the ArviZ record), target ≥ "
                   f"{TARGET_ESS:,.0f}"
                   + ("" if rate >= TARGET_ESS else f": {rate / TARGET_ESS:.0%} of it"))
    for n in ESS_PARAMS:
        ratio = proj["ess"][n] / proj["warm"] / max(bs["rate"][n], bs["per_eval_rate"][n])
        out.append(f"- {_verdict(ratio >= TARGET_RATIO)}{tag}: {n}: {_fmt_rate(ratio)}× the "
                   f"baseline's effective samples/s, target ≥ {TARGET_RATIO:,.0f}×"
                   + ("" if ratio >= TARGET_RATIO else f": {ratio / TARGET_RATIO:.0%} of it"))
    for n in ESS_PARAMS:
        ratio = proj["ess"][n] / proj["warm"] / r["user"]["rate"][n]
        out.append(f"- {_verdict(ratio >= TARGET_RATIO)}{tag}: {n}: {_fmt_rate(ratio)}× the "
                   f"user's script (least squares + emcee stretch), target ≥ "
                   f"{TARGET_RATIO:,.0f}×"
                   + ("" if ratio >= TARGET_RATIO else f": {ratio / TARGET_RATIO:.0%} of it"))
    demo, bare = e2e.get("data/demo"), e2e.get("data/demo --no-mcmc")
    checks = []
    if demo:
        checks += [("`pmdc-bayes fit data/demo` with an empty compilation cache",
                    demo["cold"], TARGET_E2E),
                   ("`pmdc-bayes fit data/demo` with a warm cache", demo["warm"], TARGET_WARM)]
    if bare:
        checks.append(("`pmdc-bayes fit data/demo --no-mcmc` with an empty cache",
                       bare["cold"], TARGET_NO_MCMC))
    for what, v, target in checks:
        w, rc = v["wall"], v["returncode"]
        out.append(f"- {_verdict(w <= target and rc == 0)}{tag}: {what}: {w:.1f} s (exit "
                   f"{rc}), target ≤ {target:.0f} s"
                   + ("" if w <= target else f": {w / target:.1f}× it")
                   + ("" if rc == 0 else ": the command failed"))
    if "hard" in r:
        h = r["hard"]
        ok = h["mcmc_s"] <= TARGET_SAMPLING + 5 and (h["passed"] or h["exit"] == 1)
        out.append(f"- {_verdict(ok)}: non-Gaussian Coulomb posterior: gates "
                   f"{'passed' if h['passed'] else 'failed with a reason'} after "
                   f"{h['mcmc_s']:.1f} s of sampling, target: passed or stopped with a "
                   f"reason within {TARGET_SAMPLING:.0f} s")
    if "lot" in r:
        m = r["lot"]
        out.append(f"- {_verdict(m['per_minute'] >= TARGET_LOT)}: {m['per_minute']:.2f} "
                   f"demo-shaped motors per minute with MCMC and reports, target ≥ "
                   f"{TARGET_LOT:.0f}"
                   + ("" if m["per_minute"] >= TARGET_LOT
                      else f": {m['per_minute'] / TARGET_LOT:.0%} of it"))
    return out


# -- main --------------------------------------------------------------------------------
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: 3 x 1,000 samples, short budgets, end to end on "
                         "'paper'; report untouched")
    ap.add_argument("--report", type=Path, default=REPORT,
                    help=f"markdown file whose '{SECTION}' section is replaced ({REPORT})")
    ap.add_argument("--no-report", action="store_true", help="print only")
    ap.add_argument("--baseline-budget", type=float, default=None,
                    help="seconds of baseline emcee (default 90; 8 with --quick)")
    args = ap.parse_args(argv)
    cfg = QUICK if args.quick else FULL
    budget = args.baseline_budget or cfg["budget"]
    start = time.perf_counter()
    machine = _machine()
    print("Machine:")
    for k, v in machine.items():
        print(f"  {k:9s} {v}")
    r: dict = {}
    bl = load_baseline()
    with tempfile.TemporaryDirectory(prefix="pmdc-bench-") as tmpdir:
        tmp = Path(tmpdir)
        simulated = simulate_viscous(tmp, cfg["duration"])
        session = load_session(simulated)
        cf = closed_form(session)
        model = build_model(session, cf)
        r["session_label"] = (f"{len(session.traces)} traces × "
                              + " + ".join(f"{tr.n:,}" for tr in session.traces) + " samples")
        r["n_obs"] = int(sum(c.n for c in model.channels))
        r["n_channels"] = sum(c.n > 0 for c in model.channels)
        print(f"\nSession: {r['session_label']}")
        base = bl.BaselinePosterior(session, cf)
        tight = bl.BaselinePosterior(session, cf, **TIGHT)
        if not np.allclose(base.s0, model.s0, rtol=1e-12, atol=0) or not np.array_equal(
                base.n_obs, model.n_obs):
            raise SystemExit("baseline channels differ from the model's: fix baseline.py")
        theta0 = np.asarray(model.theta(session.truth))
        rng = np.random.default_rng(0)
        thetas = theta0 + 0.01 * rng.standard_normal((32, theta0.size))

        print("\nMAP fit:")
        t0 = time.perf_counter()
        fit_map(model)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        fit = fit_map(model)
        r["fit"] = {"cold": cold, "warm": time.perf_counter() - t0, "message": fit.message}
        print(f"  {r['fit']['cold']:.2f} s first call, {r['fit']['warm']:.2f} s second; "
              f"{fit.message}")

        print("\nLog-likelihood agreement (baseline − exact):")
        r["agreement"] = _agreement(model, base, tight, {
            "truth": theta0, "MAP": np.asarray(fit.theta),
            "truth + 1 % noise (a)": thetas[0], "truth + 1 % noise (b)": thetas[1]})

        print("\nLog-posterior evaluations per second:")
        r["rates"] = _likelihood_rates(model, base, tight, thetas, cfg["min_time"])

        print("\nProject sampler:")
        r["project"] = _project_sampler(model, fit)
        print(f"\nBaseline emcee ({budget:.0f} s budget):")
        r["baseline"] = _baseline_sampler(bl, base, fit, budget, r["project"]["walkers"],
                                          r["rates"][0]["rate"], r["project"])
        print(f"\nThe user's script (least squares + emcee stretch, {budget:.0f} s budget):")
        r["user"] = _user_script(bl, base, cf, budget, r["project"]["walkers"], r["project"])
        del model

        print("\nEnd to end (cold: an empty compilation cache; warm: the same cache again):")
        r["e2e"] = _shapes(tmp, cfg, simulated)
        if not args.quick:
            print("\nThe sampler on a non-Gaussian Coulomb posterior (demo × 0.1 Tc):")
            r["hard"] = _hard_case(tmp)
        if cfg["motors"]:
            print(f"\nA lot of {cfg['motors']} demo-shaped motors in one command:")
            r["lot"] = _lot(tmp, cfg["motors"], tmp / f"e2e-cache-{_slug('data/demo')}")

        print("\nScaling (batch of 32):")
        r["scaling"] = _scaling(cfg, cfg["min_time"])
    machine["load_end"] = _load()
    r["elapsed"] = time.perf_counter() - start
    print(f"\n1-minute load average at the end: {machine['load_end']}; "
          f"{r['elapsed'] / 60:.1f} min in all")
    section = _section(machine, r, args.quick)
    print("\n" + section)
    if args.quick or args.no_report:
        print(f"{args.report}: not written ({'--quick' if args.quick else '--no-report'})")
    else:
        replace_section(args.report, SECTION, section)
        print(f"{args.report}: section '{SECTION}' updated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
