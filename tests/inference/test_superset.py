"""A candidate fitted in a superset model's programs, the non-idealities it lacks switched
off as data, is the candidate fitted in its own."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.fit.superset import Superset, neutral_value
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.physics.regimes import NO_LIMIT
from pmdc_bayes.physics.sensor import MIN_LAG
from pmdc_bayes.selection import laplace_log_evidence
from pmdc_bayes.simulate.cases import case_session
from pmdc_bayes.supersets import Supersets
from pmdc_bayes.terms import LOAD, SHARED, with_terms

SMOOTH = frozenset({"dead_time", "speed_lag", "current_lag", "speed_gain", "current_offset",
                    "source_resistance", "dead_zone"})


@pytest.fixture(scope="module")
def bench():
    return case_session("dead time", seed=2)


def _model(session, terms):
    s = with_terms(session, terms)
    return build_model(s, fit_seed(s))


@pytest.fixture(scope="module")
def superset(bench):
    return Superset(_model(bench, SMOOTH))


def _embed(view, own, theta, rest):
    full = np.asarray(rest, dtype=float).copy()
    full[[view.registry.index(n) for n in own.names]] = theta
    return full


def test_a_parameter_switched_off_moves_nothing_and_adds_nothing(bench, superset):
    own = _model(bench, frozenset({"dead_time"}))
    assert superset.covers(own)
    view = superset.switched(own)
    off = np.asarray(view.data["off"])
    assert set(np.asarray(view.names)[off]) == set(view.names) - set(own.names)
    rng = np.random.default_rng(0)
    theta = np.asarray(own.theta_seed()) + 0.05 * rng.standard_normal(len(own.names))
    seed = np.asarray(view.registry.seed_theta())
    with jax.enable_x64(True):
        a, b = (_embed(view, own, theta, seed + k * rng.standard_normal(seed.size))
                for k in (0.0, 2.0))
        likelihood = jax.jit(lambda t: view.log_likelihood(t))
        ll = [float(likelihood(x)) for x in (a, b)]
        own_lp = float(jax.jit(lambda t: own.log_posterior(t))(theta))
        grad = np.asarray(jax.jit(jax.grad(lambda t: view.log_likelihood(t)))(b))
        lp_at_centre = float(jax.jit(lambda t: view.log_posterior(t))(a))
    assert ll[0] == ll[1]  # wherever the switched-off parameters are
    assert np.all(grad[off] == 0.0)
    # at the off parameters' prior centre the superset's log-posterior is the model's own
    assert lp_at_centre == pytest.approx(own_lp, rel=1e-9, abs=1e-6)


def test_a_candidate_fitted_in_the_superset_is_the_candidate_fitted_in_its_own(bench,
                                                                              monkeypatch):
    import pmdc_bayes.supersets as supersets

    monkeypatch.setattr(supersets, "SUPERSET_READINGS", sum(2 * tr.n for tr in bench.traces))
    families = Supersets(bench, frozenset(), free_friction=False)
    made = []
    for terms in (frozenset(), frozenset({SHARED}), frozenset({"dead_time"})):
        own = _model(bench, terms)
        made.append(families.for_model(terms, own))
        alone, shared = fit_map(own), made[-1].fit(own)
        assert alone.ok and shared.ok
        assert shared.names == alone.names
        for n in own.names:
            assert abs(shared.values[n] - alone.values[n]) < 1e-3 * alone.sd[n], n
            assert shared.sd[n] == pytest.approx(alone.sd[n], rel=1e-3), n
        assert laplace_log_evidence(own, shared) == pytest.approx(
            laplace_log_evidence(own, alone), abs=1e-2)
    assert made[0] is not None and all(m is made[0] for m in made)  # one program for all


def test_each_switched_off_parameter_sits_where_the_model_lacks_it(bench):
    model = _model(bench, SMOOTH | {"current_limit", "voltage_drop", "coulomb"}
                   | {LOAD + bench.traces[0].name})
    got = {s.name: neutral_value(s) for s in model.registry.specs}
    assert got["Imax"] == NO_LIMIT and got["speed_lag"] == MIN_LAG
    assert got["speed_gain"] == 1.0 and got["current_offset"] == 0.0
    assert got["Vdz_fwd"] == 0.0
    assert all(got[n] == 0.0 for n in got if n.startswith("dead_time"))
    assert all(0.0 < got[n] < 1e-100 for n in ("Vdrop", "Rs", "Tc"))  # positive: the least


def test_a_family_holds_a_costly_solution_only_for_a_candidate_that_needs_it(bench):
    families = Supersets(bench, frozenset(), free_friction=True)
    universe = families.universe
    assert {"dead_time", SHARED, "current_limit", "voltage_drop", "coulomb",
            "speed_lag"} <= universe
    assert {LOAD + tr.name for tr in bench.traces} <= universe
    smooth = families.family(frozenset({"dead_time"}))
    assert {"dead_time", SHARED, "speed_lag"} <= smooth
    assert not smooth & {"current_limit", "voltage_drop", "coulomb"}
    assert not any(t.startswith(LOAD) for t in smooth)
    assert families.family(frozenset({SHARED})) == smooth == families.family(frozenset())
    switching = families.family(frozenset({"voltage_drop"}))
    assert {"voltage_drop", "current_limit"} <= switching and "speed_lag" not in switching
    assert "speed_lag" in families.family(frozenset({"voltage_drop", "speed_lag"}))
    assert "coulomb" in families.family(frozenset({LOAD + bench.traces[0].name}))
    fixed = Supersets(bench, frozenset(), free_friction=False)
    assert "coulomb" not in fixed.universe


def test_a_superset_is_used_only_where_a_fit_in_it_costs_less_than_a_compile(bench,
                                                                            monkeypatch):
    """On a session short enough (the bench's 2 traces of 601 samples, speed and current,
    under a bound raised to hold them) a smooth family's superset serves its candidates;
    a family holding the stick-slip or regime-switching solution does not, nor does any
    family of a longer session: their candidates are fitted in their own programs."""
    import dataclasses

    import pmdc_bayes.supersets as supersets

    assert not Supersets(bench, frozenset(), free_friction=True).pays(frozenset())
    monkeypatch.setattr(supersets, "SUPERSET_READINGS", 2 * sum(tr.n for tr in bench.traces))
    SUPERSET_READINGS = supersets.SUPERSET_READINGS
    families = Supersets(bench, frozenset(), free_friction=True)
    terms = frozenset({"dead_time"})
    assert families.pays(terms)
    assert families.for_model(terms, _model(bench, terms)) is not None
    for costly in ("coulomb", "voltage_drop", LOAD + bench.traces[0].name):
        assert not families.pays(terms | {costly})
    stretch = int(np.ceil(SUPERSET_READINGS / sum(tr.n for tr in bench.traces)))
    long = dataclasses.replace(bench, traces=tuple(
        dataclasses.replace(tr, name=f"{tr.name}_{k}") for tr in bench.traces
        for k in range(stretch)))
    assert not Supersets(long, frozenset(), free_friction=True).pays(terms)


def test_a_candidate_a_superset_does_not_pay_for_gets_no_superset(bench, monkeypatch):
    """``for_model`` hands no superset where ``pays`` says a compile costs less: a long
    session, a candidate with the stick-slip solution."""
    import pmdc_bayes.supersets as supersets

    monkeypatch.setattr(supersets, "SUPERSET_READINGS", 0)
    terms = frozenset({"dead_time"})
    assert Supersets(bench, frozenset(), free_friction=True).for_model(
        terms, _model(bench, terms)) is None
    monkeypatch.setattr(supersets, "SUPERSET_READINGS", 10**9)
    costly = frozenset({"coulomb"})
    families = Supersets(bench, frozenset(), free_friction=True)
    assert families.for_model(costly, _model(bench, costly)) is None
