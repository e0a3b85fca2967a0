"""Calibration of the posterior (issue 5): do 90 % intervals cover the truth 90 % of
the time?

Twenty synthetic motors are drawn from a prior around the reference paper's motor
(each parameter log-uniform within a factor 2 of its value); for each, a session of
one fixed structure is simulated (so the fit and the sampler compile once), fitted
(MAP, then emcee from the MAP), and the central 90 % interval of each parameter's
draws is checked against the truth.  The pooled count of covering intervals must lie
in the central 99 % binomial band around 0.90.

The pooled intervals of one motor are not independent (its parameters' errors are
correlated), so the binomial band is, if anything, a little narrow; the check is
still a strong one: a posterior ~2x too narrow covers ~55 %, far outside the band.
"""



import numpy as np  # noqa: E402
import pytest  # noqa: E402
from recovery_cases import Motor, plan_for  # noqa: E402
from scipy import stats  # noqa: E402

from pmdc_bayes.inference.fit.joint import fit_map  # noqa: E402
from pmdc_bayes.inference.model.objective import build_model  # noqa: E402
from pmdc_bayes.inference.sampling.posterior import sample_posterior  # noqa: E402
from pmdc_bayes.io.loader import load_session  # noqa: E402
from pmdc_bayes.paper.closed_form import closed_form  # noqa: E402
from pmdc_bayes.simulate.session import simulate_session  # noqa: E402

PAPER = {"Ra": 8.5, "La": 5.6e-3, "K": 0.062, "B": 4.5e-5, "J": 5.9e-4, "Tc": 2.5e-3}
VOLTAGE = 12.97  # V, the paper's top step
N_MOTORS = 20
FACTOR = 2.0
STRUCTURE = "viscous+current"
LEVEL = 0.90  # nominal coverage of the central intervals
BAND = 0.99  # probability of the acceptance band under Binomial(n, LEVEL)
MAX_STEPS = 1500  # emcee steps per motor (32 walkers); τ is a few to ~20 steps here


def prior_motors(n: int, seed: int = 20240611) -> list[Motor]:
    """``n`` motors, each parameter log-uniform in [x/FACTOR, x·FACTOR] around PAPER."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        values = {k: v * FACTOR ** rng.uniform(-1.0, 1.0) for k, v in PAPER.items()}
        out.append(Motor(f"prior-{i:02d}", V=VOLTAGE, structure=STRUCTURE, **values))
    return out


def binomial_band(n: int, p: float = LEVEL, mass: float = BAND) -> tuple[int, int]:
    """Counts ``[lo, hi]`` holding at least ``mass`` of Binomial(n, p), split evenly
    between the tails (scipy.stats.binom quantiles)."""
    tail = (1.0 - mass) / 2.0
    return int(stats.binom.ppf(tail, n, p)), int(stats.binom.ppf(1.0 - tail, n, p))


def test_binomial_band():
    lo, hi = binomial_band(100)
    assert (lo, hi) == (82, 97)
    # At least 99 % of the mass inside, by construction of the quantiles.
    assert stats.binom.cdf(hi, 100, 0.9) - stats.binom.cdf(lo - 1, 100, 0.9) >= 0.99


def _record(hits: dict, post, truth: dict) -> None:
    """Whether each parameter's central LEVEL interval of ``post`` covers ``truth``."""
    tail = (1.0 - LEVEL) / 2.0
    for name, draws in post.draws_si().items():
        lo, hi = np.quantile(draws, [tail, 1.0 - tail])
        hits.setdefault(name, []).append(bool(lo <= truth[name] <= hi))


def _assert_covered(hits: dict) -> int:
    """The pooled count of covering intervals lies in the 99 % binomial band; returns
    how many intervals there were."""
    per_parameter = {k: float(np.mean(v)) for k, v in hits.items()}
    covered = sum(sum(v) for v in hits.values())
    n = sum(len(v) for v in hits.values())
    lo, hi = binomial_band(n)
    print(f"coverage of {LEVEL:.0%} intervals: {covered}/{n} = {covered / n:.3f}, 99 % band "
          f"[{lo}, {hi}]; per parameter {per_parameter}")  # shown with pytest -s
    assert lo <= covered <= hi, (
        f"{covered} of {n} intervals cover the truth ({covered / n:.3f}); the 99 % band "
        f"for {LEVEL:.0%} is [{lo}, {hi}]; per parameter: {per_parameter}")
    return n


@pytest.mark.statistical
def test_central_90_percent_intervals_cover_the_truth(tmp_path):
    hits: dict[str, list[bool]] = {}
    for i, motor in enumerate(prior_motors(N_MOTORS)):
        session = load_session(simulate_session(plan_for(motor, seed=1000 + i),
                                                tmp_path / motor.name))
        model = build_model(session, closed_form(session))
        fit = fit_map(model)
        assert fit.ok, f"{motor.name}: {fit.message}"
        post = sample_posterior(model, fit, seed=i, max_steps=MAX_STEPS, progress=False)
        _record(hits, post, session.truth)
    assert _assert_covered(hits) == N_MOTORS * len(model.names)


N_RIGS = 12


@pytest.mark.statistical
def test_intervals_cover_the_truth_with_a_dead_time_and_a_voltage_drop_fitted():
    """The same check on a nuisance-rich structure, with data the fitted model did not
    generate: motors drawn over the range of small bench motors
    (:func:`~pmdc_bayes.simulate.cases.random_motor`), each on the independent LSODA
    bench simulator with a dead time (0.5–3 ms) and a brush/driver drop (0.3–1.5 V),
    two steps that start after a quiet tenth of the record and a steady table; fitted
    with a dead time per trace and a voltage drop.  Every fitted parameter's central
    90 % interval, the nuisances' included, is checked against the truth."""
    import dataclasses

    from pmdc_bayes.simulate.bench import bench_session
    from pmdc_bayes.simulate.cases import random_motor

    hits: dict[str, list[bool]] = {}
    rng = np.random.default_rng(20261124)
    for i in range(N_RIGS):
        motor, steps = random_motor(rng)
        dead, drop = float(rng.uniform(5e-4, 3e-3)), float(rng.uniform(0.3, 1.5))
        motor = dataclasses.replace(motor, dead_time=dead, voltage_drop=drop)
        steps = tuple(dataclasses.replace(s, t_step=round(0.1 * s.duration / s.dt) * s.dt)
                      for s in steps)
        session = bench_session(motor, steps, seed=i, steady_voltages=(4.0, 8.0, 12.0))
        session = dataclasses.replace(session, nuisances=("dead_time", "voltage_drop"))
        truth = dict(session.truth, Vdrop=drop,
                     **{f"dead_time_{s.name}": dead for s in steps})
        model = build_model(session, closed_form(session))
        fit = fit_map(model)
        assert fit.ok, f"rig {i}: {fit.message}"
        post = sample_posterior(model, fit, seed=i, max_steps=MAX_STEPS, progress=False)
        _record(hits, post, truth)
    assert set(hits) >= {"Vdrop", "dead_time_step_12v", "dead_time_step_6v", "K", "J"}
    assert _assert_covered(hits) == N_RIGS * len(model.names)


# -- fuzzed sessions of the kinds that were miscalibrated ---------------------------------
# Sessions from the fuzzer (the bench simulator, written and loaded) whose traces log no
# current, the current coming only from a steady table or one operating point; many of
# them log quantised speeds.  The central 90 % Laplace interval of every motor
# parameter is checked against the truth, pooled, against the 99 % binomial band; the
# same z-scores with every interval narrowed to 60 % of its width must fall outside it.
FUZZ_SEEDS = tuple(range(3000, 3008))
NARROWED = 0.6


@pytest.fixture(scope="module")
def fuzzed_fits(tmp_path_factory):
    from pmdc_bayes.inference.adequacy.verdict import assess
    from pmdc_bayes.inference.model.seed import fit_seed
    from pmdc_bayes.simulate.fuzz import fuzz_session

    root = tmp_path_factory.mktemp("fuzzed")
    out = []
    for seed in FUZZ_SEEDS:
        f = fuzz_session(seed, out=root / str(seed), trace_current=False,
                         steady=("table", "point")[seed % 2])
        session = load_session(f.path)
        cf = fit_seed(session)
        model = build_model(session, cf)
        fit = fit_map(model, seed=seed)
        assert fit.ok, f"fuzzed session {seed}: {fit.message}"
        out.append((f, model, fit, assess(model, fit, cf)))
    return out


def _laplace_z(model, fit, truth) -> list[float]:
    names = list(fit.names)
    t = np.asarray(model.theta({k: v for k, v in truth.items() if k in names}))
    sd = np.sqrt(np.diag(fit.cov_log))
    return [float((t[i] - fit.theta[i]) / sd[i]) for i, k in enumerate(names)
            if k in ("Ra", "La", "K", "B", "J", "Tc") and truth.get(k, 0.0) > 0]


def _covered(z, width: float = 1.0) -> tuple[int, int]:
    half = stats.norm.ppf(0.5 + LEVEL / 2) * width
    z = np.asarray(z)
    return int(np.sum(np.abs(z) <= half)), z.size


@pytest.mark.statistical
def test_laplace_intervals_cover_the_truth_on_fuzzed_speed_only_sessions(fuzzed_fits):
    z = [x for f, model, fit, _ in fuzzed_fits for x in _laplace_z(model, fit, f.truth)]
    covered, n = _covered(z)
    lo, hi = binomial_band(n)
    assert lo <= covered <= hi, (f"{covered}/{n} 90 % intervals cover the truth; the 99 % "
                                 f"band is [{lo}, {hi}]; z = {np.round(z, 2)}")
    narrowed, _ = _covered(z, NARROWED)  # the negative control: the band would catch it
    assert not lo <= narrowed <= hi, f"{narrowed}/{n} narrowed intervals still in band"


@pytest.mark.statistical
def test_few_false_alarms_on_fuzzed_in_class_sessions(fuzzed_fits):
    """At most the count that a 5 % session-level false-alarm rate exceeds with
    probability 1 % (Binomial(8, 0.05): 2 or fewer)."""
    flagged = [f.seed for f, _, _, a in fuzzed_fits if a.verdict == "inadequate"]
    allowed = int(stats.binom.ppf(0.99, len(fuzzed_fits), 0.05))
    assert len(flagged) <= allowed, f"in-class sessions {flagged} called inadequate"
