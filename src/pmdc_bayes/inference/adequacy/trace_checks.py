"""The residual checks of one trace channel, each with its p-value under the fitted
model (:mod:`.calibrate`): a systematic misfit (the slow part of the residual against
what white noise leaves in a moving average), anti-correlated noise (a differenced,
quantised signal), an outlying reading (:mod:`.glitches`: a reading or a short run of
them that jumps off its neighbours and back), residual whiteness (Ljung–Box), noise
inflation (the fitted against the model-free level) and the residual's correlation with
the input.

The first three and noise inflation can fail a model, each only when its effect is also
material (a slow part or a jump above :data:`MATERIAL_FRACTION` of the span; a lag-1
autocorrelation below :data:`ANTI_CORRELATION`; a fitted noise sd over
:data:`MATERIAL_INFLATION` times the data's own, the excess over it
:data:`MATERIAL_EXCESS` of the span at least, as a current sensor's offset leaves it
against a span an inrush sets; never on an angle, whose integrated misfit dwarfs its
quantum at any size); else inflation and the others warn.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

from ..model.coloured import innovation_scale
from ..model.noise import noise_scale
from .calibrate import Test, ratio_p, replicates, tail_p
from .findings import MATERIAL_FRACTION, Check, Finding, Severity
from .glitches import outlier_test
from .residual_stats import fit_percent, systematic_misfit, whiteness

__all__ = ["channel_tests", "slow_ratio", "autocorrelation", "MATERIAL_FRACTION",
           "ANTI_CORRELATION"]

ANTI_CORRELATION = -0.3  # a lag-1 autocorrelation this negative: not the assumed noise
MATERIAL_INFLATION = 2.0  # a fitted noise sd this many times the data's own: a misfit
MATERIAL_EXCESS = 0.005  # of the span, the sd the misfit adds to the data's own noise


def smoothing_window(n: int) -> int:
    """The moving average's length: about 1/40 of the record, 5 to 200 samples."""
    return int(max(5, min(n // 40, 200)))


def slow_ratio(r, w: int):
    """Rows of ``r``: mean square of their w-sample moving average, times w, over their
    mean square (1 for white noise; up to w for a slow misfit)."""
    r = np.atleast_2d(np.asarray(r, float))
    if r.shape[1] < 2 * w:
        return np.ones(r.shape[0])
    c = np.concatenate([np.zeros((r.shape[0], 1)), np.cumsum(r, axis=1)], axis=1)
    smooth = (c[:, w:] - c[:, :-w]) / w
    return np.mean(smooth**2, axis=1) * w / np.maximum(np.mean(r * r, axis=1), 1e-300)


def autocorrelation(r, lags: int):
    """Rows of ``r``: autocorrelation at lags 1..``lags`` and the Ljung–Box statistic."""
    r = np.atleast_2d(np.asarray(r, float))
    r = r - r.mean(axis=1, keepdims=True)
    n = r.shape[1]
    den = np.maximum(np.sum(r * r, axis=1), 1e-300)
    rho = np.stack([np.sum(r[:, :-k] * r[:, k:], axis=1) / den for k in range(1, lags + 1)],
                   axis=1)
    q = n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1)), axis=1)
    return rho, q


def channel_tests(channel, y, yhat, u, s0, sigma, rng, *, quantum=0.0, rho=0.0, time=None,
                  unit=""):
    """The figures of one trace channel (:class:`~pmdc_bayes.io.channel.ChannelId`; a row
    of the report's table) and its tests.
    ``quantum`` is the resolution the channel was logged at (0: not quantised); on a
    quantised channel every statistic is calibrated by the bootstrap.  A channel whose
    noise is coloured (lag-1 correlation ``rho``, :mod:`.coloured`) is checked on its
    innovations, which are white at the fitted level ``sigma``, against the model-free
    level an AR(1) noise's innovations have; ``time`` (the readings' times) and
    ``unit`` place an outlying reading in the report (:func:`outlier_test`)."""

    y, yhat = np.asarray(y, float), np.asarray(yhat, float)
    r = y - yhat
    span = float(np.max(y) - np.min(y)) or float(np.max(np.abs(y))) or 1.0
    glitch = outlier_test(channel, r, span, u=u, time=time, unit=unit, quantum=quantum)
    if rho != 0.0:
        r = np.concatenate([[np.sqrt(1.0 - rho * rho) * r[0]], r[1:] - rho * r[:-1]])
        s0 = s0 * innovation_scale(rho)
    n = r.size
    white = whiteness(r / max(sigma, 1e-300), u)
    m, w = white["lags"], smoothing_window(n)
    sys_rms = systematic_misfit(r, s0)
    t_slow = float(slow_ratio(r, w)[0])
    slow, q_rep, rho1_rep, infl_rep = [], [], [], []
    for block in replicates(yhat, sigma, rng, quantum=quantum, origin=float(y[0])):
        rr = block - yhat
        slow.append(slow_ratio(rr, w))
        if quantum > 0:
            ac, q = autocorrelation(rr, m)
            q_rep.append(q)
            rho1_rep.append(ac[:, 0])
            infl_rep += [np.sqrt(np.mean(x * x)) / noise_scale(b) for x, b in zip(rr, block,
                                                                                   strict=True)]
    p_slow = tail_p(t_slow, np.concatenate(slow), side="chi2")
    inflation = sigma / s0 if s0 > 0 else float("inf")
    if quantum > 0:
        p_white = tail_p(white["ljung_box"], np.concatenate(q_rep), side="chi2")
        p_anti = tail_p(white["rho1"], np.concatenate(rho1_rep), side="lower")
        p_infl = tail_p(np.log(inflation), np.log(infl_rep), side="upper")
    else:
        p_white = white["p_value"]
        p_anti = float(norm.cdf((white["rho1"] + 1.0 / n) * np.sqrt(n)))
        p_infl = ratio_p(sigma, s0, n)
    p_xcorr = None
    if white["input_xcorr"] is not None:  # largest of m + 1 lags, each N(0, 1/n)
        p_xcorr = float(min(1.0, (m + 1) * 2 * norm.sf(white["input_xcorr"] * np.sqrt(n))))
    row = {"n": int(n), "model_free_sd": s0, "fitted_sd": sigma, "inflation": inflation,
           "inflation_p": p_infl, "whiteness": dict(white, p_value=p_white),
           "systematic_rms": sys_rms, "systematic_fraction": sys_rms / span,
           "systematic_p": p_slow, "anti_correlation_p": p_anti, "input_xcorr_p": p_xcorr,
           "quantum": quantum, "span": span, "fit_percent_map": fit_percent(y, yhat),
           "noise_correlation": rho}
    size = (f"noise sd {sigma:.3g} fitted against {s0:.3g} from the data "
            f"(x{inflation:.3g}); systematic misfit {100 * sys_rms / span:.2g} % of the span; "
            f"fit {row['fit_percent_map']:.1f} %")
    fails = [Test(Finding(Check.SYSTEMATIC_MISFIT, channel, Severity.FAIL, size,
                           f"the model misses the data systematically "
                           f"({100 * sys_rms / span:.2g} % of the span; its noise sd is "
                           f"x{inflation:.3g} the data's own)"),
                  p_slow, sys_rms / span > MATERIAL_FRACTION),
             Test(Finding(Check.RESIDUAL_WHITENESS, channel, Severity.FAIL,
                           f"lag-1 autocorrelation {white['rho1']:.2f}",
                           f"the noise is strongly anti-correlated (lag-1 autocorrelation "
                           f"{white['rho1']:.2f}), so it is not the white noise the "
                           "likelihood assumes"), p_anti, white["rho1"] < ANTI_CORRELATION)]
    if glitch is not None:
        fails.append(glitch)
        row["outlier_p"] = glitch.p_value
    fails.append(Test(Finding(Check.NOISE_INFLATION, channel, Severity.FAIL, size,
                              f"the fitted noise sd is x{inflation:.3g} the data's own: the "
                              "model misses the data by more than their noise, and takes the "
                              "misfit for noise"), p_infl,
                      inflation > MATERIAL_INFLATION and channel.signal != "position"
                      and np.sqrt(max(sigma**2 - s0**2, 0.0)) > MATERIAL_EXCESS * span))
    warns = [Test(Finding(Check.RESIDUAL_WHITENESS, channel, Severity.WARN, size,
                           "the residuals are not white but the misfit is small; "
                           "intervals may be somewhat optimistic"), p_white),
             Test(Finding(Check.NOISE_INFLATION, channel, Severity.WARN, f"x{inflation:.3g}",
                           f"the fitted noise sd is x{inflation:.3g} the data's own: part of "
                           "the misfit is taken for noise"), p_infl)]
    if p_xcorr is not None:
        warns.append(Test(Finding(Check.INPUT_CORRELATION, channel, Severity.WARN,
                                   f"{white['input_xcorr']:.2f}",
                                   "the residuals follow the input: part of its effect is "
                                   "not modelled"), p_xcorr))
    return row, fails, warns
