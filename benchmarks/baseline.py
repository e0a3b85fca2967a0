"""The baseline: what a careful user would write without pmdc_bayes.

The same motor model, equations (5)–(6) with viscous friction, integrated with
``scipy.integrate.solve_ivp`` (LSODA, rtol 1e-6, atol 1e-8, the analytic Jacobian
given, the integration restarted at every input breakpoint so that no step straddles
a jump), and the same log-posterior as :mod:`pmdc_bayes.inference.model.objective`, written in plain
NumPy: the same channels (each trace's speed and current, the steady speeds, the
steady currents, the step readings' time constants), each channel's noise integrated
out, ``−(n_c + ν0)/2 · log(ν0·s0_c² + SS_c)`` with ν0 = 2 and the same data-derived
scales s0_c, the same Gaussian bench priors on Ra and La and log-normal priors on K,
B, J.  Its log-probability is a plain Python function of one θ for ``emcee``.

Nothing here imports pmdc_bayes: the session records (``session.traces``,
``.operating_points``, ...) and the closed-form seed (``seed.K``, ``.B``, ``.J``) are
read by attribute only.  The benchmark (``benchmarks/run.py``) and
``tests/project/test_baseline.py`` check that it computes the project's log-likelihood.
Viscous friction only: a Coulomb session raises ``ValueError``.
"""

from __future__ import annotations

import time

import emcee
import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["BaselinePosterior", "run_emcee", "user_script", "RTOL", "ATOL", "NU0",
           "PRIOR_FACTOR"]

RTOL, ATOL = 1e-6, 1e-8  # solve_ivp tolerances (LSODA)
NU0 = 2.0  # pseudo-observations of each channel's inverse-gamma noise prior
PRIOR_FACTOR = 10.0  # one-sd width of the log-normal priors on K, B, J
STEADY_RELATIVE_NOISE = 0.01  # prior noise scale of steady points: 1 % of a typical reading


def noise_scale(y) -> float:
    """Noise level of a sampled signal from its second differences (robust MAD), with
    the quantisation noise q/√12 of its smallest step as a floor."""
    y = np.asarray(y, dtype=float)
    d2 = np.diff(y, 2)
    mad = 1.482602218505602 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
    steps = np.abs(np.diff(y))
    steps = steps[steps > 1e-12 * max(1.0, np.abs(y).max())]
    quantum = steps.min() / np.sqrt(12.0) if steps.size else 0.0
    return float(max(mad, quantum, 1e-9 * max(1e-12, np.abs(y).max())))


def _typical(x) -> float:
    x = np.abs(np.asarray(x, dtype=float))
    return float(np.mean(x)) if x.size else 1.0


class _Trace:
    """One trace prepared for integration: constant-input segments and their samples."""

    def __init__(self, tr):
        t = np.asarray(tr.time, dtype=float)
        vt, vv = np.asarray(tr.voltage.times, float), np.asarray(tr.voltage.values, float)
        lt, lv = np.asarray(tr.load_torque.times, float), np.asarray(tr.load_torque.values, float)

        def held(times, values, at):
            k = np.searchsorted(times, at, side="right") - 1
            return values[np.clip(k, 0, len(values) - 1)]

        inner = np.concatenate([vt, lt])
        starts = np.unique(np.concatenate([[t[0]], inner[(inner > t[0]) & (inner < t[-1])]]))
        ends = np.append(starts[1:], t[-1])
        self.segments = []  # (t_start, t_end, Va, TL, sample indices in [t_start, t_end))
        for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
            last = k == len(starts) - 1
            sel = np.flatnonzero((t >= a) & ((t <= b) if last else (t < b)))
            self.segments.append((a, b, float(held(vt, vv, a)), float(held(lt, lv, a)), sel))
        self.n = t.size
        self.t = t
        self.initial = tr.initial if isinstance(tr.initial, str) else tuple(tr.initial)
        self.speed = np.asarray(tr.speed, dtype=float)
        self.current = None if tr.current is None else np.asarray(tr.current, dtype=float)


def simulate_trace(params, trace: _Trace, *, rtol: float = RTOL, atol: float = ATOL):
    """``(ia, ω)`` at the trace's samples (A, rad/s), by LSODA segment by segment.

    ``params`` is ``(Ra, La, K, B, J)`` in SI.  Raises ``RuntimeError`` if a solve fails.
    """
    Ra, La, K, B, J = params
    A = np.array([[-Ra / La, -K / La], [K / J, -B / J]])

    def jac(t, y):
        return A

    ia = np.empty(trace.n)
    w = np.empty(trace.n)
    y = None
    for a, b, va, tl, sel in trace.segments:
        u = np.array([va / La, -tl / J])
        if y is None:
            if trace.initial == "rest":
                y = np.zeros(2)
            elif trace.initial == "steady":
                den = K * K + Ra * B
                y = np.array([(B * va + K * tl) / den, (K * va - Ra * tl) / den])
            else:
                y = np.asarray(trace.initial, dtype=float)

        def rhs(t, x, u=u):
            return A @ x + u

        if b <= a:  # a single sample: nothing to integrate
            ia[sel], w[sel] = y[0], y[1]
            continue
        t_s = trace.t[sel]
        t_eval = t_s if t_s.size and t_s[-1] == b else np.append(t_s, b)
        sol = solve_ivp(rhs, (a, b), y, method="LSODA", t_eval=t_eval, rtol=rtol, atol=atol,
                        jac=jac)
        if sol.status != 0:
            raise RuntimeError(f"solve_ivp failed on [{a}, {b}] s: {sol.message}")
        ia[sel], w[sel] = sol.y[0, : sel.size], sol.y[1, : sel.size]
        y = sol.y[:, -1]
    return ia, w


class BaselinePosterior:
    """The session log-posterior in plain NumPy/SciPy, θ = log(Ra, La, K, B, J).

    Parameters
    ----------
    session : a session record (traces, operating points, steady tables, step
        readings, bench Ra and La), read by attribute.
    seed : the closed-form estimate (``K``, ``B``, ``J``) the priors are centred on.
    rtol, atol : solve_ivp tolerances.
    """

    names = ("Ra", "La", "K", "B", "J")

    def __init__(self, session, seed, *, rtol: float = RTOL, atol: float = ATOL):
        if getattr(session, "friction", "viscous") != "viscous":
            raise ValueError(f"the baseline models viscous friction only; session friction "
                             f"is {session.friction!r}")
        self.rtol, self.atol = rtol, atol
        self.traces = [_Trace(tr) for tr in session.traces]
        # Channels, in the project's order: per trace speed (and current), then steady
        # speeds, steady currents, step-reading time constants.
        s0, n = [], []
        for tr in self.traces:
            s0.append(noise_scale(tr.speed)), n.append(tr.n)
            if tr.current is not None:
                s0.append(noise_scale(tr.current)), n.append(tr.n)
        v, tl, w, i, has_i = [], [], [], [], []
        for op in session.operating_points:
            v.append(op.voltage), tl.append(op.load_torque), w.append(op.speed)
            i.append(0.0 if op.current is None else op.current)
            has_i.append(op.current is not None)
        for tab in session.steady_tables:
            for k in range(len(tab.voltage)):
                v.append(tab.voltage[k]), tl.append(tab.load_torque[k]), w.append(tab.speed[k])
                i.append(tab.current[k] if tab.current is not None else 0.0)
                has_i.append(tab.current is not None)
        for s in session.step_readings:
            v.append(s.voltage), tl.append(0.0), w.append(s.final_speed), i.append(0.0)
            has_i.append(False)
        self.steady_v, self.steady_tl = np.asarray(v, float), np.asarray(tl, float)
        self.steady_w, self.steady_i = np.asarray(w, float), np.asarray(i, float)
        self.has_i = np.asarray(has_i, dtype=bool)
        self.tau_obs = np.asarray([s.tau for s in session.step_readings], dtype=float)
        s0 += [STEADY_RELATIVE_NOISE * _typical(self.steady_w),
               STEADY_RELATIVE_NOISE * _typical(self.steady_i[self.has_i]),
               STEADY_RELATIVE_NOISE * (float(np.mean(self.tau_obs)) if self.tau_obs.size
                                        else 1.0)]
        n += [self.steady_w.size, int(self.has_i.sum()), self.tau_obs.size]
        self.s0, self.n_obs = np.asarray(s0), np.asarray(n, dtype=float)
        self.bench = ((session.Ra.value, session.Ra.sd), (session.La.value, session.La.sd))
        self.prior_mean = np.log([seed.K, seed.B, seed.J])
        self.prior_sd = np.log(PRIOR_FACTOR)

    def residuals(self, theta) -> list[np.ndarray]:
        """Residuals (observed − model) per channel."""
        Ra, La, K, B, J = np.exp(theta)
        res = []
        for tr in self.traces:
            ia, w = simulate_trace((Ra, La, K, B, J), tr, rtol=self.rtol, atol=self.atol)
            res.append(tr.speed - w)
            if tr.current is not None:
                res.append(tr.current - ia)
        den = K * K + Ra * B
        w = (K * self.steady_v - Ra * self.steady_tl) / den
        i = (B * self.steady_v + K * self.steady_tl) / den
        res.append(self.steady_w - w)
        res.append((self.steady_i - i)[self.has_i])
        res.append(self.tau_obs - J * Ra / (B * Ra + K * K))
        return res

    def sums_of_squares(self, theta) -> np.ndarray:
        """Sum of squared residuals per channel (observed − model)."""
        return np.asarray([np.sum(r * r) for r in self.residuals(theta)])

    def log_likelihood(self, theta) -> float:
        """Σ_c −(n_c + ν0)/2 · log(ν0·s0_c² + SS_c): each channel's σ integrated out."""
        ss = self.sums_of_squares(theta)
        terms = -0.5 * (self.n_obs + NU0) * np.log(NU0 * self.s0**2 + ss)
        return float(np.sum(np.where(self.n_obs > 0, terms, 0.0)))

    def log_prior(self, theta) -> float:
        """Gaussian bench priors on Ra, La (in value, with the log-Jacobian), log-normal
        priors on K, B, J."""
        theta = np.asarray(theta, dtype=float)
        (ra, ra_sd), (la, la_sd) = self.bench
        bench = ((np.exp(theta[0]) - ra) / ra_sd) ** 2 + ((np.exp(theta[1]) - la) / la_sd) ** 2
        z = (theta[2:] - self.prior_mean) / self.prior_sd
        return float(-0.5 * bench - 0.5 * np.sum(z * z) + theta[0] + theta[1])

    def log_posterior(self, theta) -> float:
        """Log-posterior (up to a constant); −inf where the model cannot be evaluated."""
        theta = np.asarray(theta, dtype=float)
        if not np.all(np.isfinite(theta)) or np.any(np.abs(theta) >= 700.0):
            return -np.inf
        try:
            lp = self.log_prior(theta) + self.log_likelihood(theta)
        except (RuntimeError, ArithmeticError, ValueError):
            return -np.inf
        return lp if np.isfinite(lp) else -np.inf

    __call__ = log_posterior


def run_emcee(log_prob, p0, *, budget_s: float, seed: int = 0, moves=None):
    """Run ``emcee`` (one Python call per walker and step) until ``budget_s`` seconds.

    Returns ``(chain (steps, walkers, P), wall seconds, steps)``; the wall time counts
    the steps only (the initial log-probabilities are computed before the clock starts).
    """
    p0 = np.asarray(p0, dtype=float)
    n_walkers, ndim = p0.shape
    sampler = emcee.EnsembleSampler(n_walkers, ndim, log_prob,
                                    moves=[(emcee.moves.DEMove(), 1.0)] if moves is None
                                    else moves)
    sampler.random_state = np.random.RandomState(seed).get_state()
    state = emcee.State(p0, log_prob=np.array([log_prob(p) for p in p0]))
    t0 = time.perf_counter()
    steps = 0
    while time.perf_counter() - t0 < budget_s:
        state = sampler.run_mcmc(state, 1, progress=False)
        steps += 1
    wall = time.perf_counter() - t0
    return sampler.get_chain(), wall, steps


def user_script(base: BaselinePosterior, theta0, *, budget_s: float, walkers: int = 32,
                seed: int = 0) -> dict:
    """What a user writes without this project: ``scipy.optimize.least_squares`` on the
    channels' residuals, each scaled by its noise level, from ``theta0`` (the closed
    form); then ``emcee`` with its default stretch move, the walkers in a small
    Gaussian ball around the least-squares solution (as emcee's documentation starts
    them), for ``budget_s`` seconds.

    Returns the least-squares wall time, the chain ``(steps, walkers, P)``, the emcee
    wall time and step count.
    """
    from scipy.optimize import least_squares

    def scaled(theta):
        try:
            parts = [r / s for r, s, n in zip(base.residuals(theta), base.s0, base.n_obs,
                                              strict=True) if n > 0]
        except (RuntimeError, ArithmeticError, ValueError):
            return np.full(int(base.n_obs.sum()), 1e6)
        return np.concatenate(parts)

    t0 = time.perf_counter()
    fit = least_squares(scaled, np.asarray(theta0, dtype=float), x_scale="jac")
    ls_wall = time.perf_counter() - t0
    rng = np.random.default_rng(seed)
    p0 = fit.x + 1e-4 * rng.standard_normal((walkers, fit.x.size))
    chain, wall, steps = run_emcee(base.log_posterior, p0, budget_s=budget_s, seed=seed,
                                   moves=emcee.moves.StretchMove())
    return {"least_squares_wall": ls_wall, "least_squares_nfev": int(fit.nfev),
            "chain": chain, "wall": wall, "steps": steps, "theta": fit.x}
