"""Posterior sampling of a session model with emcee, and its ArviZ record.

:func:`sample_posterior` runs ensemble samplers (independence proposals from the
Laplace approximation and differential-evolution moves by default) as independent
ensembles (:mod:`.ensembles`) started around the MAP, moving in the coordinates of
:mod:`.coordinates` (the positive quantities in log or in value, whichever the
posterior is closer to Gaussian in around the MAP), in chunks, until the chain is many
integrated autocorrelation times long, the autocorrelation estimate has settled and
the draws pass the gates, or until the steps this rule projects from the chain's own
state exceed a step budget (:mod:`.rule`, stepped between chunks, with the pieces of
:mod:`.stopping`): a stop that depends on the seed and the data, not on the machine's
load.  The result, :class:`Posterior`, carries its status in
words; :func:`summarize` and :func:`gates` (in :mod:`pmdc_bayes.inference.sampling.diagnostics`)
say whether it can be trusted.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from tqdm.auto import tqdm

from ... import _signals
from ..._x64 import to_device, x64
from .coordinates import Coordinates, exact_laplace
from .diagnostics import (
    az,
    compare_laplace,
    format_loo,
    gates,
    loo_compare,
    summarize,
)
from .ensembles import ENSEMBLES, Ensembles, r_hat_between
from .idata import LL_DRAWS, to_inference_data
from .logprob import LogProb, initial_walkers
from .logprob import batch_log_posterior as _log_posterior_batch
from .motor_coordinates import motor_maps
from .moves import LaplaceIndependenceMove, LaplaceMixture, default_moves
from .rule import CHUNK, RuleState, StoppingRule
from .stopping import CHECK, Stop, burn_in

__all__ = ["Posterior", "Stop", "sample_posterior", "to_inference_data", "summarize", "gates",
           "compare_laplace", "loo_compare", "format_loo", "default_moves",
           "LaplaceIndependenceMove", "warm_up"]

MAX_STEPS = 20_000  # the step budget: the most steps a run may take



@dataclass(frozen=True)
class Posterior:
    """An ensemble sample of the posterior, burn-in removed, not thinned.

    Attributes
    ----------
    names : parameter names, in θ order.
    draws : ``(chains, draws, ndim)`` SI values; walkers are the chains.
    draws_log : the same draws in log space (θ).
    log_prob : ``(chains, draws)`` log-posterior of each draw.
    acceptance : per-walker acceptance fraction over the whole run.
    tau : integrated autocorrelation time per parameter (steps), at the end.
    n_steps, burn_in : steps run and steps discarded: those before the independence
        proposals' last refit (``idata.posterior.attrs['adapted']``, 0 without one;
        ``attrs['independence_share']`` the share of steps they then took) and
        ``ceil(2·max τ)`` after it.  ``attrs['sampled_in_value']`` names, comma-separated,
        the positive parameters the walkers moved in value rather than in log
        (:class:`~.coordinates.Coordinates`; empty: all in θ), ``attrs['coordinates']``
        which coordinates it moved in (``"theta"``, ``"value"``, ``"motor constants"``,
        ``"motor response"``).
    capped : the run stopped before the stopping rule was met; ``stop`` says how
        (:class:`~pmdc_bayes.inference.sampling.stopping.Stop`), ``message`` why in words.
    wall_time : seconds spent sampling (including the log-likelihood for ``idata``).
    idata : the ArviZ record (see :func:`to_inference_data`).
    r_hat_between : per parameter, the R-hat across the independent ensembles the
        walkers belong to (:mod:`.ensembles`); None when there was one ensemble.
    """

    names: tuple
    draws: np.ndarray
    draws_log: np.ndarray
    log_prob: np.ndarray
    acceptance: np.ndarray
    tau: dict
    n_steps: int
    burn_in: int
    capped: bool
    message: str
    wall_time: float
    idata: az.InferenceData
    r_hat_between: dict | None = None
    stop: Stop = Stop.CONVERGED

    def draws_si(self) -> dict[str, np.ndarray]:
        """All draws of each parameter (SI), chains flattened."""
        return {n: self.draws[..., k].reshape(-1) for k, n in enumerate(self.names)}


def _layout(ndim: int, n_walkers: int | None = None) -> tuple[int, int, int]:
    """``(walkers, ensembles, batch)``: the walkers (even, at least two per parameter),
    the independent ensembles they form, and the θ per call of the batch log-posterior
    (half an ensemble: emcee moves half its walkers at a time)."""
    if n_walkers is None:
        n_walkers = max(32, 4 * ndim)
    n_walkers += n_walkers % 2
    if n_walkers < 2 * ndim:
        raise ValueError(f"n_walkers={n_walkers} is too few for {ndim} parameters; "
                         f"use at least {2 * ndim}")
    # independent ensembles when each can have 2 walkers per parameter and an even count
    k = ENSEMBLES if n_walkers % (2 * ENSEMBLES) == 0 and \
        n_walkers // ENSEMBLES >= 2 * ndim else 1
    return n_walkers, k, max(1, n_walkers // (2 * k))


@x64
def warm_up(model, theta, n_walkers: int | None = None) -> None:
    """Make (compile, or load from the cache) the batch log-posterior
    :func:`sample_posterior` calls, in the batch size it uses, by calling it once at
    ``theta``."""
    _, _, batch = _layout(len(model.names), n_walkers)
    theta = np.asarray(theta, dtype=float)
    _log_posterior_batch(model)(to_device(np.repeat(theta[None], batch, axis=0)))


@x64
def sample_posterior(model, fit, *, seed: int = 0, n_walkers: int | None = None,
                     max_steps: int = MAX_STEPS, min_tau_multiple: float = 50,
                     progress: bool | None = None, moves=None, ll_draws: int = LL_DRAWS,
                     max_seconds: float | None = None, budget: float | None = None) -> Posterior:
    """Sample the posterior of ``model`` with an emcee ensemble started at ``fit``.

    Parameters
    ----------
    model : a :class:`pmdc_bayes.inference.model.objective.SessionModel`.
    fit : its MAP fit (:func:`pmdc_bayes.inference.fit.joint.fit_map`): walkers start from
        ``N(fit.theta, fit.cov_log)``.
    seed : seeds the initial walkers and emcee's generator; same seed, same draws.
    n_walkers : default ``max(32, 4·ndim)``, rounded up to even.
    max_steps : the step budget and hard cap; a capped run says so in ``capped``,
        ``stop`` and ``message``.
    min_tau_multiple : stop once the chain (after the proposals' last refit, see
        :mod:`.moves`) is this many τ_max long, every τ changed by less than 5 % since
        the previous check or the chain twice that long (τ is estimated after 50 steps
        with the default moves, then every 200 steps; once the chain is long enough,
        every 100 steps or 5 % of its length, whichever is more), and the draws after
        burn-in already pass the gates (R-hat ≤ 1.01, bulk and tail ESS ≥ 400; while
        they are far from it, on a thinned chain, and again only after the steps that
        their shortfall predicts).
    progress : a tqdm bar (on stderr, or a notebook's widget); default in a terminal or
        a Jupyter kernel.
    moves : emcee moves; default :func:`default_moves` (Laplace independence proposals,
        refitted on each ensemble's own chain during the first 800 steps where they do
        not describe it, mixed with differential evolution, and given nine steps in
        ten from the first check on where they are mostly accepted); moves given here
        are not adapted.
    ll_draws : at most this many draws carry the pointwise log-likelihood in ``idata``
        (evenly thinned along each chain).
    max_seconds : an optional limit on the sampling's wall time (checked between
        chunks of steps; default none); a run stopped by it is ``capped``, and
        ``message`` says what the stopping rule still lacked
        (:func:`~pmdc_bayes.inference.sampling.stopping.stop_message`).  A run that stops first
        does not depend on it; one it stops depends on the machine's speed.
    budget : give up, ``capped``, at a check where the length the rule projects
        (:func:`~pmdc_bayes.inference.sampling.stopping.steps_needed`, from τ and the gates'
        shortfall) exceeds this many steps (default ``max_steps``; ``math.inf``: run to
        ``max_steps``).  Without ``max_seconds`` the stop, the draws and the verdict
        depend only on the model, the fit and ``seed``.
    """
    t_start = time.perf_counter()
    ndim = len(model.names)
    n_walkers, k, batch = _layout(ndim, n_walkers)
    if progress is None:  # a terminal, or a notebook (where tqdm.auto draws a widget)
        progress = sys.stderr.isatty() or "ipykernel" in sys.modules
    batch_fn = _log_posterior_batch(model)
    log_prob = LogProb(batch_fn, batch, model.registry.is_log())
    rng = np.random.default_rng(seed)
    theta0, lp0 = initial_walkers(fit, log_prob, n_walkers, rng)
    # the walkers move in φ (:mod:`.coordinates`); the draws are mapped back to θ
    local = exact_laplace(fit, log_prob)  # the posterior's own curvature at the MAP
    xy = Coordinates.for_fit(model.registry, local, log_prob, motor_maps(model.registry))
    sampler = Ensembles(k, n_walkers, ndim, xy.log_prob(log_prob), xy.from_theta(theta0),
                        lp0 + xy.log_jacobian(theta0), seed=seed,
                        moves=lambda j: default_moves(xy.laplace(local)) if moves is None
                        else moves)
    rule = StoppingRule(max_steps, min_tau_multiple,
                        max_steps if budget is None else budget, max_seconds,
                        adapting=moves is None, k=k,
                        # the SI values of draws in φ, on which the gates are judged
                        values=lambda phi: model.registry.to_values(xy.to_theta(phi)))
    state, elapsed = _run(rule, sampler, progress)
    return _posterior(model, sampler, xy, rule, state, elapsed, ll_draws=ll_draws, seed=seed,
                      own_moves=moves is not None, t_start=t_start)


def _run(rule: StoppingRule, sampler: Ensembles, progress: bool) -> tuple[RuleState, float]:
    """Run ``sampler`` in chunks until ``rule`` stops it: the rule's last state and the
    seconds it took."""
    state = rule.init()
    # the bar's length: until τ is first estimated, the least the stopping rule can
    # need (a first estimate and one to compare it with); then what it needs at τ
    bar = tqdm(total=min(rule.max_steps, CHUNK + CHECK), disable=not progress,
               file=sys.stderr, unit="step")
    t_loop = time.perf_counter()
    with bar:
        while not rule.terminate(state):
            n = rule.chunk(state)
            sampler.run_mcmc(n)
            _signals.check()  # an interrupt Python dropped in a callback stops here
            bar.update(n)
            state = rule.step(state, sampler, n, time.perf_counter() - t_loop)
            if state.checked == state.steps and state.stop is not Stop.CONVERGED:
                bar.total = rule.projected(state)
                bar.set_postfix(tau_max=f"{state.tau.max():.0f}")
    return state, time.perf_counter() - t_loop


def _posterior(model, sampler: Ensembles, xy: Coordinates, rule: StoppingRule,
               state: RuleState, elapsed: float, *, ll_draws: int, seed: int,
               own_moves: bool, t_start: float) -> Posterior:
    """The draws after burn-in as a :class:`Posterior`, with their ArviZ record."""
    names = tuple(model.names)
    burn = burn_in(state.tau, state.steps, state.adapted)
    chain = xy.to_theta(np.swapaxes(sampler.get_chain(discard=burn), 0, 1))  # (walkers, draws, P)
    lp = np.swapaxes(sampler.get_log_prob(discard=burn), 0, 1) - xy.log_jacobian(chain)
    acc = np.asarray(sampler.acceptance_fraction, dtype=float)
    converged = state.stop is Stop.CONVERGED
    idata = to_inference_data(model, chain, lp, acc, ll_draws=ll_draws, seed=seed)
    idata.posterior.attrs.update(n_steps=state.steps, burn_in=burn, capped=int(not converged),
                                 ensembles=rule.k, adapted=state.adapted,
                                 stop=state.stop.name, coordinates=xy.kind,
                                 sampled_in_value=",".join(xy.in_value(names)))
    shares = [] if own_moves else [m.share for ms in sampler.moves for m, _ in ms
                                   if isinstance(m, LaplaceMixture)]
    if shares:  # the independence proposals' share of the steps the kept draws took
        idata.posterior.attrs["independence_share"] = float(np.mean(shares))
    si = model.registry.to_values(chain)
    return Posterior(names, si, chain, lp, acc,
                     dict(zip(names, map(float, state.tau), strict=True)), state.steps, burn,
                     not converged, rule.message(state, names, elapsed),
                     time.perf_counter() - t_start, idata, r_hat_between(si, rule.k, names),
                     state.stop)
