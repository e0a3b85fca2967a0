"""One bad reading in a trace (a logger's 65535, a dropped byte, a spike): the outlying
reading check finds it and names it, holds its false-alarm rate on noise of every kind
the likelihood admits, leaves step edges and slow misfits to the checks made for them,
and a whole fit on a bench-simulator session with a glitch says first that the data,
not the model, are at fault."""


import numpy as np
import pytest
from scipy.signal import lfilter

from pmdc_bayes.inference.adequacy.glitches import outlier_test
from pmdc_bayes.inference.adequacy.trace_checks import MATERIAL_FRACTION
from pmdc_bayes.io.channel import ChannelId
from pmdc_bayes.simulate.fuzz import fuzz_session

N = 1500
T = np.arange(N) * 1e-3
SIGNAL = 100.0 * (1.0 - np.exp(-T / 0.2))  # a step response, span about 100


def _p(y, yhat=SIGNAL, u=None, **kw):
    return outlier_test(ChannelId("tr", "speed"), y - yhat, float(np.ptp(y)), u=u, time=T, **kw)


@pytest.mark.parametrize("rho", [0.0, 0.8], ids=["white", "AR(1) 0.8"])
def test_noise_alone_is_flagged_at_its_stated_rate(rho):
    rng = np.random.default_rng(11)
    p = []
    for _ in range(300):
        e = lfilter([1.0], [1.0, -rho], rng.standard_normal(N)) * np.sqrt(1 - rho**2) * 0.3
        p.append(_p(SIGNAL + e).p_value)
    p = np.asarray(p)
    # Bonferroni's bound over the readings: at most the nominal share, not far below it
    assert np.mean(p < 0.01) <= 0.025
    assert np.mean(p < 0.2) >= 0.05


def test_a_glitch_is_found_and_placed():
    rng = np.random.default_rng(3)
    y = SIGNAL + 0.3 * rng.standard_normal(N)
    y[700] = 65535.0
    t = _p(y, unit="rad/s")
    assert t.p_value < 1e-12 and t.material
    assert "t = 0.7 s" in t.finding.message and "rad/s" in t.finding.message
    assert t.finding.check == "outlying reading"
    # a spike of twelve noise sd on a quieter sensor is as rare, but below the material
    # share of the span: it does not fail the model
    y = SIGNAL + 0.05 * rng.standard_normal(N)
    y[400] += 12 * 0.05
    t = _p(y)
    assert t.p_value < 1e-6
    assert not t.material and 12 * 0.05 < MATERIAL_FRACTION * np.ptp(y)


@pytest.mark.parametrize("length", [2, 3])
def test_a_short_run_of_bad_readings_is_one_glitch(length):
    """Two or three readings lost together (a dropped packet written as zeros, a
    sentinel held over a few samples): found, placed from its first to its last reading,
    and material, where the one-reading contrast sees only its edges."""
    rng = np.random.default_rng(4)
    y = SIGNAL + 0.3 * rng.standard_normal(N)
    y[900:900 + length] = 0.0
    t = _p(y, unit="rad/s")
    assert t.p_value < 1e-12 and t.material
    text = t.finding.message
    assert f"the {length} readings from t = 0.9 s to {0.9 + (length - 1) * 1e-3:g} s" in text
    assert "leave those cells empty" in text
    # the same run with a sensor so quiet that its noise never moves the readings
    flat = np.full(N, 57.0)
    flat[900:900 + length] = 65535.0
    assert outlier_test(ChannelId("tr", "speed"), flat - 57.0, 200.0, time=T).material


def test_a_run_longer_than_a_glitch_or_a_late_start_is_not_one():
    """Five readings off together is a stretch the model misses, not a glitch; nor is a
    response that starts a few samples after its input's step."""
    rng = np.random.default_rng(6)
    y = SIGNAL + 0.3 * rng.standard_normal(N)
    y[900:905] -= 30.0
    assert not _p(y).material
    u = np.where(T >= 0.5, 12.0, 6.0)
    late = SIGNAL.copy()
    late[500:503] -= 20.0
    assert not _p(y, late, u=u).material


def test_a_step_edge_and_a_slow_misfit_are_not_glitches():
    rng = np.random.default_rng(5)
    u = np.where(T >= 0.5, 12.0, 6.0)
    y = SIGNAL + 0.3 * rng.standard_normal(N)
    yhat = SIGNAL.copy()
    yhat[500] += 20.0  # the model's switch a sample early: one reading far off, at the edge
    assert _p(y, yhat, u=u).p_value > 0.01
    assert _p(y, yhat).p_value < 1e-6  # the same residual away from any step is one
    slow = 5.0 * np.sin(2 * np.pi * T / 0.4)  # a misfit 5 % of the span, smooth
    assert _p(y + slow, u=u).p_value > 0.01
    # a response that starts three samples after the step (a dead time the model lacks):
    # the residual steps there, away from the edge; the statistic sees it, but it is no
    # lone bad reading, so it does not fail the data
    late = yhat.copy()
    late[500:503] = y[500:503] - 20.0
    t = _p(y, late, u=u)
    assert t.p_value < 1e-6 and not t.material


def test_a_quantised_reading_is_not_a_glitch():
    rng = np.random.default_rng(8)
    q = 2.0  # a quantum well above the noise: the readings flick between levels
    y = q * np.round((SIGNAL + 0.2 * rng.standard_normal(N)) / q)
    assert _p(y).p_value > 0.01
    # noise about the quantum's size dithers it: the second differences sit on the
    # lattice (a median of them is a whole number of quanta, no yardstick), yet their
    # mean square is the noise's and the rate holds
    p = [_p(0.24 * np.round((SIGNAL + 0.15 * rng.standard_normal(N)) / 0.24)).p_value
         for _ in range(200)]
    assert np.mean(np.asarray(p) < 0.01) <= 0.03
    # a steady level read by a quantiser its noise seldom moves: one reading flickers a
    # quantum down, which the quiet readings around it make a rare jump, but it is the
    # quantiser's resolution, no bad reading
    y = np.full(N, 57.256)
    y[700] -= 0.6736
    t = outlier_test(ChannelId("tr", "speed"), y - 57.25, 200.0, time=T, quantum=0.6736)
    assert t.p_value < 1e-6 and not t.material
    y[700] = 65535.0
    assert outlier_test(ChannelId("tr", "speed"), y - 57.25, 200.0, time=T, quantum=0.6736).material


def test_a_bad_reading_alone_is_the_data_s_fault():
    """A bad reading alone is the data's fault; beside a systematic misfit it may be the
    model's (a model far off the data leaves single readings far off too: a current
    limit's plateau at a trace's start), and the verdict stays the model's."""
    from pmdc_bayes.inference.adequacy.findings import Check, Severity
    from pmdc_bayes.inference.adequacy.verdict import Adequacy, Finding, Verdict

    where, bad = ChannelId("tr", "speed"), Verdict.INADEQUATE
    glitch = Finding(Check.OUTLYING_READING, where, Severity.FAIL, "+6.6e4 rad/s", "a glitch")
    misfit = Finding(Check.SYSTEMATIC_MISFIT, where, Severity.FAIL, "3 %", "a misfit")
    assert Adequacy(bad, (glitch,)).faulty_data
    assert not Adequacy(bad, (glitch, misfit)).faulty_data
    assert not Adequacy(bad, (misfit,)).faulty_data
    warned = Finding(Check.OUTLYING_READING, where, Severity.WARN, "", "")
    assert not Adequacy(bad, (misfit, warned)).faulty_data
    assert not Adequacy(Verdict.ADEQUATE).faulty_data


def _fit_with_cell(pmdc, root, text, out):
    """``pmdc-bayes fit`` of the session at ``root`` with the speed two thirds down its
    first trace written as ``text``."""
    csv = next(root.glob("tr0_*.csv"))
    lines = csv.read_text().splitlines()
    col = lines[0].split(",").index("speed")
    k = len(lines) * 2 // 3
    row = lines[k].split(",")
    row[col] = text
    lines[k] = ",".join(row)
    csv.write_text("\n".join(lines) + "\n")
    return pmdc("fit", root, "--out", out, "--no-mcmc", timeout=900)


@pytest.mark.compiles
def test_a_session_with_a_glitch_is_refused_for_its_data_with_no_search(tmp_path, pmdc):
    fuzz_session(5, out=tmp_path / "s")
    run = _fit_with_cell(pmdc, tmp_path / "s", "65535", tmp_path / "out")
    assert run.returncode == 3, run.stdout + run.stderr
    first = run.stdout.splitlines()[1]
    assert "outlying reading" in first and "leave that cell empty" in first
    assert "Model search from ideal: 1 fit " in run.stdout
    assert "likely:" not in run.stderr
    # the reading left empty, as the message says: the same session fits
    run = _fit_with_cell(pmdc, tmp_path / "s", "", tmp_path / "out2")
    assert run.returncode == 0, run.stdout + run.stderr
