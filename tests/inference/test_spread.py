"""The posterior's widest direction beyond the Laplace approximation, judged jointly,
and how the command line says it (with the posterior's failed gates, in one line)."""

import types

import numpy as np

from pmdc_bayes._console import gate_failure_text
from pmdc_bayes._headline import spread_text
from pmdc_bayes.inference.sampling.diagnostics import widest_direction

NAMES = ("La", "K", "J", "dead_time_a", "dead_time_b")


def _fit(cov):
    return types.SimpleNamespace(names=NAMES, cov_log=np.asarray(cov))


def _ridge_case(stretch, rng, n=20_000):
    """A Laplace Gaussian with La and the dead times correlated, and posterior draws
    that spread ``stretch`` times further along their joint direction only."""
    sd = np.array([0.3, 0.01, 0.02, 1e-4, 1e-4])
    corr = np.eye(5)
    for i, j, r in ((0, 3, -0.8), (0, 4, -0.8), (3, 4, 0.7)):
        corr[i, j] = corr[j, i] = r
    cov = corr * np.outer(sd, sd)
    vals, vecs = np.linalg.eigh(np.linalg.inv(np.diag(sd)) @ cov @ np.linalg.inv(np.diag(sd)))
    root = np.diag(sd) @ vecs * np.sqrt(vals)
    z = rng.standard_normal((n, 5))
    z[:, -1] *= stretch  # the largest eigendirection: La against the dead times
    return _fit(cov), z @ root.T


def test_a_ridge_wider_than_laplace_is_found_and_named():
    rng = np.random.default_rng(3)
    fit, draws = _ridge_case(8.0, rng)
    wide = widest_direction(fit, draws.reshape(4, -1, 5))
    assert abs(wide["ratio"] - 8.0) < 0.3
    assert set(wide["parameters"]) == {"La", "dead_time_a", "dead_time_b"}
    assert wide["weights"]["dead_time_a"] * wide["weights"]["La"] < 0  # they trade
    # each parameter alone looks only moderately wider than its Laplace sd
    one_by_one = np.std(draws, axis=0) / np.sqrt(np.diag(fit.cov_log))
    assert one_by_one.max() < wide["ratio"]


def test_draws_from_the_laplace_gaussian_have_no_wide_direction_worth_saying():
    fit, draws = _ridge_case(1.0, np.random.default_rng(4))
    wide = widest_direction(fit, draws)
    assert 0.95 < wide["ratio"] < 1.1
    assert spread_text({"widest_direction": wide}) == ""
    assert widest_direction(fit, draws[:20]) is None  # too few draws to judge
    assert widest_direction(_fit(np.zeros((5, 5))), draws) is None  # singular Laplace


def test_the_failed_gates_are_one_line_that_names_the_stop_the_count_and_the_ridge():
    fit, draws = _ridge_case(6.0, np.random.default_rng(5))
    diag = {"failures": ["run capped: stopped after 60 s of sampling; slowest parameter La",
                         "La: R-hat 1.469 > 1.01 (chains have not mixed)",
                         "La: bulk ESS 120 < 400", "K: bulk ESS 300 < 400"],
            "widest_direction": widest_direction(fit, draws)}
    text = gate_failure_text(diag, 5)
    assert "\n" not in text
    assert text.startswith("stopped after 60 s of sampling; slowest parameter La; ")
    assert "R-hat or ESS short of the gates for 2 of 5 parameters (La: R-hat 1.469" in text
    assert "along La, dead_time_" in text and "spreads 6." in text
    assert gate_failure_text({"failures": ["K: bulk ESS 300 < 400"]}, 5) == (
        "R-hat or ESS short of the gates for 1 of 5 parameters (K: bulk ESS 300 < 400; "
        "summary.json lists each)")


def test_a_single_parameter_wider_than_laplace_is_named_as_one():
    wide = {"ratio": 5.6, "parameters": ["load_step_9v"], "weights": {"load_step_9v": 1.0}}
    text = spread_text({"widest_direction": wide})
    assert text.startswith("in load_step_9v the posterior spreads 5.6 times as far as the "
                           "Laplace approximation: a parameter the data barely constrain")
    assert "together" not in text and "combination" not in text
