"""The public Python API: ``docs/python-api.md``'s example run as written, the
headline a result shows, and arguments refused before any work."""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import pytest

import pmdc_bayes
from pmdc_bayes._headline import headline_html, headline_rows, headline_text

DOC = Path(__file__).resolve().parents[2] / "docs" / "python-api.md"


def _blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.mark.compiles
def test_the_documented_example_runs(tmp_path, monkeypatch):
    """Every python block of docs/python-api.md, in order, in one namespace: a full fit
    of the demo, ArviZ on its posterior, python-control systems of posterior draws,
    a MAP-only fit and the run written to disk (the blocks assert what they show)."""
    blocks = _blocks(DOC.read_text(encoding="utf-8"))
    assert len(blocks) >= 4
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    with warnings.catch_warnings():
        # ArviZ's notice that some observations' Pareto k are high is for the reader of
        # the example to see; it is not an error of the example.
        warnings.filterwarnings("ignore", message="Estimated shape parameter of Pareto",
                                category=UserWarning)
        for code in blocks:
            exec(compile(code, str(DOC), "exec"), namespace)  # noqa: S102
    result = namespace["result"]
    assert "model adequate" in repr(result).splitlines()[0]
    assert "<table>" in result._repr_html_()
    systems = namespace["systems"]
    assert len(systems) == 50
    # each system is one posterior draw's, and the draws differ
    gains = namespace["gains"]
    assert gains.std() > 0
    assert (tmp_path / "demo-run" / "summary.json").is_file()
    with pytest.raises(pmdc_bayes.UsageError, match="already exists"):
        result.write(tmp_path / "demo-run")


def _summary(verdict="adequate", post=True):
    row = {"unit": "V*s/rad", "closed_form": 0.0620199, "map": 0.0619991,
           "map_sd": 3.2e-6}
    if post:
        row.update(mean=0.0619990, sd=3.3e-6)
    return {"session": {"name": "demo", "friction": "coulomb"},
            "adequacy": {"verdict": verdict}, "parameters": {"K": row}}


def test_the_headline_rounds_each_value_to_its_uncertainty():
    (row,) = headline_rows(_summary())
    assert row["estimate"] == "61.9990" and row["sd"] == "0.0033"
    assert row["unit"] == "×1e-3 V·s/rad" and row["closed_form"] == "62.0199"
    assert row["off"] == "+0.034 %, +6.3 sd" and row["source"] == "posterior mean"
    (row,) = headline_rows(_summary(post=False))
    assert row["estimate"] == "61.9991" and row["sd"] == "0.0032" and row["source"] == "MAP"


def test_the_headline_says_first_when_the_model_is_rejected():
    text = headline_text(_summary("inadequate"))
    assert text.splitlines()[0].endswith("MODEL INADEQUATE: the data reject the fitted "
                                         "model; the values below are conditional on it")
    assert "MODEL INADEQUATE" in headline_html(_summary("inadequate"))
    assert "<script" not in headline_html(dict(_summary(), session={"name": "<script>"}))


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"add": ["dead-time", "brush_wear"]}, "add: unknown non-ideality 'brush_wear'"),
    ({"friction": "sticky"}, "friction: 'sticky' is not"),
])
def test_fit_refuses_arguments_that_do_not_apply_before_any_work(kwargs, match):
    with pytest.raises(pmdc_bayes.UsageError, match=match):
        pmdc_bayes.fit("demo", **kwargs)


def test_a_missing_session_is_a_session_error(tmp_path):
    with pytest.raises(pmdc_bayes.SessionError):
        pmdc_bayes.fit(tmp_path / "nowhere", mcmc=False)


def test_a_session_shows_what_it_holds_not_its_arrays():
    from pmdc_bayes.io.bundled import session_path

    session = pmdc_bayes.load_session(session_path("bench"))
    text = repr(session)
    assert text.startswith("Session('bench'") and len(text) < 600
    assert "step_9v_braked (301 samples)" in text and "current_limit" in text
    assert "array" not in text and "[0." not in text
    assert repr(session.traces[0]) == ("Trace('step_12v', kind='step', 301 samples over "
                                       "0.15 s, logged=['position'])")


def test_the_cli_prints_the_headline_a_result_shows_then_the_details(capsys):
    from pmdc_bayes._console import print_fit
    from pmdc_bayes._headline import headline_text

    summary = dict(_summary(post=False), fit={"message": "converged"},
                   identifiability={"findings": []})
    summary["session"]["motor"] = "m"
    summary["adequacy"]["findings"] = []
    print_fit(summary, "run")
    out = capsys.readouterr().out
    assert headline_text(summary) in out  # the same lines as repr(result) and the report's
    assert "+0.034 %, +6.5 sd" in out  # the closed form's error, in % and in sd
    assert out.index(headline_text(summary)) < out.index("Details of the fit of m")


def test_a_session_changed_in_memory_is_fitted_but_not_written_as_a_run(tmp_path):
    """A run directory is read back from its copy of the session's files: a session
    whose data were changed in memory would be read back as something it was not."""
    import dataclasses

    import numpy as np

    from pmdc_bayes.api import _as_on_disk
    from pmdc_bayes.io.bundled import session_path
    from pmdc_bayes.run import RunResult

    session = pmdc_bayes.load_session(session_path("demo"))
    assert _as_on_disk(session)
    # what a run records apart (non-idealities, friction) may differ from the files
    assert _as_on_disk(dataclasses.replace(session, nuisances=("dead_time",),
                                           friction="viscous"))
    tr = session.traces[0]
    edited = dataclasses.replace(tr, speed=np.where(np.arange(tr.n) == 5, 0.0, tr.speed))
    assert not _as_on_disk(dataclasses.replace(session, traces=(edited,) + session.traces[1:]))
    assert not _as_on_disk(session.without_traces([tr.name]))
    result = RunResult({"session": {"changed_in_memory": True}}, session, session, None, None)
    with pytest.raises(pmdc_bayes.UsageError, match="changed in memory"):
        result.write(tmp_path / "run")
    assert not (tmp_path / "run").exists()


@pytest.mark.compiles
def test_fit_computes_in_64_bits_and_leaves_the_callers_jax_setting_as_it_was():
    """In a fresh interpreter, JAX starts in 32-bit mode (the test suite's conftest
    switches 64-bit on for itself, so this runs apart): the fit still computes in 64
    bits, gets the demo's K to its sd, and JAX is still in 32-bit mode afterwards."""
    import subprocess
    import sys

    code = """
import jax, numpy as np, pmdc_bayes
assert not jax.config.jax_enable_x64
r = pmdc_bayes.fit("demo", mcmc=False, progress=False)
assert not jax.config.jax_enable_x64 and jax.numpy.zeros(1).dtype == np.float32
assert np.asarray(r.fit.theta).dtype == np.float64 and np.asarray(r.fit.cov_log).dtype == np.float64
p = r.summary["parameters"]["K"]
assert r.summary["fit"]["status"] == "converged", r.summary["fit"]["message"]
assert abs(p["map"] - 0.062) < 3 * p["map_sd"] and p["map_sd"] < 1e-5, p
print("ok")
"""
    env = {k: v for k, v in os.environ.items() if not k.startswith("JAX_")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600, env=env)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]


@pytest.mark.compiles
def test_use_cache_keeps_compiled_programs_for_a_later_interpreter(tmp_path):
    """pmdc_bayes.use_cache(dir) from Python: the first interpreter's fit stores its
    programs there; a second interpreter's fit loads them instead of writing anew and
    finds the same MAP to the last digit; JAX's 64-bit mode is left off in both."""
    import json
    import subprocess
    import sys

    from conftest import write_session

    session = write_session(tmp_path / "sess")
    cache_dir = tmp_path / "programs"
    code = f"""
import json, jax, pmdc_bayes
from jax import export
exported, real = [], export.export
export.export = lambda *a, **k: exported.append(1) or real(*a, **k)  # count the exports
root = pmdc_bayes.use_cache({str(cache_dir)!r})
r = pmdc_bayes.fit({str(session)!r}, mcmc=False, search=False, progress=False)
assert not jax.config.jax_enable_x64
print(json.dumps({{"root": str(root), "K": r.values()["map"]["K"], "exported": len(exported)}}))
"""
    runs = []
    for _ in range(2):
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=600, env=dict(os.environ, PMDC_BAYES_CACHE="/nonexistent"))
        assert done.returncode == 0, done.stderr[-2000:]
        stored = {p: p.stat().st_mtime_ns for p in cache_dir.glob("export/*/*.jaxexport")}
        runs.append((json.loads(done.stdout.strip().splitlines()[-1]), stored))
    (first, stored1), (second, stored2) = runs
    assert first["root"] == str(cache_dir) and stored1  # programs were written there
    assert first["exported"] == len(stored1)
    # the second interpreter loaded them: it traced and exported none, rewrote none
    assert second["exported"] == 0 and stored2 == stored1
    assert second["K"] == first["K"]
