"""Independent ensembles: they never exchange a position, and the R-hat across them
(each ensemble's walkers pooled) sees what the walkers' own R-hat is blind to."""

import types

import emcee
import numpy as np

from pmdc_bayes.inference.sampling.diagnostics import gates
from pmdc_bayes.inference.sampling.ensembles import Ensembles, r_hat_between


def _gauss(x):
    return -0.5 * np.sum(np.atleast_2d(x) ** 2, axis=1)


def test_ensembles_never_borrow_each_others_positions():
    """Every move of a walker is drawn from its own ensemble: the first ensemble's chain
    is the same whatever the second ensemble's walkers are (and not so for a single
    ensemble of all the walkers)."""
    rng = np.random.default_rng(0)
    first, second = rng.standard_normal((8, 2)), rng.standard_normal((8, 2))
    moves = lambda j: [(emcee.moves.DEMove(), 1.0)]  # noqa: E731

    def chains(k, other):
        p0 = np.concatenate([first, other])
        e = Ensembles(k, 16, 2, _gauss, p0, _gauss(p0), moves=moves, seed=1)
        e.run_mcmc(40)
        return e.get_chain()

    a, b = chains(2, second), chains(2, second + 5.0)
    assert np.array_equal(a[:, :8], b[:, :8]) and not np.array_equal(a[:, 8:], b[:, 8:])
    assert np.array_equal(chains(2, second), a)  # same seed, same draws
    assert not np.array_equal(chains(1, second)[:, :8], chains(1, second + 5.0)[:, :8])


def test_r_hat_between_ensembles_flags_ensembles_that_disagree():
    rng = np.random.default_rng(2)
    chain = rng.standard_normal((32, 500, 2))  # walkers, draws, parameters
    agree = r_hat_between(chain, 2, ["a", "b"])
    assert all(abs(v - 1.0) < 0.01 for v in agree.values())
    chain[16:, :, 0] += 0.5  # the second ensemble sits half an sd higher in a
    apart = r_hat_between(chain, 2, ["a", "b"])
    assert apart["a"] > 1.02 and abs(apart["b"] - 1.0) < 0.01
    assert r_hat_between(chain, 1, ["a", "b"]) is None


def test_the_gates_fail_a_parameter_the_ensembles_disagree_on():
    row = {"mean": 1.0, "sd": 0.1, "hdi_3%": 0.8, "hdi_97%": 1.2, "ess_bulk": 2000.0,
           "ess_tail": 2000.0, "r_hat": 1.001}
    post = types.SimpleNamespace(capped=False, r_hat_between={"K": 1.002, "J": 1.04})
    ok, failures = gates({"K": row, "J": row}, posterior=post)
    assert not ok and failures == ["J: R-hat 1.040 > 1.01 across the independent ensembles "
                                   "(they disagree)"]


def _pair(log_prob, seed=3):
    rng = np.random.default_rng(seed)
    p0 = rng.standard_normal((16, 2))
    moves = lambda j: [(emcee.moves.DEMove(), 1.0)]  # noqa: E731
    return Ensembles(2, 16, 2, log_prob, p0, _gauss(p0), moves=moves, seed=seed)


def test_ensembles_stepped_in_threads_give_the_draws_each_gives_alone():
    """The ensembles run in threads of their own: each one's chain is what it gives when
    stepped alone, one after the other, chunk after chunk."""
    together, alone = _pair(_gauss), _pair(_gauss)
    for n in (30, 50):
        together.run_mcmc(n)
        alone.states = [s.run_mcmc(st, n, progress=False)
                        for s, st in zip(alone.samplers, alone.states, strict=True)]
    assert together.get_chain().shape == (80, 16, 2)
    assert np.array_equal(together.get_chain(), alone.get_chain())
    assert np.array_equal(together.get_log_prob(), alone.get_log_prob())


def test_an_error_in_either_ensemble_is_raised_and_stops_the_other():
    import threading

    import pytest

    def failing_in(main: bool):
        calls = []

        def log_prob(x):
            if (threading.current_thread() is threading.main_thread()) == main:
                calls.append(1)
                if len(calls) > 20:
                    raise ArithmeticError("solve failed")
            return _gauss(x)

        return log_prob

    for main in (True, False):
        e = _pair(failing_in(main))
        with pytest.raises(ArithmeticError, match="solve failed"):
            e.run_mcmc(100_000)
        # the other ensemble stopped within steps of the failure, not at 100,000 steps
        assert max(s.iteration for s in e.samplers) < 1_000
