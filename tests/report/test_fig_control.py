"""The controller-design figure's curves: the band is the draws' spread, the estimate
lies inside it, a session without a posterior or a closed form shows what it has."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pmdc_bayes.physics.response import frequency_response, step_response
from pmdc_bayes.report.fig_control import response_curves, response_figure

NAMES = ("Ra", "La", "K", "B", "J", "Tc")
BEST = dict(zip(NAMES, (8.5, 5.6e-3, 0.062, 4.5e-5, 5.9e-4, 2.5e-3), strict=True))


def _ctx(rel_sd, with_cf=True, n=2000):
    rng = np.random.default_rng(1)
    base = np.array([BEST[n] for n in NAMES])
    draws = None if rel_sd is None else base * (1 + rel_sd * rng.standard_normal((n, 6)))
    values = {"map": BEST, **({"mean": BEST} if draws is not None else {})}
    if with_cf:
        values["closed_form"] = dict(BEST, B=BEST["B"] * 1.24, J=BEST["J"] * 1.03)
    return SimpleNamespace(best=BEST, values=values, truth=None, draws=draws, names=NAMES,
                           has_posterior=draws is not None, best_label="posterior mean",
                           cf_label="closed form")


def test_the_band_is_the_spread_of_the_draws_and_holds_the_estimate():
    narrow, wide = response_curves(_ctx(0.01)), response_curves(_ctx(0.05))
    for curves in (narrow, wide):
        for key in ("step", "gain_db", "phase_deg"):
            lo, hi = curves["band"][key]
            est = curves["estimate"][key]
            assert np.all(lo <= est + 1e-12) and np.all(est <= hi + 1e-12)
    width = {k: np.mean(np.diff(c["band"]["step"], axis=0)) for k, c in
             (("narrow", narrow), ("wide", wide))}
    assert 3.5 < width["wide"] / width["narrow"] < 6.5
    # the estimate's curves are the physics' responses on the figure's axes
    args = [BEST[n] for n in NAMES[:5]]
    np.testing.assert_array_equal(narrow["estimate"]["step"],
                                  step_response(*args, narrow["time"]))
    np.testing.assert_allclose(narrow["estimate"]["gain_db"], 20 * np.log10(
        np.abs(frequency_response(*args, narrow["frequency"]))), rtol=1e-12)
    # the time axis covers the settling, the frequencies both poles
    assert narrow["estimate"]["step"][-1] > 0.99 * BEST["K"] / (
        BEST["Ra"] * BEST["B"] + BEST["K"] ** 2)
    # the closed form's larger B settles lower
    assert narrow["closed_form"]["step"][-1] < narrow["band"]["step"][0][-1]


def test_without_a_posterior_or_a_closed_form_only_the_estimate_is_drawn():
    curves = response_curves(_ctx(None, with_cf=False))
    assert "band" not in curves and "closed_form" not in curves
    assert response_figure(_ctx(None, with_cf=False)).png()[:8] == b"\x89PNG\r\n\x1a\n"
