"""A finished run's exit code and errors, the same for `fit` and for a lot's motor."""

from __future__ import annotations

from pmdc_bayes._console import run_outcome
from pmdc_bayes._errors import EXIT_FAILED, EXIT_INADEQUATE


def _summary(converged=True, fail=False, gates=True, proposals=True):
    findings = [{"severity": "warn", "where": "a", "message": "w", "check": "c"}]
    if fail:
        findings.append({"severity": "fail", "where": "step: speed", "check": "c",
                         "message": "the model misses the data"})
    return {"fit": {"status": "converged" if converged else "max_steps",
                    "message": "stopped at its step limit"},
            "adequacy": {"findings": findings, "diagnosis": ["add a dead time"],
                         "proposals": [{"nuisance": "dead_time", "trace": None}] * proposals},
            "diagnostics": {"gates_passed": gates, "gates": {}},
            "parameters": {"K": {}}}


def test_a_clean_run_exits_0_with_nothing_to_say():
    assert run_outcome(_summary()) == (0, [])


def test_an_inadequate_model_exits_3_and_ends_the_run_before_the_gates():
    status, errors = run_outcome(_summary(fail=True, gates=False))
    assert status == EXIT_INADEQUATE
    assert len(errors) == 1
    assert errors[0].startswith("model inadequate: step: speed: the model misses the data")
    assert "likely: add a dead time" in errors[0] and "--allow-inadequate" in errors[0]
    assert "--allow-inadequate" not in run_outcome(_summary(fail=True), advice=False)[1][0]
    # a diagnosis that proposes nothing (a bad reading, no known pattern) is no "likely"
    assert "likely" not in run_outcome(_summary(fail=True, proposals=False))[1][0]


def test_a_fit_that_did_not_converge_is_told_first_and_wins_the_exit_code():
    status, errors = run_outcome(_summary(converged=False, fail=True))
    assert status == EXIT_FAILED
    assert errors[0].startswith("the fit did not converge")
    assert errors[1].startswith("model inadequate")


def test_allowing_goes_on_to_the_gates_and_allowing_those_exits_0():
    status, errors = run_outcome(_summary(fail=True, gates=False), allow_inadequate=True)
    assert status == EXIT_FAILED
    assert errors[-1].startswith("the posterior failed its convergence gates")
    assert run_outcome(_summary(gates=False), allow_unconverged=True) == (0, [])
