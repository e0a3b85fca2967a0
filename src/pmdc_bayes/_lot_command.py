"""``pmdc-bayes lot``: the motors fitted (:mod:`.lot`), the population stage, the lot's
files written whole and its table printed, outliers first."""

from __future__ import annotations

import csv
import io
import json
import os
import sys
from pathlib import Path

import numpy as np

from ._batch import claim_lot, clear_lot_files, expand_sessions, lot_outs
from ._errors import EXIT_FAILED, UsageError
from .lot import connect, pooled_names, run_lot, status_name

__all__ = ["run_lot_command", "write_lot_files"]


def _write(path: Path, write) -> None:
    """``write(tmp)`` to a temporary file beside ``path``, renamed into place."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _rows(runs, record) -> list[dict]:
    by = {m["motor"]: m for m in (record or {}).get("motors", [])}
    names = (record or {}).get("parameters", [])
    rows = []
    for r in runs:
        m = by.get(r.name)
        row = {"motor": r.name, "session": str(r.session), "status": status_name(r.status),
               "exit_code": r.status, "run": str(r.run or ""), "error": r.error,
               "outlier": "" if m is None else str(m["outlier"]).lower(),
               "p_value": "" if m is None else f"{m['p_value']:.4g}",
               "judged_against": "" if m is None else m["judged_against"]}
        for n in names:
            v = m["values"][n] if m is not None else {}
            row[n] = v.get("own", "")
            row[f"{n}_lo"], row[f"{n}_hi"] = v.get("own_interval") or ("", "")
            row[f"{n}_pooled"] = v.get("pooled") if v.get("pooled") is not None else ""
            row[f"{n}_pooled_lo"], row[f"{n}_pooled_hi"] = v.get("pooled_interval") or ("", "")
        rows.append(row)
    return rows


def write_lot_files(out: Path, runs, record, pop) -> list[Path]:
    """``lot.csv`` (one row per motor, its status, flag and values), ``lot.json`` (the
    population under ``population``), ``population.nc`` (its ArviZ record) and
    ``lot.png``, each written whole."""
    out.mkdir(parents=True, exist_ok=True)
    rows = _rows(runs, record)
    fields = list(dict.fromkeys(k for row in rows for k in row))
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n", restval="")
    writer.writeheader()
    writer.writerows(rows)
    paths = [out / "lot.csv"]
    _write(paths[0], lambda p: p.write_text(buf.getvalue(), encoding="utf-8"))
    doc = dict(record or {"population": None})
    doc["status"] = [{"motor": r["motor"], "status": r["status"], "error": r["error"],
                      "run": r["run"]} for r in rows]
    paths.append(out / "lot.json")
    _write(paths[-1], lambda p: p.write_text(json.dumps(doc, indent=1), encoding="utf-8"))
    if pop is None:  # an earlier lot's population is not this lot's
        clear_lot_files(out, keep=("lot.csv", "lot.json"))
    else:
        from .inference.model.correlation import correlations
        from .inference.sampling.arviz_import import az
        from .report.lot_figure import lot_figure

        def chains(x):
            return x.reshape(-1, pop.walkers).T

        post = {}
        for k, n in enumerate(pop.names):
            post[f"median_{n}"] = chains(np.exp(pop.mu[:, k]))
            post[f"spread_{n}"] = chains(pop.sigma[:, k])
        if pop.correlated:
            r = correlations(pop.chol)
            for i, a in enumerate(pop.names):
                for j, b in enumerate(pop.names[:i]):
                    post[f"correlation_{b}_{a}"] = chains(r[:, i, j])
        idata = az.from_dict(posterior=post)
        paths.append(out / "population.nc")
        _write(paths[-1], lambda p: idata.to_netcdf(str(p), engine="h5netcdf"))
        paths.append(out / "lot.png")
        _write(paths[-1], lambda p: lot_figure(record, p))
    return paths


def _say(args):
    return (lambda text: None) if args.quiet else (lambda text: print(text, flush=True))


def run_lot_command(args, *, note=None) -> int:
    """Fit the lot, pool it, write its files; the exit code (module docstring of
    :mod:`.lot`)."""
    from . import cachedir
    from ._cores import usable_cores
    from .inference.population.evidence import subset
    from .inference.population.pooling import analyse_lot

    if args.scheduler and args.workers:
        raise UsageError("--workers sizes a local cluster; drop it with --scheduler")
    if args.workers and args.workers > (cores := usable_cores()):
        raise UsageError(f"--workers {args.workers}: this machine has {cores} usable cores "
                         f"and each worker fits a motor on one; give at most {cores}, or "
                         "--scheduler for a larger cluster")
    paths = expand_sessions(args.session, note=note)
    outs = lot_outs(paths, args.out, args.force)
    client = connect(args.scheduler) if args.scheduler else None  # before anything is written
    claim_lot(args.out)
    cachedir.enable()
    say = _say(args)
    say(f"fitting {len(paths)} motors")
    runs = run_lot(paths, outs, workers=args.workers, client=client,
                   mcmc=not args.no_mcmc, seed=args.seed, force=args.force, say=say)
    passed = [r for r in runs if r.status == 0 and r.evidence is not None]
    record = pop = None
    if len(passed) >= 2:
        names = pooled_names([r.evidence for r in passed])
        record, pop = analyse_lot([subset(r.evidence, names) for r in passed],
                                  seed=args.seed)
        record["units"] = {n: passed[0].summary["parameters"][n]["unit"] for n in names}
    files = write_lot_files(args.out, runs, record, pop)
    flagged = [] if record is None else [m for m in record["motors"] if m["outlier"]]
    for m in flagged:
        print(f"pmdc-bayes: outlier: motor {m['motor']}: the lot makes its values "
              f"improbable (p = {m['p_value']:.2g}, Holm-corrected at "
              f"{record['outlier_test']['alpha']:.0%} over the lot)", file=sys.stderr)
    if record is None:
        print("pmdc-bayes: no population: fewer than two motors passed their fits",
              file=sys.stderr)
    elif not args.quiet:
        for n in record["parameters"]:
            p = record["population"][n]
            lo, hi = p["median_interval"]
            slo, shi = p["spread_interval"]
            print(f"  {n:<3} median {p['median']:.4g} (90 %: {lo:.4g} .. {hi:.4g}), spread "
                  f"{100 * p['spread']:.2g} % (90 %: {100 * slo:.2g} .. {100 * shi:.2g} %)")
        for pair, c in record["correlation"].get("pairs", {}).items():
            if c["excludes_zero"]:
                lo, hi = c["interval"]
                print(f"  correlation {pair} across the lot {c['median']:.2f} "
                      f"(90 %: {lo:.2f} .. {hi:.2f})")
    failed = [r for r in runs if r.status != 0]
    for r in failed:
        print(f"pmdc-bayes: error: motor {r.name}: {r.error}", file=sys.stderr)
    if not args.quiet:
        print(f"{len(runs) - len(failed)} of {len(runs)} motors passed; "
              f"{len(flagged)} outlier(s); wrote {', '.join(str(p) for p in files)}")
    status = max(r.status for r in runs)
    return max(status, EXIT_FAILED) if flagged else status
