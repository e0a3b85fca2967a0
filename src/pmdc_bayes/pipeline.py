"""The ``pmdc-bayes fit`` pipeline: closed form → MAP (→ MCMC), written atomically.

A run directory is built beside its destination under a temporary name and renamed
into place only when complete, so a crash never leaves a half-written run and never
replaces a good one.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from datetime import datetime
from importlib import metadata
from pathlib import Path

import numpy as np

from ._errors import UsageError
from .io._jsonio import dumps
from .paper.closed_form import closed_form
from .paper.consistency import consistency_checks
from .inference.fit import fit_map
from .inference.identifiability import identifiability
from .io.loader import load_session
from .inference.objective import build_model
from ._x64 import x64

__all__ = ["run_fit", "default_out_dir", "UNITS", "versions"]

UNITS = {"Ra": "ohm", "La": "H", "K": "V*s/rad", "B": "N*m*s/rad", "J": "kg*m^2", "Tc": "N*m"}
_LIBRARIES = ("pmdc-bayes", "jax", "jaxlib", "diffrax", "optimistix", "emcee", "arviz", "numpy")


def versions() -> dict:
    out = {}
    for lib in _LIBRARIES:
        try:
            out[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:
            out[lib] = None
    return out


def default_out_dir(session_name: str, root: Path | None = None) -> Path:
    """``reports/<session>-<timestamp>`` under the current directory (or ``root``)."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    return (root or Path.cwd() / "reports") / f"{session_name}-{stamp}"


def _rms(x) -> float:
    x = np.asarray(x)
    return float(np.sqrt(np.mean(x * x)))


def trace_rms(model, theta, *, coulomb=None) -> dict:
    """Per trace RMS of the speed (rad/s) and current (A) residuals."""
    out = {}
    for tr, (ia, w) in zip(model.session.traces, model.predict(theta, coulomb=coulomb)):
        row = {"speed": _rms(tr.speed - w)}
        if tr.current is not None:
            row["current"] = _rms(tr.current - ia)
        out[tr.name] = row
    return out


def _closed_form_theta(model, cf):
    vals = dict(cf.params(), Tc=0.0)
    return np.log(np.maximum([vals[n] for n in model.names], 1e-300))


@x64
def run_fit(session_path, *, out: Path | None = None, force: bool = False,
            mcmc: bool = True, friction: str | None = None, seed: int = 0,
            holdout=(), compare_friction: bool = False,
            progress=None) -> tuple[Path, dict]:
    """Run the pipeline and write ``summary.json`` (and ``posterior.nc``) into ``out``.

    Returns the run directory and the summary.  Raises :class:`UsageError` for an
    existing ``out`` without ``force``.
    """
    t_start = time.perf_counter()
    session_full = load_session(session_path)
    for name in holdout:
        session_full.trace(name) if name in {t.name for t in session_full.traces} else _no_trace(
            session_full, name)
    session = session_full.without_traces(holdout) if holdout else session_full
    out = Path(out) if out is not None else default_out_dir(session.name)
    if out.exists() and not force:
        raise UsageError(f"{out}: already exists; choose another --out or pass --force to "
                         "replace it")
    wall = {}
    t0 = time.perf_counter()
    cf = closed_form(session)
    wall["closed_form"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    coulomb = None if friction is None else friction == "coulomb"
    model = build_model(session, cf, coulomb=coulomb)
    fit = fit_map(model, seed=seed)
    ident = identifiability(model, fit)
    wall["map"] = time.perf_counter() - t0

    cf_theta = _closed_form_theta(model, cf)
    params = {}
    for k, name in enumerate(model.names):
        params[name] = {"unit": UNITS[name],
                        "closed_form": float(getattr(cf, name)) if name != "Tc" else None,
                        "map": fit.values[name], "map_sd": fit.sd[name]}
    summary = {
        "session": {"name": session.name, "path": str(session.root), "motor": session.motor,
                    "friction": "coulomb" if model.coulomb else "viscous",
                    "holdout": list(holdout)},
        "seed": seed,
        "parameters": params,
        "closed_form": cf.as_json(),
        "fit": {"status": fit.status, "message": fit.message, "log_posterior": fit.log_posterior,
                "starts": fit.starts, "correlation": np.asarray(fit.corr).tolist(),
                "names": list(model.names), "noise_sd": fit.noise_sd},
        "identifiability": ident,
        "consistency": consistency_checks(session, cf),
        "residuals": {"closed_form": trace_rms(model, cf_theta, coulomb=False),
                      "map": trace_rms(model, fit.theta)},
        "versions": versions(),
    }
    if session.truth:
        summary["truth"] = {k: session.truth.get(k) for k in model.names}
    summary["diagnostics"] = {"gates_passed": None, "failures": []}
    extra = None
    wall["mcmc"] = 0.0
    if mcmc:
        t0 = time.perf_counter()
        post, stats = _posterior_stage(model, fit, seed=seed, progress=progress)
        for name in model.names:
            params[name].update(stats["summary"][name])
        summary["derived"] = stats["derived"]
        summary["laplace_check"] = stats["laplace_check"]
        summary["diagnostics"].update(stats["diagnostics"])
        if compare_friction:
            summary["model_comparison"] = _compare_friction(session, cf, model, post,
                                                            seed=seed, progress=progress)
        wall["mcmc"] = time.perf_counter() - t0
        extra = lambda tmp: post.idata.to_netcdf(tmp / "posterior.nc")  # noqa: E731
    wall["report"] = 0.0
    wall["total"] = time.perf_counter() - t_start
    summary["diagnostics"]["wall_s"] = wall
    _write_atomically(out, {"summary.json": dumps(summary)},
                      force=force, extra=extra)
    from .report import report_stage  # the report (issue 6); records its wall time

    report_stage(out, summary)
    return out, summary


def _reference_voltage(session) -> float:
    """The voltage at which derived no-load figures are stated: the highest the session
    applies (step, operating point or table)."""
    volts = [float(np.max(tr.voltage.values)) for tr in session.traces]
    volts += [op.voltage for op in session.operating_points]
    volts += [float(np.max(t.voltage)) for t in session.steady_tables]
    volts += [sr.voltage for sr in session.step_readings]
    return max(volts) if volts else 12.0


def _posterior_stage(model, fit, *, seed, progress):
    from .inference.derived import derived_quantities
    from .inference.sampling import compare_laplace, gates, sample_posterior, summarize

    post = sample_posterior(model, fit, seed=seed, progress=progress)
    summ = summarize(post)
    passed, failures = gates(summ, posterior=post)
    voltage = _reference_voltage(model.session)
    stats = {
        "summary": summ,
        "derived": {"voltage": voltage,
                    "quantities": derived_quantities(post.draws_si(), voltage=voltage)},
        "laplace_check": compare_laplace(fit, summ),
        "diagnostics": {
            "gates_passed": bool(passed), "failures": failures,
            "autocorrelation_time": {k: float(v) for k, v in post.tau.items()},
            "acceptance_fraction": float(np.mean(post.acceptance)),
            "n_walkers": int(post.draws.shape[0]), "n_steps": int(post.n_steps),
            "burn_in": int(post.burn_in), "capped": bool(post.capped),
            "sampler_message": post.message,
        },
    }
    return post, stats


def _compare_friction(session, cf, model, post, *, seed, progress):
    """LOO of the viscous and viscous + Coulomb models on the same session."""
    from .inference.sampling import loo_compare, sample_posterior

    other = build_model(session, cf, coulomb=not model.coulomb)
    other_post = sample_posterior(other, fit_map(other, seed=seed), seed=seed,
                                  progress=progress)
    by_name = {("coulomb" if model.coulomb else "viscous"): post.idata,
               ("coulomb" if other.coulomb else "viscous"): other_post.idata}
    return loo_compare(by_name)


def _no_trace(session, name):
    names = ", ".join(t.name for t in session.traces) or "none"
    raise UsageError(f"{session.root / 'session.toml'}: --holdout {name!r} names no trace; "
                     f"traces are: {names}")


def _write_atomically(out: Path, files: dict, *, force: bool, extra=None):
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, text in files.items():
            (tmp / name).write_text(text)
        if extra is not None:
            extra(tmp)
        if out.exists():
            if not force:
                raise UsageError(f"{out}: already exists; pass --force to replace it")
            old = out.with_name(f".{out.name}.old")
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
