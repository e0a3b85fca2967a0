"""The residual statistics the adequacy checks read: whiteness (autocorrelation, the
Ljung–Box test, cross-correlation with the input), MATLAB's fit percentage, and the size
of a residual's slow, systematic part."""

from __future__ import annotations

import numpy as np
from scipy.special import gammaincc

__all__ = ["whiteness", "fit_percent", "systematic_misfit"]


def whiteness(r, u=None, *, lags: int | None = None) -> dict:
    """Autocorrelation of ``r`` at lags 1..M, its 99 % band ±2.58/√n, the Ljung–Box
    statistic and p-value; and the largest |cross-correlation| with the input ``u`` at
    lags 0..M (None when ``u`` does not vary)."""
    r = np.asarray(r, float) - np.mean(r)
    n = r.size
    m = int(lags or max(1, min(25, n // 5)))
    den = float(np.dot(r, r)) or 1.0
    rho = np.array([np.dot(r[:-k], r[k:]) / den for k in range(1, m + 1)])
    q = n * (n + 2) * float(np.sum(rho**2 / (n - np.arange(1, m + 1))))
    band = 2.58 / np.sqrt(n)
    out = {"lags": m, "rho1": float(rho[0]), "max_abs_rho": float(np.max(np.abs(rho))),
           "band": float(band), "outside_band": int(np.sum(np.abs(rho) > band)),
           "ljung_box": q, "p_value": float(gammaincc(m / 2, q / 2)),  # χ²(m) survival
           "input_xcorr": None}
    if u is not None:
        u = np.asarray(u, float) - np.mean(u)
        su = float(np.sqrt(np.dot(u, u)))
        if su > 1e-12 * max(1.0, float(np.max(np.abs(u)))):
            xc = [np.dot(r[k:], u[:n - k]) / (np.sqrt(den) * su) for k in range(0, m + 1)]
            out["input_xcorr"] = float(np.max(np.abs(xc)))
    return out


def fit_percent(y, yhat) -> float:
    """MATLAB's ``compare`` figure: 100·(1 − ‖y − ŷ‖/‖y − ȳ‖)."""
    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    den = float(np.linalg.norm(y - y.mean()))
    return float(100.0 * (1.0 - np.linalg.norm(y - yhat) / den)) if den > 0 else float("nan")


def systematic_misfit(r, noise_sd: float) -> float:
    """RMS of the slow part of ``r``: a centred moving average over ~1/40 of the record,
    less the share of white noise of sd ``noise_sd`` that survives the average."""
    r = np.asarray(r, float)
    w = int(max(5, min(r.size // 40, 200)))
    if r.size < 2 * w:
        return float(np.sqrt(max(0.0, np.mean(r * r) - noise_sd**2)))
    smooth = np.convolve(r, np.ones(w) / w, mode="valid")
    return float(np.sqrt(max(0.0, np.mean(smooth**2) - noise_sd**2 / w)))
