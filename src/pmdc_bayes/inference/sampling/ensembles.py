"""Independent emcee ensembles run side by side, read as one sample.

An ensemble's walkers are not independent chains: every move of one walker is drawn
from the positions of the others, so walkers that agree with each other can still all
be wrong together (an ensemble that has not yet left one part of the posterior).  The
R-hat of ArviZ over the walkers cannot see that.  :class:`Ensembles` therefore runs
``k`` ensembles that never exchange a position, each started from its own draws, and
:func:`r_hat_between` compares them: each ensemble's walkers pooled into one chain, the
rank-normalised split R-hat across the ensembles.  Agreement between independent
ensembles is what the gates then ask for, besides the walkers' own R-hat and ESS.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import emcee
import numpy as np

from .arviz_import import az

__all__ = ["Ensembles", "r_hat_between", "ENSEMBLES"]

ENSEMBLES = 2  # independent ensembles, when each can have at least 2 walkers per parameter


class Ensembles:
    """``k`` emcee ensembles of ``n_walkers // k`` walkers each over the same
    ``log_prob``, stepped together; the accessors give the walkers of all of them,
    ensemble by ensemble (so walker ``i`` of the result belongs to ensemble
    ``i // (n_walkers // k)``)."""

    def __init__(self, k: int, n_walkers: int, ndim: int, log_prob, p0, lp0, *, moves,
                 seed: int):
        if n_walkers % k:
            raise ValueError(f"{n_walkers} walkers do not split into {k} ensembles")
        m = n_walkers // k
        seeds = np.random.SeedSequence(seed).generate_state(k)
        self.k, self.samplers, self.states, self.moves = k, [], [], []
        for j in range(k):
            self.moves.append(moves(j))
            s = emcee.EnsembleSampler(m, ndim, log_prob, vectorize=True, moves=self.moves[j])
            s.random_state = np.random.RandomState(int(seeds[j]) if k > 1 else seed).get_state()
            self.samplers.append(s)
            self.states.append(emcee.State(p0[j * m:(j + 1) * m],
                                           log_prob=lp0[j * m:(j + 1) * m]))

    def run_mcmc(self, n: int) -> None:
        """``n`` steps of every ensemble, the ensembles in threads of their own (each
        waits mostly on the compiled log-posterior, which runs outside Python's lock, so
        on several cores they run side by side; each has its own generator, so the
        draws do not depend on how the threads interleave)."""
        if self.k == 1:
            self.states = [self.samplers[0].run_mcmc(self.states[0], n, progress=False)]
            return
        stop = threading.Event()

        def run(j):  # an error in one ensemble stops the others within a step
            state = self.states[j]
            try:
                for state in self.samplers[j].sample(self.states[j], iterations=n):  # noqa: B007 (the last is returned)
                    if stop.is_set():
                        break
            except BaseException:
                stop.set()
                raise
            return state

        with ThreadPoolExecutor(self.k - 1) as pool:
            try:
                others = [pool.submit(run, j) for j in range(1, self.k)]
                states = [run(0)] + [f.result() for f in others]
            except BaseException:  # an interrupt while waiting stops them too
                stop.set()
                raise
        self.states = states

    def adapt(self, **criteria) -> bool:
        """Adapt each ensemble's adaptable moves (those with ``adapt(samples,
        **criteria)``: :mod:`.moves`) to the later half of the ensemble's own chain so
        far; whether any move changed.  The chain before this point is then not a
        Markov chain of the final moves and must be discarded."""
        changed = False
        for s, moves in zip(self.samplers, self.moves, strict=True):
            chain = s.get_chain()
            recent = chain[chain.shape[0] // 2:].reshape(-1, chain.shape[-1])
            for move in (m[0] if isinstance(m, tuple) else m for m in (moves or ())):
                if hasattr(move, "adapt"):
                    changed = bool(move.adapt(recent, **criteria)) or changed
        return changed

    def get_chain(self, discard: int = 0, thin: int = 1) -> np.ndarray:
        """``(steps, walkers, P)``, every ensemble's walkers (every ``thin``-th step)."""
        return np.concatenate([s.get_chain(discard=discard, thin=thin) for s in self.samplers],
                              axis=1)

    def get_log_prob(self, discard: int = 0) -> np.ndarray:
        return np.concatenate([s.get_log_prob(discard=discard) for s in self.samplers], axis=1)

    @property
    def acceptance_fraction(self) -> np.ndarray:
        return np.concatenate([s.acceptance_fraction for s in self.samplers])

    def get_autocorr_time(self, discard: int = 0) -> np.ndarray:
        """Per parameter, the largest integrated autocorrelation time of the ensembles
        over the steps after ``discard`` (steps; the chain's length where it cannot be
        estimated, as for a walker that has not moved)."""
        taus = []
        for s in self.samplers:
            with np.errstate(invalid="ignore", divide="ignore"):  # a walker that never moved
                tau = np.asarray(s.get_autocorr_time(discard=discard, tol=0), dtype=float)
            taus.append(np.where(np.isfinite(tau), tau, float(s.iteration - discard)))
        return np.max(taus, axis=0)


def r_hat_between(chain: np.ndarray, k: int, names) -> dict[str, float] | None:
    """Rank-normalised split R-hat across ``k`` ensembles of ``chain`` ``(walkers,
    draws, P)`` (walkers ensemble by ensemble), each ensemble's walkers pooled into one
    chain; None for a single ensemble."""
    if k < 2:
        return None
    w, d, p = chain.shape
    pooled = chain.reshape(k, (w // k) * d, p)
    r = az.rhat({n: pooled[..., i] for i, n in enumerate(names)})
    return {n: float(r[n]) for n in names}
