"""The model search (``fit --compare``, and a plain fit whose ideal model the data reject):
models as sets of terms, the run copy's ``[model]``, the search's decisions, and on
benches the package's own model did not simulate (``simulate/bench.py``) the model it
reaches."""

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import SMALL_MOTOR, plan, plan_toml, step, sweep

from pmdc_bayes._x64 import x64
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.params import ParamSpec, Prior, Registry
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.rundir import SESSION_COPY, copy_session, write_model
from pmdc_bayes.search import ADD_MARGIN, _better, nested_start, search_model
from pmdc_bayes.selection import format_selection, laplace_log_evidence
from pmdc_bayes.simulate.bench import BenchMotor, bench_session
from pmdc_bayes.simulate.cases import MOTOR, STEADY_VOLTAGES, STEPS, case_session
from pmdc_bayes.terms import label, model_table, terms_of, with_terms

MODELS = (frozenset(), frozenset({"dead_time"}), frozenset({"dead_time:shared", "speed_lag"}),
          frozenset({"voltage_drop", "unknown_load:step_6v", "coulomb"}),
          frozenset({"current_limit", "source_resistance", "unknown_load:step_12v",
                     "unknown_load:step_6v"}))


def test_a_model_reads_back_as_the_terms_it_was_made_of():
    session = case_session(None, seed=2)
    for terms in MODELS:
        s = with_terms(session, terms)
        assert terms_of(s) == terms, terms
    assert label(frozenset()) == "ideal"
    assert label(MODELS[2]) == "dead time (shared) + speed lag"
    assert label(MODELS[3]) == "voltage drop + unknown load (step_6v) + Coulomb friction"
    table, friction = model_table(session, MODELS[3])
    assert table == {"voltage_drop": True, "unknown_load": ["step_6v"]}
    assert friction == "coulomb"


def test_the_run_copy_declares_the_chosen_model_and_reads_back_as_it(tmp_path):
    session = load_session(bundled_session_dir("demo"))
    original = (session.root / "session.toml").read_text()
    hashes = copy_session(session, tmp_path)
    trace = session.traces[0].name
    terms = frozenset({"dead_time:shared", "voltage_drop", f"unknown_load:{trace}"})
    table, friction = model_table(session, terms)
    written = write_model(session, tmp_path, table, friction="viscous")
    copy = tmp_path / SESSION_COPY
    back = load_session(copy)
    assert terms_of(back) == terms and back.friction == "viscous"
    assert set(written) == {"session.toml"} and written["session.toml"] != hashes["session.toml"]
    # the original is untouched; every other file of the copy is as recorded
    assert (session.root / "session.toml").read_text() == original
    assert "[model]" in (copy / "session.toml").read_text()
    # a model the copy cannot declare leaves the copy as it was
    before = (copy / "session.toml").read_text()
    assert write_model(session, tmp_path, {"unknown_load": ["no_such_trace"]}, "viscous") is None
    assert (copy / "session.toml").read_text() == before


@x64
def test_the_model_is_left_to_the_search_only_when_nothing_declares_it():
    """A [model], an --add or a --friction is the user's model: a plain fit does not
    search over it (the demo's viscous fit stays rejected, not patched with loads)."""
    from pmdc_bayes.pipeline import model_left_open

    demo = load_session(bundled_session_dir("demo"))
    assert model_left_open(demo, (), None)
    assert not model_left_open(demo, ("dead_time",), None)
    assert not model_left_open(demo, (), "viscous")
    assert not model_left_open(with_terms(demo, {"dead_time"}), (), None)


def test_a_nested_start_is_the_parent_with_the_additions_neutral(jax_x64):
    session = case_session(None, seed=2)
    parent = build_model(session, fit_seed(session))
    child_session = with_terms(session, {"dead_time", "speed_lag", "current_limit",
                                         "speed_gain"})
    child = build_model(child_session, fit_seed(child_session))
    values = {n: parent.registry[n].seed * 1.1 for n in parent.names}
    theta = nested_start(child, SimpleNamespace(values=values))
    got = child.registry.values(theta)
    for n in parent.names:
        assert got[n] == pytest.approx(values[n], rel=1e-12), n
    extra = set(child.names) - set(parent.names)
    assert {n for n in extra if n.startswith("dead_time")} == {"dead_time_step_12v",
                                                               "dead_time_step_6v"}
    for n in extra:
        spec = child.registry[n]
        if n.startswith("dead_time"):
            assert got[n] == 0.0
        elif n == "speed_gain":
            assert got[n] == pytest.approx(1.0)
        elif n == "Imax":  # far above the prior's centre (the largest logged current)
            assert got[n] > 8 * spec.prior.centre
        else:  # a lag far shorter than the prior's centre
            assert got[n] < spec.prior.centre / 100


def _cand(name, ok, z, undetermined=()):
    return SimpleNamespace(terms=frozenset({name}) if name else frozenset(), ok=ok,
                           log_evidence=z, undetermined=undetermined,
                           fit=SimpleNamespace(ok=True))


def test_an_addition_is_taken_only_when_the_evidence_or_the_verdict_calls_for_it():
    adequate = _cand("", True, 100.0)
    assert _better(adequate, [_cand("speed_lag", True, 100.0 + ADD_MARGIN - 0.1)])[0] is None
    best, why = _better(adequate, [_cand("speed_lag", True, 100.0 + ADD_MARGIN + 0.1),
                                   _cand("dead_time", True, 110.0)])
    assert best.terms == {"dead_time"} and "+10.0" in why
    # parameters the data cannot determine are not taken over an adequate model, nor a
    # model the data reject, however probable
    assert _better(adequate, [_cand("speed_gain", True, 120.0, ("speed_gain",))])[0] is None
    assert _better(adequate, [_cand("speed_lag", False, 200.0)])[0] is None
    # a model the data reject gives way to an adequate one no less probable, ...
    rejected = _cand("", False, 100.0)
    best, why = _better(rejected, [_cand("dead_time", True, 100.5),
                                   _cand("speed_lag", False, 102.0)])
    assert best.terms == {"dead_time"} and "reject" in why
    # ... and to a rejected one only by a clear gain
    assert _better(rejected, [_cand("speed_lag", False, 102.0)])[0] is None
    assert _better(rejected, [_cand("speed_lag", False, 104.0)])[0].terms == {"speed_lag"}


def test_each_term_of_a_move_of_several_is_taken_out_where_the_evidence_allows():
    """An unknown load tried on every suspect trace at once, then taken out of each trace
    whose data do not support it (it stayed on an unloaded trace, B undetermined)."""
    from pmdc_bayes.search import REMOVE_MARGIN, _removals

    both = frozenset({"unknown_load:braked", "unknown_load:free"})
    evidence = {both: 50.0, frozenset({"unknown_load:braked"}): 50.0 - REMOVE_MARGIN / 4,
                frozenset({"unknown_load:free"}): 20.0, frozenset(): 10.0}

    def cand(terms):
        return SimpleNamespace(terms=terms, ok=True, log_evidence=evidence[terms], why="",
                               fit=SimpleNamespace(ok=True), move="")

    class Search:
        done = {both: cand(both)}
        fits = 10

        def fits_left(self):
            return self.fits

        def evaluate(self, moves, parent, kind):
            assert kind == "remove"
            out = []
            for move in moves:
                c = cand(parent.terms - move)
                c.move = f"− {sorted(move)[0]}"
                self.done[c.terms] = c
                self.fits -= 1
                out.append(c)
            return out

    search = Search()
    chosen = _removals(search, search.done[both], frozenset(), both)
    assert chosen.terms == {"unknown_load:braked"}
    # a single term just added is not taken out again
    one = frozenset({"unknown_load:braked"})
    assert _removals(search, cand(one), frozenset(), one).terms == one
    # nor the last of a move of several, however little each costs: the move's gain
    evidence.update({frozenset(): 49.9, frozenset({"unknown_load:free"}): 49.95})
    search.done = {both: cand(both)}
    assert _removals(Search(), cand(both), frozenset(), both).terms in (
        {"unknown_load:braked"}, {"unknown_load:free"})


def test_the_path_on_screen_names_every_candidate_and_the_side_by_side_values():
    row = {"name": "ideal", "n_params": 5, "verdict": "inadequate", "log_evidence": 1.0,
           "delta_log_evidence": None, "failures": ["step: whiteness"], "why": "the ideal motor",
           "decision": "dropped", "values": {"K": [0.05, 1e-4], "switch_lead_step": [1e-4, 1e-5]}}
    rows = [row, dict(row, name="dead time", n_params=7, verdict="adequate", log_evidence=50.0,
                      delta_log_evidence=49.0, why="log Z +49.0 over ideal", decision="chosen"),
            dict(row, name="speed lag", n_params=6, verdict="adequate", log_evidence=49.5,
                 delta_log_evidence=48.5, why="log Z -0.5 against dead time",
                 values={"K": [0.0501, 1e-4], "switch_lead_step": [2e-4, 1e-5]})]
    sel = {"start": "ideal", "fits": 3, "max_fits": 16, "candidates": rows,
           "recommended": "dead time", "reason": "the data do not reject it",
           "equivalent": ["speed lag"]}
    lines = format_selection(sel)
    assert lines[0].startswith("Model search from ideal: 3 fits")
    assert any(x.startswith("*dead time") and "+49.0" in x for x in lines)
    assert lines[-6].startswith("The data do not tell it from: speed lag")
    # each model named in full, however long, and its column by its number
    assert lines[-5].split() == ["[1]", "dead", "time"]
    assert lines[-4].split() == ["[2]", "speed", "lag"] and lines[-3].split() == ["[1]", "[2]"]
    assert lines[-2].split()[0] == "K" and "0.0501" in lines[-2]
    # each column's number ends where its values end, however long a parameter's name
    head, k_row, lead_row = lines[-3:]
    assert lead_row.split()[0] == "switch_lead_step"
    for number, value in (("[1]", "0.05"), ("[2]", "0.0501")):
        assert head.index(number) + 3 == k_row.index(value) + len(value)
    assert k_row.index("0.0501") == lead_row.index("0.0002")


# -- searches on simulated benches (slow: each candidate is a MAP fit) ------------------
def _search(session, **kw):
    sel = search_model(session, **kw)
    return sel, "\n".join(format_selection(sel))


@pytest.mark.compiles
@pytest.mark.parametrize(("case", "expected"), [
    (None, set()), ("dead time", {"dead_time"}), ("brush drop", {"voltage_drop"})])
def test_the_search_reaches_what_the_bench_has(case, expected):
    sel, text = _search(case_session(case, seed=2))
    chosen = {t.split(":")[0] for t in sel["terms"]}
    assert expected <= chosen, text
    assert sel["candidates"][-1]["verdict"] == "adequate" or any(
        r["decision"] == "chosen" and r["verdict"] == "adequate" for r in sel["candidates"])
    if case is None:  # in class: the ideal motor, and no addition clearly better
        assert sel["recommended"] == "ideal", text
    assert sel["fits"] <= sel["max_fits"]


@pytest.mark.compiles
def test_a_combination_is_reached_from_the_ideal_model():
    """A dead time and a brush drop at once: no single addition makes the model adequate,
    the search takes the dead time, then the drop, and the data do not reject the pair."""
    from pmdc_bayes.inference import _runtime
    from pmdc_bayes.search import run_search

    session = bench_session(BenchMotor(**MOTOR, dead_time=3e-3, voltage_drop=1.0), STEPS,
                            seed=3, steady_voltages=STEADY_VOLTAGES)
    before = set(_runtime._IN_MEMORY)
    found = run_search(session)
    sel, text = found.record, "\n".join(format_selection(found.record))
    # the programs of every model dropped are let go: of the MAP's programs made, only
    # the chosen model's is kept (the run goes on from it)
    kept = {k[1:] for k in set(_runtime._IN_MEMORY) - before if k[0] == "optimistix-step"}
    assert kept <= {found.chosen.model.structure_key()} and len(sel["candidates"]) > 2
    chosen = {t.split(":")[0] for t in sel["terms"]}
    assert {"dead_time", "voltage_drop"} <= chosen, text
    assert next(r for r in sel["candidates"] if r["decision"] == "chosen")["verdict"] \
        == "adequate", text


@pytest.mark.compiles
@x64
def test_a_larger_model_never_ends_below_the_one_it_contains():
    """Started also from its parent's MAP with the dead times at zero (their prior's
    centre, so the start's log-posterior is the parent's maximum), the larger model's
    maximum is at least the parent's."""
    session = case_session("sensor lag", seed=2)
    parent_s = with_terms(session, {"speed_lag"})
    parent = build_model(parent_s, fit_seed(parent_s))
    pfit = fit_map(parent, seed=0)
    child_s = with_terms(session, {"speed_lag", "dead_time:shared"})
    child = build_model(child_s, fit_seed(child_s))
    start = nested_start(child, pfit)
    at_start = float(child.log_posterior(start))
    assert at_start == pytest.approx(pfit.log_posterior, abs=1e-6 * abs(pfit.log_posterior))
    cfit = fit_map(child, seed=0, n_starts=1, alternatives=[start])
    assert cfit.log_posterior >= pfit.log_posterior - 1e-9 * abs(pfit.log_posterior)
    assert np.isfinite(cfit.log_posterior)


PLAN = plan_toml(plan(
    seed=5, motor="delayed motor", truth=SMALL_MOTOR,
    bench={"Ra": (0.06, "ohm"), "La": (0.2, "mH")},
    steady=(sweep([4.0, 8.0, 12.0], 0.2, 0.001),),
    traces=(step("step_12v", 12.0, duration=0.12, rate=5000.0, speed_noise=0.05,
                 current_noise=0.002, delay=3e-3),)))


@pytest.mark.compiles
def test_a_plain_fit_searches_and_its_run_copy_reproduces_the_choice(tmp_path, monkeypatch,
                                                                    capsys):
    """No [model], the ideal model rejected (a 3 ms dead time): a plain fit searches, goes
    on from the fit of the model it chose (not fitting it again), and writes it into the
    run's copy of session.toml; the report re-read from the run and a refit of the copy
    (without a search) use that model."""
    from pmdc_bayes import pipeline
    from pmdc_bayes.pipeline import FitOptions, run_fit
    from pmdc_bayes.readback import read_run
    from pmdc_bayes.simulate.session import simulate_session

    (tmp_path / "plan.toml").write_text(PLAN)
    session = simulate_session(tmp_path / "plan.toml", tmp_path / "session")
    refits = []
    monkeypatch.setattr(pipeline, "fit_map", lambda *a, **k: refits.append(1) or fit_map(*a, **k))
    out, summary = run_fit(session, FitOptions(mcmc=False), out=tmp_path / "run")
    assert refits == [] and summary["diagnostics"]["wall_s"]["model_search"] > 0
    sel = summary["model_selection"]
    assert sel["candidates"][0]["name"] == "ideal"
    assert sel["candidates"][0]["verdict"] == "inadequate"
    assert "dead_time" in sel["nuisances"], format_selection(sel)
    assert summary["adequacy"]["verdict"] == "adequate"
    # it stops at the first model the data do not reject: no addition tried beyond it
    assert sel["stopped"] == "adequate_reached", format_selection(sel)
    assert sel["compare"] is False
    from pmdc_bayes._console import print_fit

    capsys.readouterr()
    print_fit(summary, out)  # the terminal says why it searched, and how not to
    assert ("The model, found by a search (the data reject the session's model; "
            "--no-search skips it):") in capsys.readouterr().out
    chosen = next(r for r in sel["candidates"] if r["decision"] == "chosen")
    assert not [r for r in sel["candidates"]
                if r["parent"] == chosen["name"] and r["move"].startswith("+")]
    names = list(summary["fit"]["names"])
    copy = load_session(out / SESSION_COPY)
    assert terms_of(copy) == frozenset(sel["terms"])
    assert "[model]" not in (session / "session.toml").read_text()
    again = read_run(out)  # what `pmdc-bayes report RUN` reads
    assert list(again.model.names) == names
    _, refit = run_fit(out / SESSION_COPY, FitOptions(mcmc=False, search=False),
                       out=tmp_path / "refit")
    assert "model_selection" not in refit
    assert list(refit["fit"]["names"]) == names
    for name in names:
        a, b = summary["parameters"][name], refit["parameters"][name]
        assert abs(a["map"] - b["map"]) <= 1e-3 * a["map_sd"] + 1e-12, name
    # --no-search: the session's own (ideal) model, rejected, no search recorded
    _, plain = run_fit(session, FitOptions(mcmc=False, search=False), out=tmp_path / "plain")
    assert "model_selection" not in plain and plain["adequacy"]["verdict"] == "inadequate"


@x64
def test_a_half_normal_priors_evidence_counts_only_its_positive_half():
    """With no data a candidate's evidence is its prior's mass, 1 (log 0), whatever the
    prior's scale: a positive quantity fitted in log under a Gaussian prior in value
    centred on zero (a voltage drop's half-normal) integrates over θ to one half of that
    Gaussian, which the evidence must put back (without it: log Z ≈ −0.85)."""
    import jax
    import jax.numpy as jnp

    for scale in (0.01, 1.2, 30.0):
        spec = ParamSpec("Vdrop", "V", "driver", Prior("half_normal", 0.0, scale), seed=scale)
        registry = Registry([spec])
        centre, sd = registry.prior_arrays()

        def log_prior(theta, registry=registry, centre=centre, sd=sd):
            return registry.log_prior(theta, centre, sd)

        mode = jnp.log(jnp.asarray([scale]))  # where θ − e^{2θ}/(2s²) peaks
        assert float(jax.grad(log_prior)(mode)[0]) == pytest.approx(0.0, abs=1e-9)
        cov = np.linalg.inv(-np.asarray(jax.hessian(log_prior)(mode)))
        model = SimpleNamespace(registry=registry, data={"prior_scale": sd})
        fit = SimpleNamespace(log_posterior=float(log_prior(mode)), cov_log=cov,
                              overflows=False)
        # the Laplace approximation of this skewed density, at its mode log s with
        # curvature 2: log Z = −1/2 + log 2 + log(1/√2) = log 0.858
        assert laplace_log_evidence(model, fit) == pytest.approx(np.log(0.858), abs=0.01)
