"""Issue 14's ideas for speed, each measured on its own.

On the bundled demo (and the sessions named per row), in one process unless a row says
a subprocess:

* **cached programs called eagerly or through jit**: the batched log-posterior the
  sampler calls, loaded from the disk cache (``jax.export``), called as the exported
  program (``Exported.call``, dispatched op by op) and through ``jax.jit``: time per call;
* **independent ensembles in threads**: ``sample_posterior`` with its two ensembles
  stepped in threads (the default) and one after the other: wall time, same draws;
* **posterior.nc compressed or not**: ``to_netcdf`` of the demo's ArviZ record;
* **gradient-informed proposals**: the cost of the log-posterior's value and gradient
  against its value alone, per θ at the sampler's batch, the price of each leapfrog
  step of a gradient-based sampler against one proposal of the present moves;
* **a parameterisation closer to Gaussian**: on the bench's posterior (``data/bench``,
  its declared model, sampled without a time limit), the largest excess kurtosis of
  the draws along any direction (4,000 random ones, after whitening) in the sampler's
  coordinates (log B, log Tc), with B and Tc linear, and as friction torques at two
  reference speeds (a quarter of the top speed and the top speed);
* **shape buckets**: ``pmdc-bayes fit`` (subprocesses) of a demo-like session whose
  traces are 10 % longer, with the compilation cache of the demo (a new shape: what
  every session of a new shape pays today) and again with its own cache (what a
  shape bucket shared with the demo would give at most), against the cost of padding
  from the scaling of a log-posterior evaluation with samples.

Prints the table and replaces the section ``## Issue 14's ideas, measured`` of
``reports/benchmarks.md`` (``--no-report`` to print only).

    python benchmarks/ideas.py      # ~4 min on 2 cores
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from _common import ROOT, cli_command, run_measured, write_table_section

from pmdc_bayes.inference import _runtime as cache
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.inference.sampling import ensembles
from pmdc_bayes.inference.sampling.posterior import _log_posterior_batch, sample_posterior
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.session import simulate_session

SECTION = "Issue 14's ideas, measured"


def _per_call(fn, arg, min_time: float = 1.0) -> float:
    """Median seconds per call, after a warm-up call."""
    jax.block_until_ready(fn(arg))
    times, start = [], time.perf_counter()
    while len(times) < 5 or time.perf_counter() - start < min_time:
        t0 = time.perf_counter()
        jax.block_until_ready(fn(arg))
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def cached_call(model, thetas) -> tuple[float, float]:
    """The batched log-posterior from the disk cache: eager ``Exported.call`` against the
    jit-compiled call (ms per call)."""
    _log_posterior_batch(model)(thetas)  # exported and loaded
    (program,) = {id(p): p for p in cache._IN_MEMORY.values()
                  if isinstance(p, cache._Exported) and "log_posterior_batch" in p.stem.name
                  }.values()
    jitted = next(iter(program.programs.values()))
    exported = jitted.__wrapped__.__self__  # the Exported whose call jit wraps
    args = (thetas, model.data)
    eager = _per_call(lambda a: exported.call(*a), args)
    through_jit = _per_call(lambda a: jitted(*a), args)
    return 1e3 * eager, 1e3 * through_jit


def ensembles_in_threads(model, fit) -> tuple:
    """``sample_posterior`` wall time with the ensembles in threads and one after the
    other; whether the draws agree."""
    threaded = ensembles.Ensembles.run_mcmc

    def one_after_the_other(self, n):
        self.states = [s.run_mcmc(st, n, progress=False)
                       for s, st in zip(self.samplers, self.states, strict=True)]

    sample_posterior(model, fit, progress=False)  # compiles
    out, draws = {}, {}
    for label, run in (("threads", threaded), ("sequential", one_after_the_other)) * 2:
        ensembles.Ensembles.run_mcmc = run
        try:
            t0 = time.perf_counter()
            post = sample_posterior(model, fit, progress=False)
            out.setdefault(label, []).append(time.perf_counter() - t0)
            draws[label] = post.draws
        finally:
            ensembles.Ensembles.run_mcmc = threaded
    same = bool(np.array_equal(draws["threads"], draws["sequential"]))
    return min(out["threads"]), min(out["sequential"]), same, post


def netcdf(idata, tmp: Path) -> dict:
    out = {}
    for compress in (True, False):
        path = tmp / f"posterior-{compress}.nc"
        t0 = time.perf_counter()
        idata.to_netcdf(path, compress=compress)
        out[compress] = (time.perf_counter() - t0, path.stat().st_size / 1e6)
    return out


def gradient_cost(model, thetas) -> tuple[float, float]:
    """ms per call at the sampler's batch: the value, and the value with its gradient."""
    value = jax.jit(lambda t, d: model.log_posterior_batch(t, data=d))
    grad = jax.jit(lambda t, d: jax.vmap(jax.value_and_grad(
        lambda x: model.log_posterior(x, data=d)))(t))
    args = (thetas, model.data)
    return (1e3 * _per_call(lambda a: value(*a), args),
            1e3 * _per_call(lambda a: grad(*a), args))


def _max_kurtosis(y: np.ndarray, rng) -> float:
    """The largest excess kurtosis of the whitened draws ``y`` along 4,000 random
    directions (0 for a Gaussian)."""
    y = y - y.mean(axis=0)
    z = np.linalg.solve(np.linalg.cholesky(np.cov(y.T)), y.T).T
    u = rng.standard_normal((4000, y.shape[1]))
    proj = z @ (u / np.linalg.norm(u, axis=1, keepdims=True)).T
    return float(np.max(np.mean(proj**4, axis=0) / np.mean(proj**2, axis=0) ** 2 - 3))


def parameterisations() -> dict:
    """The bench posterior's largest directional excess kurtosis in three coordinates."""
    import pmdc_bayes

    t0 = time.perf_counter()
    r = pmdc_bayes.fit("bench", max_sampling_seconds=None, progress=False)
    wall = time.perf_counter() - t0
    names = list(r.model.names)
    x = np.stack([r.idata.posterior[n].values.reshape(-1) for n in names], axis=1)
    logged = [r.model.registry[n].transform == "log" for n in names]
    theta = np.where(logged, np.log(np.abs(x) + 1e-300), x)
    b, tc = names.index("B"), names.index("Tc")
    top = max(float(np.nanmax(np.abs(tr.speed))) for tr in r.session.traces
              if tr.speed is not None)  # the speed logged or read from the counts
    linear, torques = theta.copy(), theta.copy()
    linear[:, b], linear[:, tc] = x[:, b], x[:, tc]
    torques[:, b] = np.log(x[:, tc] + x[:, b] * top / 4)
    torques[:, tc] = np.log(x[:, tc] + x[:, b] * top)
    rng = np.random.default_rng(0)
    return {"wall": wall, "message": r.summary["diagnostics"]["sampler_message"],
            "log": _max_kurtosis(theta, rng), "linear": _max_kurtosis(linear, rng),
            "torques": _max_kurtosis(torques, rng), "top": top}


def longer_demo(folder: Path, factor: float = 1.1) -> Path:
    """The demo's plan with every trace ``factor`` times longer, simulated."""
    text = (ROOT / "data" / "demo" / "plan.toml").read_text(encoding="utf-8")
    text = re.sub(r"(?m)^(duration = )([0-9.eE+-]+)",
                  lambda m: f"{m.group(1)}{float(m.group(2)) * factor:.6g}", text)
    folder.mkdir(parents=True)
    (folder / "plan.toml").write_text(text, encoding="utf-8")
    simulate_session(folder / "plan.toml", folder, seed=5)
    return folder


def shape_buckets(tmp: Path) -> dict:
    """Wall time of a new-shape session with the demo's cache, then with its own."""
    demo_cache, own = tmp / "cache-demo", tmp / "cache-own"
    session = longer_demo(tmp / "longer")
    runs = {}
    for label, cmd_session, cache_dir in (("demo (fills the cache)", "data/demo", demo_cache),
                                          ("new shape, demo's cache", str(session), demo_cache),
                                          ("new shape, its own cache", str(session), own),
                                          ("new shape, its own cache again", str(session), own)):
        out = tmp / re.sub(r"[^A-Za-z0-9]+", "-", label)
        m = run_measured([*cli_command(), "fit", cmd_session, "--out", str(out), "--quiet"],
                         env={"PMDC_BAYES_CACHE": str(cache_dir)}, cwd=ROOT,
                         log=out.with_suffix(".log"))
        runs[label] = m
        print(f"  {label}: {m['wall']:.1f} s, exit {m['returncode']}", flush=True)
    return runs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-report", action="store_true")
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cache.enable_cache(tmp / "cache-in-process")
        session = load_session(ROOT / "data" / "demo")
        model = build_model(session, fit_seed(session))
        fit = fit_map(model)
        walkers = max(32, 4 * len(model.names))  # sample_posterior's default
        batch = walkers // (2 * ensembles.ENSEMBLES)  # what each call of a move evaluates
        rng = np.random.default_rng(0)
        thetas = jnp.asarray(np.asarray(fit.theta) + 1e-3 * rng.standard_normal(
            (batch, len(model.names))))

        eager, jitted = cached_call(model, thetas)
        print(f"cached program: {eager:.2f} ms eager, {jitted:.2f} ms through jit", flush=True)
        rows.append(("a cached program called through jit, not eagerly",
                     f"the sampler's batched log-posterior ({batch} θ) from the disk cache: "
                     f"{eager:.2f} ms per call as `Exported.call`, {jitted:.2f} ms through "
                     f"`jax.jit`", f"{eager / jitted:.1f}× per call; kept"))

        threads, sequential, same, post = ensembles_in_threads(model, fit)
        print(f"ensembles: {threads:.2f} s in threads, {sequential:.2f} s one after the "
              f"other; same draws: {same}", flush=True)
        rows.append(("independent ensembles in threads",
                     f"`sample_posterior` on the demo: {threads:.2f} s in threads, "
                     f"{sequential:.2f} s one after the other (best of two); same draws: "
                     f"{'yes' if same else 'NO'}", f"{sequential / threads:.2f}× faster; kept"))

        nc = netcdf(post.idata, tmp)
        (tc, sc), (tu, su) = nc[True], nc[False]
        print(f"posterior.nc: compressed {tc:.2f} s {sc:.0f} MB; uncompressed {tu:.2f} s "
              f"{su:.0f} MB", flush=True)
        rows.append(("posterior.nc uncompressed",
                     f"`to_netcdf` of the demo's record: {tc:.2f} s and {sc:.0f} MB "
                     f"compressed, {tu:.2f} s and {su:.0f} MB not",
                     f"{tc - tu:.1f} s less per run for {su / sc - 1:.0%} more disk; kept"))

        value, grad = gradient_cost(model, thetas)
        print(f"gradient: value {value:.2f} ms, value and gradient {grad:.2f} ms per batch "
              f"of {batch}", flush=True)
        rows.append(("gradient-informed proposals",
                     f"per batch of {batch} θ: the log-posterior {value:.2f} ms, with its "
                     f"gradient {grad:.2f} ms",
                     f"one leapfrog step costs {grad / value:.1f} proposals of the present "
                     f"moves; with ~10 per trajectory a gradient sampler must cut τ "
                     f"{10 * grad / value:.0f}-fold to break even (demo τ ≈ "
                     f"{max(post.tau.values()):.0f} steps); not built"))

        print("parameterisations (data/bench, no time limit):", flush=True)
        k = parameterisations()
        print(f"  {k}", flush=True)
        rows.append(("a parameterisation closer to Gaussian",
                     f"data/bench's posterior ({k['message']}): largest excess kurtosis "
                     f"along a direction {k['log']:.1f} in the sampler's coordinates (log B, "
                     f"log Tc), {k['linear']:.1f} with B and Tc linear, {k['torques']:.1f} as "
                     f"log friction torques at {k['top'] / 4:.0f} and {k['top']:.0f} rad/s",
                     "part of the heavy tail is the logarithm of a small Tc; the rest is "
                     "the data's own trade-off of B, Tc and the voltage drop, which torques "
                     "at two speeds remove no better than B and Tc linear (linear torques "
                     "are an affine change of B and Tc, to which the moves are blind); not "
                     "built"))

        print("shape buckets (subprocesses):", flush=True)
        runs = shape_buckets(tmp)
        new, own = runs["new shape, demo's cache"], runs["new shape, its own cache again"]
        rows.append(("shape buckets",
                     f"`pmdc-bayes fit` of a demo-like session 10 % longer: {new['wall']:.1f} s "
                     f"with the demo's cache (a new shape compiles), {own['wall']:.1f} s with "
                     "its own (what sharing a bucket with the demo could give at most)",
                     f"at most {new['wall'] - own['wall']:.1f} s per new shape, paid for by "
                     "evaluating the padding on every call (the cost grows linearly with "
                     "samples: up to 2× for power-of-two buckets); not built"))
    for what, measured, verdict in rows:
        print(f"- {what}: {measured}: {verdict}")
    if args.no_report:
        return 0
    intro = ("`python benchmarks/ideas.py` ({stamp}): the ideas of issue 14 measured one "
             "by one on the demo (what each row times: the script's docstring). The "
             "compilation of the sampler's programs in a thread during the MAP fit and the "
             "adequacy checks was measured by hand on 2026-11-25 (demo, 2 cores): cold "
             "21.1 → 20.6 s, warm 11.9 → 11.4 s, peak memory +270 MB cold, because XLA's "
             "compilations and the tracing compete for the same two cores; not kept.")
    write_table_section(SECTION, intro, ("idea", "measured", "result"),
                        ("---", "---", "---"), rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
