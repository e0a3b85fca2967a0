"""The headline (the CLI's lines, a result's repr and the report's first section) holds
the fit % of each trace, closed form against MAP, and what the data cannot determine,
also when they determine everything."""

from __future__ import annotations

from pmdc_bayes._console import print_fit
from pmdc_bayes._headline import (
    EVERYTHING_DETERMINED,
    UNCONVERGED,
    determinability,
    fit_table,
    headline_html,
    headline_rows,
    headline_text,
    pi_loop_text,
)

CHANNELS = {  # as summary.json holds them: by their text, each row naming its trace and signal
    "step_12v97: speed": {"trace": "step_12v97", "signal": "speed",
                          "fit_percent_closed_form": 96.44, "fit_percent_map": 99.21},
    "step_12v97: current": {"trace": "step_12v97", "signal": "current",
                            "fit_percent_closed_form": 95.7, "fit_percent_map": 97.5},
    "coast: speed": {"trace": "coast", "signal": "speed", "fit_percent_closed_form": None,
                     "fit_percent_map": 91.04},
    "steady: speed": {"trace": "steady", "signal": "speed",
                      "rms_miss_fraction": 0.002},  # a steady channel: no fit %
}


def _summary(findings=()):
    return {"session": {"name": "demo", "friction": "coulomb", "motor": "m"},
            "adequacy": {"verdict": "adequate", "findings": [], "channels": CHANNELS},
            "fit": {"message": "converged"},
            "identifiability": {"findings": list(findings)},
            "parameters": {"K": {"unit": "V*s/rad", "closed_form": 0.0620199,
                                 "map": 0.0619991, "map_sd": 3.2e-6}}}


def test_the_fit_table_has_one_row_per_trace_closed_form_beside_map():
    header, rows = fit_table(_summary())
    assert header == ("trace", "speed: closed form", "speed: MAP", "current: closed form",
                      "current: MAP")
    assert rows == [("step_12v97", "96.4", "99.2", "95.7", "97.5"),
                    ("coast", "—", "91.0", "", "")]
    # a trace named with ": " is the row's name whole, its signal the column's
    named = {"run: 2: speed": {"trace": "run: 2", "signal": "speed",
                               "fit_percent_closed_form": 90.0, "fit_percent_map": 99.0}}
    summary = _summary()
    summary["adequacy"]["channels"] = named
    assert fit_table(summary) == (("trace", "speed: closed form", "speed: MAP"),
                                  [("run: 2", "90.0", "99.0")])


def test_draws_that_failed_their_gates_give_way_to_the_map_and_its_laplace_sd():
    # a sampler stuck in a corner of a ridge: its sd a tenth of the Laplace sd's
    summary = _summary()
    summary["parameters"]["K"].update(mean=0.0619801, sd=3.1e-7)
    summary["diagnostics"] = {"gates_passed": True}
    row, = headline_rows(summary)
    assert (row["estimate"], row["sd"], row["source"]) == ("61.98010", "0.00031",
                                                          "posterior mean")
    summary["diagnostics"]["gates_passed"] = False
    row, = headline_rows(summary)
    assert (row["estimate"], row["sd"], row["source"]) == ("61.9991", "0.0032",
                                                          UNCONVERGED)
    assert f"(values: {UNCONVERGED})" in headline_text(summary)
    del summary["parameters"]["K"]["mean"]  # nothing sampled: the MAP, said plainly
    assert headline_rows(summary)[0]["source"] == "MAP"


def test_what_the_data_cannot_determine_is_said_also_when_nothing():
    assert determinability(_summary()) == [EVERYTHING_DETERMINED]
    weak = "B and J are 0.97 correlated: a load step or a coast-down would separate them."
    assert determinability(_summary([weak])) == [weak]
    assert determinability({"parameters": {}}) == []  # a run written before the analysis


def test_repr_and_notebook_show_the_fit_and_the_determinability():
    text = headline_text(_summary())
    assert "  step_12v97: speed 96.4 → 99.2, current 95.7 → 97.5" in text
    assert f"- {EVERYTHING_DETERMINED}" in text
    html = headline_html(_summary())
    assert "<th>speed: MAP</th>" in html and EVERYTHING_DETERMINED in html


def test_the_cli_prints_the_fit_per_trace_and_the_determinability(capsys):
    print_fit(_summary(), "run")
    out = capsys.readouterr().out
    assert "Fit % per trace (closed form → MAP):\n  step_12v97: speed 96.4 → 99.2" in out
    assert "  coast: speed — → 91.0\n" in out
    assert f"- {EVERYTHING_DETERMINED}" in out


def _loop(pm, gm, delay=0.002, n=1000):
    rec = {"kp": 0.5, "ki": 5.0, "delay": delay,
           "at_estimate": {"phase_margin_deg": pm[1], "gain_margin_db": gm[1]}}
    if n:
        rec["over_draws"] = {"n": n, "phase_margin_deg": list(pm), "gain_margin_db": list(gm),
                             "share_pm_below_45": 0.0}
    return rec


def test_pi_margins_are_written_to_the_precision_of_their_spread():
    # the demo's margins vary in the second decimal: no "[46.3°, 46.3°]"
    text = pi_loop_text(_loop((46.28387, 46.29335, 46.30310), (40.22134, 40.22720, 40.23272)))
    assert text == ("PI loop kp=0.5, ki=5, delay 2 ms: phase margin 46.293°, gain margin "
                    "40.227 dB; over 1000 posterior draws, 94 % of phase margins in "
                    "[46.284°, 46.303°], of gain margins in [40.221 dB, 40.233 dB]; 0 % of "
                    "draws under 45°")
    wide = pi_loop_text(_loop((31.2, 44.87, 58.3), (None, None, None), delay=0.0))
    assert "phase margin 45°" in wide and "[31°, 58°]" in wide
    assert "gain margin ∞" in wide and "[∞, ∞]" in wide
    alone = pi_loop_text(_loop((None, 46.293352, None), (None, 40.2272, None), n=0))
    assert alone == ("PI loop kp=0.5, ki=5, delay 2 ms: phase margin 46.2934°, gain margin "
                     "40.2272 dB (no posterior draws: no spread)")
