"""The uncertainty report: every figure embedded, every table present, the paper's
disagreements stated in numbers, hold-out errors per method, controller export."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest

from pmdc_bayes import write_report
from pmdc_bayes.cli import main
from pmdc_bayes.io.bundled import bundled_session_dir
from pmdc_bayes.pipeline import FitOptions, run_fit
from pmdc_bayes.report import to_control
from pmdc_bayes.report.tables import TABLE_TITLES

pytestmark = pytest.mark.compiles

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
IMG = re.compile(r'<img alt="[^"]*" src="data:image/png;base64,([A-Za-z0-9+/=]*)">')
ALWAYS = ("parameters", "derived", "diagnostics", "transfer", "comparison")


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "demo"
    run_fit(bundled_session_dir("demo"), FitOptions(mcmc=True, seed=0, pi=(0.5, 5.0, 0.002)),
            out=out)
    return out


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "paper"
    run_fit(bundled_session_dir("paper"),
            FitOptions(mcmc=True, seed=0, allow_inadequate=True, search=False), out=out)
    return out


@pytest.fixture(scope="module")
def holdout_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "holdout"
    run_fit(bundled_session_dir("demo"), FitOptions(mcmc=True, seed=0, holdout=("load_change",)),
            out=out)
    return out


def _images(html: str) -> list[bytes]:
    return [base64.b64decode(m, validate=True) for m in IMG.findall(html)]


def _table_rows(md: str, title: str) -> list[list[str]]:
    block = md.split(f"### {title}\n", 1)[1].strip("\n").split("\n\n", 1)[0]
    return [[c.strip() for c in line.strip("|").split("|")] for line in block.splitlines()[2:]]


def test_every_figure_of_the_report_goes_to_a_worker(demo_run, monkeypatch):
    """No figure of a full report falls back to this process (an artist that does not
    pickle would, silently, and cost the report its parallel drawing)."""
    from pmdc_bayes.readback import read_run
    from pmdc_bayes.report._context import context_from_result
    from pmdc_bayes.report._doc import Figure
    from pmdc_bayes.report._render import WORKERS_ENV
    from pmdc_bayes.report.build import build_sections

    monkeypatch.setenv(WORKERS_ENV, "2")
    sections, _ = build_sections(context_from_result(read_run(demo_run), demo_run))
    figures = [b for sec in sections for b in sec.blocks if isinstance(b, Figure)]
    assert len(figures) >= 8
    assert [f.name for f in figures if not f.png.in_worker] == []
    assert all(f.png.png()[:8] == PNG_MAGIC for f in figures)


def test_demo_report_files_figures_and_tables(demo_run):
    html = (demo_run / "report.html").read_text(encoding="utf-8")
    assert "http://" not in html and "https://" not in html  # nothing fetched to view it
    assert html.count("<img") == len(_images(html)) > 0  # every <img> is an embedded PNG
    for png in _images(html):
        assert png.startswith(PNG_MAGIC) and len(png) > 1024
    figures = sorted(p.stem for p in (demo_run / "figures").glob("*.png"))
    assert len(figures) == html.count("<img")
    for name in ("forest", "corner", "steady", "chains", "ranks", "response", "trace_step_12v97",
                 "trace_load_change", "trace_current_capture"):
        assert name in figures
        assert f'id="fig-{name}"' in html
    md = (demo_run / "report.md").read_text(encoding="utf-8")
    for key in ALWAYS + ("rms",):
        assert f"<h3>{TABLE_TITLES[key]}</h3>" in html
        assert f"### {TABLE_TITLES[key]}" in md
    for name in figures:
        assert f"(figures/{name}.png)" in md
    assert "posterior mean ± sd" in html and "No posterior was sampled" not in html
    # --pi: the loop's margins at the estimate and over the posterior draws
    loop = json.loads((demo_run / "summary.json").read_text())["pi_loop"]
    assert loop["over_draws"]["n"] == 1000 and loop["at_estimate"]["gain_margin_db"] > 0
    assert "PI loop kp=0.5, ki=5, delay 2 ms: phase margin" in html
    summary = json.loads((demo_run / "summary.json").read_text())
    assert summary["diagnostics"]["wall_s"]["report"] > 0.0


def test_the_report_opens_with_the_answer(demo_run):
    """Before any detail: the verdict, the parameters rounded to their uncertainty with
    the closed form's error, and the fit % per channel."""
    md = (demo_run / "report.md").read_text(encoding="utf-8")
    first = md.split("\n## ", 2)[1]
    assert first.startswith("At a glance\n")
    assert "Model adequate: the data do not reject the fitted model." in first
    rows = {r[0]: r for r in _table_rows(md, "Parameters at a glance")}
    assert set(rows) == {"Ra", "La", "K", "B", "J", "Tc"}
    b = rows["B"]  # the closed form's B is the paper method's largest error on the demo
    assert b[3] == "×1e-6 N·m·s/rad" and float(b[1]) == pytest.approx(45.0, abs=0.5)
    off_pct, off_sd = re.match(r"\+(\d+) %, \+(\d+) sd", b[5]).groups()
    assert 15 < int(off_pct) < 35 and int(off_sd) > 50
    fits = _table_rows(md, "Fit % per trace")
    assert {r[0] for r in fits} == {"step_12v97", "step_6v49", "load_change", "current_capture"}
    assert all(float(r[2]) > 85 and float(r[4]) > 85 for r in fits)  # speed and current, MAP
    assert "- The data determine every parameter" in first


def test_the_first_screen_in_a_browser_shows_the_verdict_and_the_headline(demo_run, tmp_path):
    """As laid out by headless Chromium in a 1280×900 window (skipped without one)."""
    check = _browser_check()
    if check.browser() is None:
        pytest.skip("no Chromium installed (apt-get install chromium)")
    m = check.measure(demo_run / "report.html", screenshot=tmp_path / "first.png")
    assert check.verdict(m) == []
    assert m["table_rows"][1:] == ["Ra", "La", "K", "B", "J", "Tc"]
    # the whole of 'At a glance' (fit % per trace, what the data cannot determine too)
    # lies within the 1280×900 window
    assert m["section_bottom"] <= check.HEIGHT
    assert (tmp_path / "first.png").read_bytes().startswith(PNG_MAGIC)


def _browser_check():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "check_report_in_browser.py"
    spec = importlib.util.spec_from_file_location("check_report_in_browser", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_demo_report_explains_closed_form_bias(demo_run):
    md = (demo_run / "report.md").read_text(encoding="utf-8")
    rows = {r[0]: r for r in _table_rows(md, TABLE_TITLES["comparison"])}
    assert set(rows) == {"Ra", "La", "K", "B", "J", "Tc"}
    assert "Tc/ω" in md  # Coulomb friction lumped into B at the operating point
    assert "La is neglected in the first-order τ" in md
    assert "quantised by the sampling interval 10 ms" in md
    assert "started from rest" in md


def test_report_command_regenerates_and_rejects_other_dirs(demo_run, tmp_path, capsys):
    html = demo_run / "report.html"
    html.unlink()
    assert main(["report", str(demo_run)]) == 0
    assert html.is_file() and html.stat().st_size > 10_000
    capsys.readouterr()
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "summary.json" in err[0]


def test_paper_report_states_the_published_disagreements(paper_run):
    md = (paper_run / "report.md").read_text(encoding="utf-8")
    html = (paper_run / "report.html").read_text(encoding="utf-8")
    line = next(x for x in md.splitlines() if "Table I does not reproduce" in x)
    assert "G = K/(B·Ra + K²) = 14.3 rad/s per V" in line
    assert "simulated column rises at 13.3 rad/s per V" in line
    line = next(x for x in md.splitlines() if "torque sensitivity is" in x and "Table I" in x)
    assert "2.3 times what Table I predicts" in line
    assert "The session has no traces" in md
    for key in ALWAYS:
        assert f"<h3>{TABLE_TITLES[key]}</h3>" in html
    assert all(p.startswith(PNG_MAGIC) and len(p) > 1024 for p in _images(html))


def test_holdout_table_has_every_method(holdout_run):
    md = (holdout_run / "report.md").read_text(encoding="utf-8")
    header = md.split(f"### {TABLE_TITLES['holdout']}\n\n", 1)[1].splitlines()[0]
    for col in ("RMS closed form", "RMS MAP", "RMS posterior predictive"):
        assert col in header
    rows = _table_rows(md, TABLE_TITLES["holdout"])
    assert {r[0] for r in rows} == {"load_change"}
    assert {r[1] for r in rows} == {"speed (rad/s)", "current (A)"}
    for r in rows:  # the fitted parameters predict the unseen trace to the noise level
        noise, cf, map_, pp = (float(x) for x in r[2:6])
        assert map_ < 1.2 * noise and pp < 1.2 * noise and cf > map_
    assert "figures/heldout_load_change.png" in md
    assert "load_change" not in {r[0] for r in _table_rows(md, TABLE_TITLES["rms"])}


def test_controller_export_matches_posterior_mean(demo_run):
    model = json.loads((demo_run / "controller.json").read_text())
    summary = json.loads((demo_run / "summary.json").read_text())
    n = len(model["names"])
    assert np.shape(model["A"]) == (2, 2) and np.shape(model["B"]) == (2, 2)
    assert np.shape(model["C"]) == (1, 2) and np.shape(model["D"]) == (1, 2)
    cov = np.asarray(model["covariance"])
    assert cov.shape == (n, n) and np.allclose(cov, cov.T, rtol=0, atol=0)
    p = model["parameters"]
    for k, name in enumerate(model["names"]):
        assert p[name] == pytest.approx(summary["parameters"][name]["mean"], rel=1e-6)
        assert np.sqrt(cov[k, k]) == pytest.approx(summary["parameters"][name]["sd"], rel=1e-3)
    pytest.importorskip("control")
    ss, tf = to_control(model)
    g = p["K"] / (p["B"] * p["Ra"] + p["K"] ** 2)
    assert float(np.real(tf.dcgain())) == pytest.approx(g, rel=1e-9)
    assert float(np.real(ss.dcgain()[0, 1])) == pytest.approx(g, rel=1e-9)


def test_no_posterior_report_says_so(tmp_path):
    out = tmp_path / "nomcmc"
    run_fit(bundled_session_dir("paper"), FitOptions(mcmc=False, search=False), out=out)
    assert not (out / "posterior.nc").exists()
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "No posterior was sampled" in html and "chains" not in {
        p.stem for p in (out / "figures").glob("*.png")}
    paths = write_report(out)
    assert paths["html"] == out / "report.html"


def test_report_quiet_prints_nothing_and_verbose_a_line_per_stage(tmp_path, capsys):
    out = tmp_path / "nomcmc"
    run_fit(bundled_session_dir("paper"),
            FitOptions(mcmc=False, allow_inadequate=True, search=False), out=out)
    capsys.readouterr()
    assert main(["report", str(out), "--quiet", "--no-cache"]) == 0
    assert capsys.readouterr() == ("", "")
    assert main(["report", str(out), "-v", "--no-cache"]) == 0
    text = capsys.readouterr()
    assert text.out.startswith("Wrote ")
    stages = text.err.splitlines()
    assert len(stages) == 3 and all(line.startswith("pmdc-bayes: [") for line in stages)
    assert "its copy of the session" in stages[0]
    with pytest.raises(SystemExit) as exc:  # one or the other, as for fit
        main(["report", str(out), "-q", "-v"])
    assert exc.value.code == 2


@pytest.mark.compiles
def test_the_report_leads_with_the_verdict(demo_run, paper_run):
    """Before any number: 'adequate' on the demo; on the paper (viscous, steady line
    off zero) the rejection, its reason and the conditional label."""
    for run, word in ((demo_run, "adequate"), (paper_run, "INADEQUATE")):
        md = (run / "report.md").read_text(encoding="utf-8")
        body = md.split("\n## ", 1)[1]
        first = body.split("\n## ", 1)[0]
        assert word in first, first[:400]
        assert md.index(word) < md.find("|")  # before the first table
    paper = (paper_run / "report.md").read_text(encoding="utf-8")
    assert "conditional" in paper.lower()
    assert "voltage drop" in paper
