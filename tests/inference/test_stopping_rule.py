"""The sampler's stopping rule: its gate check agrees with the summary's gates on the same
draws (on the SI values they are judged on), predicts how much longer a chain must grow,
sees ensembles that disagree, and schedules its next check accordingly."""

import types
import warnings

import numpy as np
import pytest

from pmdc_bayes.inference.diagnostics import az, gates
from pmdc_bayes.inference.ensembles import r_hat_between
from pmdc_bayes.inference.stopping import CHECK, gate_shortfall, next_gate_check


def _ar1(rng, walkers, steps, dims, rho, *, offset=0.0):
    """``(steps, walkers, dims)`` AR(1) walkers of lag-one correlation ``rho``."""
    x = np.empty((steps, walkers, dims))
    x[0] = rng.standard_normal((walkers, dims))
    e = rng.standard_normal((steps, walkers, dims)) * np.sqrt(1.0 - rho**2)
    for t in range(1, steps):
        x[t] = rho * x[t - 1] + e[t]
    return x + offset


def _sampler(chain):
    """What ``_gate_shortfall`` reads of :class:`~pmdc_bayes.inference.ensembles.Ensembles`."""
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
