"""Convergence summaries and checks of a posterior sample, and LOO model comparison.

Everything here reads ArviZ objects and returns plain records (dicts of floats and
messages), so a report or the command line can print them without ArviZ.
"""

from __future__ import annotations

import warnings

import numpy as np

from .arviz_import import az

__all__ = ["R_HAT_MAX", "ESS_MIN", "summarize", "gates", "compare_laplace", "widest_direction",
           "loo_compare", "format_loo"]

HDI_PROB = 0.94
CENTRAL = (0.05, 0.5, 0.95)  # the central 90 % interval and the median
LAPLACE_TOLERANCE = 0.2
R_HAT_MAX = 1.01  # the convergence gates: rank-normalised split R-hat at most this,
ESS_MIN = 400  # and bulk and tail ESS at least this, for every parameter
_PARETO_WARNING = r"Estimated shape parameter of Pareto distribution"


def summarize(posterior) -> dict[str, dict[str, float]]:
    """Per parameter (SI): mean, sd, 94 % HDI, the central 90 % interval and the median
    (``q5%``, ``q95%``, ``median``: quantiles of the draws), bulk and tail ESS, R-hat,
    and the R-hat across the independent ensembles (``r_hat_ensembles``) when there
    were several.

    Walkers count as chains; R-hat is the rank-normalised split R-hat of ArviZ.
    """
    table = az.summary(posterior.idata, var_names=list(posterior.names), hdi_prob=HDI_PROB,
                       round_to="none")
    cols = ["mean", "sd", "hdi_3%", "hdi_97%", "ess_bulk", "ess_tail", "r_hat"]
    out = {name: {c: float(table.loc[name, c]) for c in cols} for name in posterior.names}
    for name in posterior.names:
        draws = np.asarray(posterior.idata.posterior[name]).ravel()
        q5, median, q95 = np.quantile(draws, CENTRAL)
        out[name].update({"q5%": float(q5), "median": float(median), "q95%": float(q95)})
    for name, value in (getattr(posterior, "r_hat_between", None) or {}).items():
        out[name]["r_hat_ensembles"] = value
    return out


def gates(summary: dict, *, posterior=None, r_hat_max: float = R_HAT_MAX,
          ess_min: float = ESS_MIN) -> tuple[bool, list[str]]:
    """Whether the sample may be trusted, and why not in words, one message per failure.

    ``posterior`` (optional) adds a failure when the run stopped at its step cap, and
    one per parameter whose R-hat across the run's independent ensembles
    (``posterior.r_hat_between``) is above ``r_hat_max``.
    """
    failures = []
    if posterior is not None and posterior.capped:
        failures.append(f"run capped: {posterior.message}")
    between = getattr(posterior, "r_hat_between", None) or {}
    for name, row in summary.items():
        r_hat, bulk, tail = row["r_hat"], row["ess_bulk"], row["ess_tail"]
        if not np.isfinite(r_hat) or r_hat > r_hat_max:
            failures.append(f"{name}: R-hat {r_hat:.3f} > {r_hat_max} (chains have not mixed)")
        if not np.isfinite(bulk) or bulk < ess_min:
            failures.append(f"{name}: bulk ESS {bulk:.0f} < {ess_min:g}")
        if not np.isfinite(tail) or tail < ess_min:
            failures.append(f"{name}: tail ESS {tail:.0f} < {ess_min:g}")
        rb = between.get(name, 1.0)
        if not np.isfinite(rb) or rb > r_hat_max:
            failures.append(f"{name}: R-hat {rb:.3f} > {r_hat_max} across the independent "
                            "ensembles (they disagree)")
    return not failures, failures


def compare_laplace(fit, summary: dict, *, tolerance: float = LAPLACE_TOLERANCE) -> list[dict]:
    """Laplace (linearised) sd against the posterior sd, per parameter (SI).

    A ratio ``posterior_sd / laplace_sd`` further than ``tolerance`` from 1 is flagged:
    the posterior is then not the Gaussian the Laplace approximation assumes.
    """
    rows = []
    for name in fit.names:
        lap, post = float(fit.sd[name]), float(summary[name]["sd"])
        ratio = post / lap if lap > 0 else float("inf")
        flagged = bool(not np.isfinite(ratio) or abs(ratio - 1.0) > tolerance)
        rows.append({"name": name, "laplace_sd": lap, "posterior_sd": post, "ratio": ratio,
                     "flagged": flagged,
                     "note": "non-Gaussian or banana-shaped posterior" if flagged else ""})
    return rows


def widest_direction(fit, draws_log, *, share: float = 0.3) -> dict | None:
    """The combination of parameters along which the posterior spreads furthest beyond
    the Laplace approximation, judged jointly rather than one parameter at a time.

    ``draws_log`` are posterior draws in log space (θ), ``(..., P)``.  The generalised
    eigenproblem of the draws' covariance against ``fit.cov_log`` gives, for its largest
    eigenvalue λ, the ratio ``sqrt(λ)`` of the posterior's sd to the Laplace sd along
    that direction, and the direction itself.  A ridge the data barely constrain (a
    prior-bound inductance trading against dead times, say) shows here as a ratio of
    several even when each parameter's own sd looks close to its Laplace sd.

    Returns ``{"ratio", "parameters", "weights"}`` — the parameters whose weight in the
    direction (in posterior sd units) is at least ``share`` of the largest, largest
    first — or None when there are too few draws (fewer than 5 per dimension) or the
    Laplace covariance is singular.
    """
    x = np.asarray(draws_log, dtype=float).reshape(-1, np.shape(draws_log)[-1])
    n, p = x.shape
    if n < 5 * p:
        return None
    try:
        root = np.linalg.cholesky(np.asarray(fit.cov_log, dtype=float))
    except np.linalg.LinAlgError:
        return None
    inv_root = np.linalg.inv(root)
    post = np.atleast_2d(np.cov(x.T))
    vals, vecs = np.linalg.eigh(inv_root @ post @ inv_root.T)
    direction = root @ vecs[:, -1]
    sd = np.sqrt(np.clip(np.diag(post), 1e-300, None))
    weights = direction / sd
    weights = weights / np.max(np.abs(weights))
    order = np.argsort(-np.abs(weights))
    names = list(fit.names)
    keep = [int(k) for k in order if abs(weights[k]) >= share]
    return {"ratio": float(np.sqrt(max(vals[-1], 0.0))),
            "parameters": [names[k] for k in keep],
            "weights": {names[k]: float(weights[k]) for k in keep}}


def _reff(idata) -> float:
    """Relative efficiency of the draws that carry a log-likelihood (possibly thinned)."""
    ll = idata.log_likelihood
    post = idata.posterior.sel(draw=ll.draw)
    n = ll.sizes["chain"] * ll.sizes["draw"]
    ess = az.ess(post, method="mean")
    return float(min(1.0, np.mean([ess[v].values for v in ess.data_vars]) / n))


def _loo(idata):
    from .idata import lumped

    with warnings.catch_warnings(record=True) as caught:
        warnings.filterwarnings("always", message=_PARETO_WARNING, category=UserWarning)
        elpd = az.loo(lumped(idata), pointwise=True, reff=_reff(idata))
    for w in caught:  # anything but the Pareto-k notice (reported in the rows) goes on
        if not str(w.message).startswith("Estimated shape parameter of Pareto"):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return elpd


def loo_compare(idata_by_model: dict) -> list[dict]:
    """PSIS-LOO of each model and their comparison (best first), e.g. viscous vs Coulomb.

    The models must be fitted to the same session (same observations).  Each row:
    ``model, rank, elpd_loo, se, p_loo, elpd_diff, dse, weight, n_bad_k`` (observations
    with Pareto k > 0.7, where the LOO estimate is unreliable), ``warning``.
    """
    loos = {name: _loo(idata) for name, idata in idata_by_model.items()}
    with warnings.catch_warnings():
        # ArviZ 0.23's compare calls DataFrame.sort_values(inplace=True), which pandas
        # >= 3.1 deprecates; the result is unaffected.
        warnings.filterwarnings("ignore", message="The inplace keyword in DataFrame")
        table = az.compare(loos, ic="loo")
    rows = []
    for name, r in table.iterrows():
        k = np.asarray(loos[name].pareto_k)
        rows.append({"model": name, "rank": int(r["rank"]), "elpd_loo": float(r["elpd_loo"]),
                     "se": float(r["se"]), "p_loo": float(r["p_loo"]),
                     "elpd_diff": float(r["elpd_diff"]), "dse": float(r["dse"]),
                     "weight": float(r["weight"]), "n_bad_k": int(np.sum(k > 0.7)),
                     "warning": bool(r["warning"])})
    return rows


def format_loo(rows: list[dict]) -> str:
    """The rows of :func:`loo_compare` as a small text table."""
    lines = [f"{'model':<12} {'elpd_loo':>12} {'se':>9} {'Δelpd':>10} {'dse':>9} "
             f"{'p_loo':>7} {'weight':>7}  bad k"]
    for r in rows:
        lines.append(f"{r['model']:<12} {r['elpd_loo']:12.1f} {r['se']:9.1f} "
                     f"{r['elpd_diff']:10.1f} {r['dse']:9.1f} {r['p_loo']:7.1f} "
                     f"{r['weight']:7.2f}  {r['n_bad_k']}")
    return "\n".join(lines)
