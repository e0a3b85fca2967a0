"""A fuzzed session's posterior as a run samples it: the sampler's tests on data from
the bench simulator."""

from __future__ import annotations


def sampled(seed: int, tmp_path):
    """``(fuzzed session, model, posterior, (gates passed, failures))``: the fuzzer's
    session of ``seed`` written, loaded, fitted from its closed-form seed and sampled,
    each with ``seed``."""
    from pmdc_bayes.inference.fit.joint import fit_map
    from pmdc_bayes.inference.model.objective import build_model
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.inference.sampling.posterior import gates, sample_posterior, summarize
    from pmdc_bayes.io.loader import load_session
    from pmdc_bayes.simulate.fuzz import fuzz_session

    fz = fuzz_session(seed, out=tmp_path / f"s{seed}")
    session = load_session(fz.path)
    model = build_model(session, fit_seed(session))
    post = sample_posterior(model, fit_map(model, seed=seed), seed=seed, progress=False)
    return fz, model, post, gates(summarize(post), posterior=post)
