"""The warm-up threads make the programs of a fit's later stages while the MAP runs:
each once, the very ones the stages then call, and none when stopped first."""

from __future__ import annotations

import time

import numpy as np

from pmdc_bayes.inference import _runtime as cache
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.inference.sampling.posterior import sample_posterior
from pmdc_bayes.inference.warmup import WarmUp
from pmdc_bayes.io.loader import load_session

LATER = {"predict", "log_posterior_batch", "pointwise-residuals"}


def _model(session_dir):
    session = load_session(session_dir)
    return build_model(session, fit_seed(session))


def _made(model) -> dict:
    """Per program name of ``model``'s structure, the programs made (signatures)."""
    key = model.structure_key()
    return {k[0]: len({id(p) for p in fn.programs.values()})
            for k, fn in cache._IN_MEMORY.items() if k[1:] == key}


def test_the_warm_up_makes_what_the_sampler_then_calls(session_dir):
    cache._IN_MEMORY.clear()
    model = _model(session_dir)
    warm = WarmUp(model, mcmc=True)
    fit = fit_map(model, seed=0)  # meanwhile, in this thread
    warm.join()
    made = _made(model)
    assert LATER <= set(made) and all(made[n] == 1 for n in LATER)
    post = sample_posterior(model, fit, seed=0, max_steps=400, progress=False)
    assert np.isfinite(post.draws).all()
    assert {n: _made(model)[n] for n in LATER} == {n: 1 for n in LATER}  # none made again


def test_without_mcmc_only_the_prediction_is_made(session_dir):
    cache._IN_MEMORY.clear()
    model = _model(session_dir)
    WarmUp(model, mcmc=False).join()
    made = _made(model)
    assert "predict" in made and not ({"log_posterior_batch", "pointwise-residuals"} & set(made))


def test_a_stopped_warm_up_begins_nothing_more(session_dir):
    cache._IN_MEMORY.clear()
    model = _model(session_dir)
    warm = WarmUp(model, mcmc=True, start=False)  # stopped before its threads start
    warm.stop()
    warm.start()
    warm.join()
    assert not (LATER & set(_made(model)))


def test_fits_makes_each_models_fitting_programs_which_the_fits_then_use(session_dir):
    import dataclasses

    cache._IN_MEMORY.clear()
    session = load_session(session_dir)
    models = [build_model(s, fit_seed(s)) for s in
              (session, dataclasses.replace(session, nuisances=("dead_time",)))]
    assert models[0].structure_key() != models[1].structure_key()
    warm = WarmUp.fits(models)
    warm.join()
    for model in models:
        assert {n: c for n, c in _made(model).items()} == {"optimistix-step": 1, "predict": 1}
        fit_map(model, seed=0)
        assert _made(model)["optimistix-step"] == 1  # the fit called the program made ahead


def test_fits_makes_no_more_models_programs_ahead_than_its_bound(session_dir):
    """With a lookahead of one, the threads make the programs of the model after the one
    being fitted, then wait: a search's dozen candidates are not all held at once."""
    import dataclasses

    cache._IN_MEMORY.clear()
    session = load_session(session_dir)
    models = [build_model(s, fit_seed(s)) for s in
              (dataclasses.replace(session, nuisances=("dead_time",)),
               dataclasses.replace(session, nuisances=("speed_lag",)))]
    warm = WarmUp.fits(models, threads=2, lookahead=1)  # the caller fits another
    deadline = time.monotonic() + 600
    while warm.waiting() < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert warm.waiting() == 2  # both threads wait at the second model's jobs
    assert _made(models[0]) == {"optimistix-step": 1, "predict": 1} and not _made(models[1])
    warm.fitting(models[0])  # the caller now fits the first: the next may be made
    warm.join()
    assert _made(models[1]) == {"optimistix-step": 1, "predict": 1} and warm.waiting() == 0


def test_a_stopped_warm_up_waiting_for_the_fits_ends(session_dir):
    session = load_session(session_dir)
    model = build_model(session, fit_seed(session))
    warm = WarmUp.fits([model, model], threads=1, lookahead=0)  # nothing may be made yet
    deadline = time.monotonic() + 60
    while warm.waiting() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    warm.stop()
    warm.join()  # returns: the waiting thread is woken and ends
    assert warm.waiting() == 0
