"""The sampler's stopping rule: its gate check agrees with the summary's gates on the same
draws (on the SI values they are judged on), predicts how much longer a chain must grow,
sees ensembles that disagree, and schedules its next check accordingly."""

import types
import warnings

import numpy as np
import pytest

from pmdc_bayes.inference.sampling.arviz_import import az
from pmdc_bayes.inference.sampling.diagnostics import gates
from pmdc_bayes.inference.sampling.ensembles import r_hat_between
from pmdc_bayes.inference.sampling.stopping import (
    CHECK,
    TRUST_TAU,
    Stop,
    gate_shortfall,
    next_gate_check,
    over_budget,
    steps_needed,
    stop_message,
)


def _ar1(rng, walkers, steps, dims, rho, *, offset=0.0):
    """``(steps, walkers, dims)`` AR(1) walkers of lag-one correlation ``rho``."""
    x = np.empty((steps, walkers, dims))
    x[0] = rng.standard_normal((walkers, dims))
    e = rng.standard_normal((steps, walkers, dims)) * np.sqrt(1.0 - rho**2)
    for t in range(1, steps):
        x[t] = rho * x[t - 1] + e[t]
    return x + offset


def _sampler(chain):
    """What ``_gate_shortfall`` reads of :class:`~.ensembles.Ensembles`."""
    return types.SimpleNamespace(
        get_chain=lambda discard=0, thin=1: chain[discard + thin - 1::thin])


def _summary_gates(chain, k, values):
    si = values(np.swapaxes(chain, 0, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        idata = az.from_dict(posterior={f"p{i}": si[..., i] for i in range(si.shape[-1])})
        table = az.summary(idata, round_to="none")
    summary = {n: {c: float(table.loc[n, c]) for c in ("r_hat", "ess_bulk", "ess_tail")}
               for n in table.index}
    post = types.SimpleNamespace(capped=False, r_hat_between=r_hat_between(si, k, list(summary)))
    return gates(summary, posterior=post)[0]


@pytest.mark.parametrize("rho", [0.5, 0.9, 0.97, 0.995])
def test_the_gate_check_agrees_with_the_summarys_gates(rho):
    """Judged on the SI values (here exp of θ, where R-hat's folded part differs from the
    log's): a chain the rule calls converged passes the final gates, and one it does not
    fails them."""
    rng = np.random.default_rng(int(rho * 1000))
    chain = _ar1(rng, 24, 900, 3, rho)
    short = gate_shortfall(_sampler(chain), 0, 2, values=np.exp)
    assert (short <= 1.0) == _summary_gates(chain, 2, np.exp)


def test_a_shortfall_predicts_the_length_that_passes():
    """A chain ``s`` times too short passes once about ``s`` times longer."""
    rng = np.random.default_rng(5)
    chain = _ar1(rng, 20, 20_000, 2, 0.99)
    short = gate_shortfall(_sampler(chain[:800]), 0, 2)
    assert 1.5 < short < 50
    grown = int(800 * short * 1.5)
    assert gate_shortfall(_sampler(chain[:grown]), 0, 2) <= 1.0
    assert gate_shortfall(_sampler(chain[:int(800 * short / 3)]), 0, 2) > 1.0


def test_ensembles_that_disagree_are_a_shortfall_however_long():
    rng = np.random.default_rng(6)
    for steps in (1000, 8000):
        chain = np.concatenate([_ar1(rng, 10, steps, 2, 0.3),
                                _ar1(rng, 10, steps, 2, 0.3, offset=0.5)], axis=1)
        assert gate_shortfall(_sampler(chain), 0, 2) > 1.5


def test_the_next_check_is_nine_tenths_of_the_way_within_bounds():
    assert next_gate_check(8000, 1000, 1.2) == 8000 + int(0.9 * (1.2 - 1.0) * 7000)
    assert next_gate_check(4000, 1000, 1.001) == 4000 + 4000 // 20  # at least 5 %
    assert next_gate_check(1000, 0, 1.001) == 1000 + CHECK
    assert next_gate_check(4000, 1000, 30.0) == 4000 + 4000 // 4  # at most a quarter
    assert next_gate_check(4000, 1000, np.inf) == 4000 + 4000 // 4


# Giving up: the projection from the chain's own state against the step budget


def _tau(chain):
    """Per dimension, emcee's integrated autocorrelation time of ``(steps, walkers, P)``."""
    import emcee

    return emcee.autocorr.integrated_time(chain, tol=0)


def test_a_chain_whose_tau_projects_beyond_the_budget_gives_up_once_tau_is_trusted():
    """AR(1) walkers with ρ = 0.995 have τ = (1 + ρ)/(1 − ρ) ≈ 400 steps, so 50 τ is
    about 20,000 steps: beyond a budget of 10,000.  The estimate errs low on a short
    chain: on the first 2,000 steps it projects less than the budget and the run goes
    on; on 6,000 it projects more, by a τ the chain is over ten times as long as, and
    the run gives up, which under a budget of 40,000 it does not."""
    rng = np.random.default_rng(11)
    chain = _ar1(rng, 16, 6000, 2, 0.995)
    early, late = _tau(chain[:2000]), _tau(chain)
    assert early.max() < late.max() < 400
    assert not over_budget(2000, 0, early, steps_needed(2000, 0, early, min_tau_multiple=50),
                           10_000)
    need = steps_needed(6000, 0, late, min_tau_multiple=50)
    assert need == pytest.approx(50 * late.max()) and need > 10_000
    assert over_budget(6000, 0, late, need, 10_000)
    assert not over_budget(6000, 0, late, need, 40_000)
    # a projection beyond the budget from a τ the chain cannot yet vouch for goes on
    assert 2000 < TRUST_TAU * late.max() and not over_budget(2000, 0, late, need, 10_000)
    # a quickly mixing chain projects far less than the budget
    t = _tau(_ar1(rng, 16, 2000, 2, 0.5))
    assert not over_budget(2000, 0, t, steps_needed(2000, 0, t, min_tau_multiple=50), 10_000)


def test_ensembles_that_disagree_project_beyond_any_budget_from_the_gates():
    """τ alone asks for little, but two ensembles apart make the gates' shortfall, and
    with it the projected length, large: the run gives up; the steps since the last
    refit (``adapted``) are burn-in the projection adds."""
    rng = np.random.default_rng(12)
    chain = np.concatenate([_ar1(rng, 10, 2000, 2, 0.3), _ar1(rng, 10, 2000, 2, 0.3,
                                                             offset=2.0)], axis=1)
    t = _tau(chain)
    short = gate_shortfall(_sampler(chain), 100, 2)
    by_tau = steps_needed(2000, 0, t, min_tau_multiple=50)
    need = steps_needed(2000, 0, t, min_tau_multiple=50, gates=(2000, 100, short))
    assert by_tau < 200 and need == pytest.approx(100 + short * 1900)
    assert over_budget(2000, 0, t, need, 20_000) and not over_budget(2000, 0, t, by_tau, 20_000)
    assert steps_needed(2000, 400, t, min_tau_multiple=50) == pytest.approx(by_tau + 400)


def test_a_run_that_gives_up_says_how_many_steps_it_would_need_and_why():
    names = ("Ra", "J")
    by_tau = stop_message(3000, [3.0, 300.0], names, min_tau_multiple=50.0, settled=True,
                          max_steps=10_000, need=15_000.0)
    assert by_tau.startswith("gave up after 3000 steps: the chain would need about 15000 "
                             "steps, 50 × τ_max (slowest parameter J, τ ≈ 300 steps), more "
                             "than the step budget (10000 steps)"), by_tau
    gates_short = stop_message(3000, [3.0, 20.0], names, min_tau_multiple=50.0, settled=True,
                               max_steps=10_000, need=40_000.0)
    assert "for the draws after burn-in to reach the gates (R-hat ≤ 1.01" in gates_short
    assert "--max-sampling-seconds" not in by_tau + gates_short
    assert [s.name for s in Stop] == ["CONVERGED", "OVER_BUDGET", "STEP_CAP", "TIME_LIMIT"]
