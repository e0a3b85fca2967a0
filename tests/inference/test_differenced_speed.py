"""A speed logged as an encoder's counts differenced over each sample interval (the
fuzzer's "encoder speed" rig): read as a speed its errors are anti-correlated and the
adequacy checks reject it; with the encoder's counts_per_rev declared the trace is read
as the counted angle and fitted as the rig ran."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.fit.undetermined import identifiability
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
from pmdc_bayes.simulate.bench import BenchMotor, StepSpec, bench_session
from pmdc_bayes.simulate.fuzz import fuzz_session


def _declare_counts(path, counts_per_rev):
    """``session.toml`` with ``counts_per_rev`` on every driven trace that logs a speed."""
    lines, table, kind = [], None, ""
    for line in (path / "session.toml").read_text().splitlines():
        lines.append(line)
        table = line if line.startswith("[[") else table
        kind = line if line.startswith("kind = ") else kind
        if (table == "[[trace]]" and "coast-down" not in kind
                and line.startswith("columns = ") and "speed = " in line):
            lines.append(f"counts_per_rev = {counts_per_rev}")
    (path / "session.toml").write_text("\n".join(lines) + "\n")


@pytest.mark.compiles
@pytest.mark.parametrize("seed", [3, 12])
def test_a_speed_differenced_from_counts_fits_once_its_counts_per_rev_is_declared(tmp_path,
                                                                                  seed):
    """Seed 3 (a load change logged in rpm with its current, two steps from rest) and
    seed 12 (Coulomb friction): as logged, the fit is rejected; declared, every driven
    trace is read as a counted angle, the model is adequate and every motor parameter
    lies inside its 99 % Laplace interval."""
    fz = fuzz_session(seed, misspecified="encoder speed", out=tmp_path / "s")
    verdicts = []
    for declared in (False, True):
        if declared:
            _declare_counts(fz.path, 64)
        session = load_session(fz.path)
        cf = fit_seed(session)
        model = build_model(session, cf)
        fit = fit_map(model, seed=seed)
        assert fit.ok, fit.message
        verdicts.append(str(assess(model, fit, cf).verdict))
    assert verdicts == ["inadequate", "adequate"]
    assert all(not tr.speed_logged and tr.encoder_step > 0 for tr in session.traces)
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in fz.truth.items() if k in names}))
    for k in ("Ra", "La", "K", "B", "J"):
        i = names.index(k)
        assert abs(theta[i] - fit.theta[i]) < 2.576 * np.sqrt(fit.cov_log[i, i]), k


def _loop_session(root, seed, *, per_rev=360, period=0.010, work=8e-4, tc=1e-3):
    """The bench simulator's motor (Coulomb friction ``tc``, no current logged) stepped
    0 → 12 V at 200 ms, logged as an Arduino loop logs an encoder: each pass ``period``
    plus up to ``work``, the counts (``per_rev`` a turn) over the pass's own ``micros()``
    interval written as a speed, the row stamped with ``millis()``; the true
    parameters."""
    motor = BenchMotor(Ra=2.0, La=1.5e-3, K=0.02, B=2e-6, J=5e-6, Tc=tc, speed_noise=0.0)
    fine = bench_session(motor, [StepSpec("step", 12.0, 1.2, 1e-5, t_step=0.2,
                                          log_current=False)], seed=seed).traces[0]
    angle = np.r_[0.0, np.cumsum(0.5 * (fine.speed[1:] + fine.speed[:-1]) * np.diff(fine.time))]
    rng = np.random.default_rng(seed)
    t = np.r_[0.0, np.cumsum(period + rng.uniform(0.0, work, int(1.2 / period)))]
    t = t[t < fine.time[-1]]
    q = 2 * np.pi / per_rev
    counts = np.floor(np.interp(t, fine.time, angle) / q + 1e-9)
    speed = np.r_[0.0, np.diff(counts) * q / np.diff(t)]
    root.mkdir()
    (root / "step.csv").write_text("ms,w\n" + "".join(
        f"{int(a)},{b:.4f}\n" for a, b in zip(np.floor(t * 1e3), speed, strict=True)))
    friction = 'friction = "coulomb"\n' if tc else ""
    (root / "session.toml").write_text(
        f'[motor]\nname = "loop"\n{friction}\n[bench.Ra]\nvalue = 2.0\n'
        'sd = 0.06\nunit = "ohm"\n\n[[trace]]\nname = "step"\nfile = "step.csv"\n'
        'kind = "step"\ncolumns = { time = "ms", speed = "w" }\n'
        f'units = {{ time = "ms", speed = "rad/s" }}\ncounts_per_rev = {per_rev}\n'
        'voltage = [[0, 0.0], [200, 12.0]]\n')
    return {k: getattr(motor, k) for k in ("Ra", "La", "K", "B", "J", "Tc")}


@pytest.mark.compiles
def test_counts_over_a_loops_own_interval_stamped_in_milliseconds_fit_as_the_rig_ran(
        tmp_path):
    """A speed whose counts are whole only over intervals the log does not hold (the
    loop's ``micros()``, stamped by ``millis()``) is read as the angle it integrates over
    the logged intervals: the ideal model, which the rig is, is adequate and every motor
    parameter lies inside its 99 % Laplace interval."""
    truth = _loop_session(tmp_path / "s", seed=5)
    session = load_session(tmp_path / "s")
    assert not session.traces[0].speed_logged and session.traces[0].encoder_step > 0
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=5)
    assert fit.ok, fit.message
    assert str(assess(model, fit, cf).verdict) == "adequate"
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in truth.items() if k in names}))
    for k in ("Ra", "La", "K", "B", "J", "Tc"):
        i = names.index(k)
        assert abs(theta[i] - fit.theta[i]) < 2.576 * np.sqrt(fit.cov_log[i, i]), k


@pytest.mark.compiles
def test_la_read_through_millisecond_stamps_is_given_the_stamps_error(tmp_path):
    """The loop at 5 ms a pass and up to 0.4 ms of work, 1000 counts a turn, viscous
    friction only: the rise places La (τe 0.75 ms) to far better than the stamps' tick
    of 1 ms allows, so the fit's sd alone does not hold the truth.  The findings say La
    may be off by up to Ra·tick beyond its sd, and that bound does hold it; K, B and J,
    on the mechanical time scale, lie inside their 99 % intervals."""
    truth = _loop_session(tmp_path / "s", seed=5, per_rev=1000, period=0.005, work=4e-4,
                          tc=0.0)
    session = load_session(tmp_path / "s")
    cf = fit_seed(session)
    model = build_model(session, cf)
    fit = fit_map(model, seed=5)
    assert fit.ok, fit.message
    ident = identifiability(model, fit)
    assert ident["clock_tick_s"] == pytest.approx(1e-3)
    (said,) = [f for f in ident["findings"] if "stamped to 1 ms" in f]
    bound = 1e-3 * fit.values["Ra"]
    assert abs(fit.values["La"] - truth["La"]) < bound + 2.576 * fit.sd["La"]
    names = list(fit.names)
    theta = np.asarray(model.theta({k: v for k, v in truth.items() if k in names}))
    for k in ("K", "B", "J"):
        i = names.index(k)
        assert abs(theta[i] - fit.theta[i]) < 2.576 * np.sqrt(fit.cov_log[i, i]), k
