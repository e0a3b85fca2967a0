"""Every table and figure label of the report shows a value rounded to its uncertainty
(two significant digits of the sd, the value to match, one scale per row given before
the unit), units from the one display table, and quantities named in words."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes._format import row_format, value_sd
from pmdc_bayes.inference.sampling.derived import derived_quantities
from pmdc_bayes.report import fig_params
from pmdc_bayes.report._plot import scale_of
from pmdc_bayes.report.adequacy import bench_table
from pmdc_bayes.report.tables import (
    comparison_table,
    derived_table,
    laplace_sd,
    rms_table,
    transfer_table,
)

NAMES = ("Ra", "La", "K", "B", "J", "Tc")
UNITS = dict(zip(NAMES, ("ohm", "H", "V*s/rad", "N*m*s/rad", "kg*m^2", "N*m"), strict=True))
MEAN = dict(zip(NAMES, (8.49921, 5.598e-3, 0.0619991, 4.4960e-5, 5.8984e-4, 2.5099e-3),
                strict=True))
SD = dict(zip(NAMES, (7.7e-4, 1.05e-5, 3.2e-6, 4.2e-8, 1.6e-7, 6.1e-6), strict=True))
CF = dict(MEAN, Ra=8.34727, La=5.955e-3, K=0.0620199, B=5.5825e-5, J=6.0823e-4, Tc=0.0)
VOLTAGE = 16.8


def _ctx(posterior: bool):
    rng = np.random.default_rng(3)
    draws = np.array([MEAN[n] for n in NAMES]) + np.array(
        [SD[n] for n in NAMES]) * rng.standard_normal((8000, len(NAMES)))
    params = {n: {"unit": UNITS[n], "closed_form": CF[n] if n != "Tc" else None,
                  "map": MEAN[n], "map_sd": SD[n]} for n in NAMES}
    summary = {"parameters": params, "derived": {"voltage": VOLTAGE}}
    values = {"map": dict(MEAN), "closed_form": dict(CF)}
    if posterior:
        for k, n in enumerate(NAMES):
            params[n].update(mean=float(draws[:, k].mean()), sd=float(draws[:, k].std()))
        values["mean"] = {n: params[n]["mean"] for n in NAMES}
        summary["derived"]["quantities"] = derived_quantities(
            {n: draws[:, k] for k, n in enumerate(NAMES)}, voltage=VOLTAGE)
    ctx = SimpleNamespace(summary=summary, values=values, names=NAMES,
                          draws=draws if posterior else None, has_posterior=posterior,
                          best=values.get("mean", values["map"]),
                          best_label="posterior mean" if posterior else "MAP",
                          cf_label="closed form", truth=None, log_names=NAMES,
                          model=SimpleNamespace(registry={
                              n: SimpleNamespace(transform="log", description=f"the {n}")
                              for n in NAMES}))
    ctx.unit = lambda n: UNITS[n]
    ctx.sd = lambda n: SD[n]
    ctx.covariance = lambda: np.diag([SD[n] ** 2 for n in NAMES])
    return ctx


def _decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def _two_digits(sd: str) -> bool:
    """An sd written with two significant digits (``0.0032``, ``1.2``, ``30``)."""
    return len(sd.replace(".", "").lstrip("0")) == 2


def _assert_rounded(value: str, sd: str):
    assert _two_digits(sd), sd
    assert _decimals(value) == _decimals(sd), (value, sd)


def _plain(table) -> str:
    return " ".join(" ".join(map(str, r)) for r in (table.header, *table.rows))


@pytest.mark.parametrize("posterior", [True, False])
def test_derived_quantities_are_rounded_to_their_sd_and_named_in_words(posterior):
    table = derived_table(_ctx(posterior))
    rows = {r[0]: r for r in table.rows}
    assert set(rows) == {"mechanical time constant τm", "electrical time constant τe",
                         "steady gain G", "no-load speed ω0", "no-load current i0",
                         "stall torque", "stall current", "speed constant Kv"}
    text = _plain(table)
    assert "_" not in text and "*" not in text and "rad/s/V" not in text
    assert rows["stall torque"][1] == "N·m" and rows["steady gain G"][1] == "rad/s per V"
    assert rows["electrical time constant τe"][1] == "×1e-6 s"  # τe ≈ 6.6e-4 s
    est = -1 if not posterior else -2  # "value ± sd" cell
    for r in table.rows:
        value, sd = r[est].split(" ± ")
        _assert_rounded(value, sd)
        _assert_rounded(r[2], sd)  # the closed form on the row's scale and decimals
        if posterior:
            lo, hi = r[-1].strip("[]").split(", ")
            _assert_rounded(lo, sd)
            assert lo != hi  # no "[14.67, 14.67]": the interval shows its width
    assert ("MAP ± sd (Laplace)" in table.header) is (not posterior)


def test_without_a_posterior_the_derived_sd_is_the_laplace_one_propagated():
    ctx = _ctx(False)
    sd = laplace_sd(ctx, lambda v: {"K2": 2.0 * v["K"], "KJ": v["K"] * v["J"],
                                    "Kv": 60.0 / (2 * np.pi * v["K"])})
    assert sd["K2"] == pytest.approx(2 * SD["K"], rel=1e-6)
    assert sd["KJ"] == pytest.approx(np.hypot(MEAN["J"] * SD["K"], MEAN["K"] * SD["J"]),
                                     rel=1e-5)
    assert sd["Kv"] == pytest.approx(60 / (2 * np.pi) * SD["K"] / MEAN["K"] ** 2, rel=1e-5)
    rows = {r[0]: r for r in derived_table(ctx).rows}
    assert rows["speed constant Kv"][-1] == "154.0231 ± 0.0079"  # 60/(2π·K), sd 7.95e-3


@pytest.mark.parametrize("posterior", [True, False])
def test_transfer_function_coefficients_are_rounded_to_their_sd(posterior):
    table = transfer_table(_ctx(posterior))
    text = _plain(table)
    assert "*" not in text and "^" not in text and "÷" not in text
    rows = {r[0]: r for r in table.rows}
    assert rows["(7) numerator K"][1] == "×1e-3 V·s/rad"
    assert rows["(22) numerator K/J"][1] == "rad/s² per A"
    assert rows["(22) constant (Ra·B + K²)/J"][1] == "Ω/s"
    for r in table.rows:
        value, sd = r[-1].split(" ± ")
        _assert_rounded(value, sd)
        _assert_rounded(r[2], sd)
    # K's row as the parameter table writes it: 61.999x ± 0.0032 on ×1e-3
    assert re.fullmatch(r"61\.999\d ± 0\.003\d", rows["(7) numerator K"][-1])


def test_the_comparison_rows_have_a_unit_and_their_sd_s_digits():
    ctx = _ctx(True)
    rows = [{"name": n, "closed_form": CF[n], "reference": MEAN[n], "sd": SD[n],
             "z": (CF[n] - MEAN[n]) / SD[n], "relative": CF[n] / MEAN[n] - 1} for n in NAMES]
    table = comparison_table(ctx, rows)
    assert table.header[:4] == ("parameter", "unit", "closed form", "posterior mean")
    k = next(r for r in table.rows if r[0] == "K")
    assert k[1:5] == ("×1e-3 V·s/rad", "62.0199", "61.9991", "0.0032")  # not "0.062"
    assert k[5:] == ("+6.5", "+0.034 %")  # as the headline writes them
    b = next(r for r in table.rows if r[0] == "B")
    assert b[1:] == ("×1e-6 N·m·s/rad", "55.825", "44.960", "0.042", "+259", "+24 %")
    tc = next(r for r in table.rows if r[0] == "Tc")
    assert tc[5:] == ("-411", "-100 %")


def test_bench_values_are_rounded_each_to_its_own_sd_with_a_display_unit():
    ctx = _ctx(True)
    table = bench_table(ctx, {
        "Ra": {"bench": 8.34727, "bench_sd": 0.1, "fitted": MEAN["Ra"], "z": 1.5, "unit": "ohm"},
        "La": {"bench": 5.955208e-3, "bench_sd": 2e-4, "fitted": MEAN["La"], "z": -1.8,
               "unit": "H"}})
    assert table.rows[0] == ("Ra", "Ω", "8.35 ± 0.10", "8.49921", "+1.5")
    assert table.rows[1] == ("La", "×1e-3 H", "5.96 ± 0.20", "5.598", "-1.8")


def test_rms_table_units_come_from_the_unit_table():
    tp = SimpleNamespace(trace=SimpleNamespace(name="step"), channels=("speed", "position"),
                         sims={"map": None}, noise={"speed": 0.3, "position": 0.01},
                         rms={"map": {"speed": 0.31, "position": 0.011}},
                         coverage={"speed": 0.93, "position": 0.95})
    table = rms_table([tp])
    assert [r[1] for r in table.rows] == ["speed (rad/s)", "position (rad)"]


def test_figure_scales_are_the_tables_scales():
    assert scale_of("J", 5.8984e-4, "kg*m^2") == (pytest.approx(1e6), "J (×1e-6 kg·m²)")
    assert scale_of("Ra", 8.5, "ohm") == (1.0, "Ra (Ω)")
    f = row_format(5.8984e-4, 1.6e-7)
    assert f.suffix == "×1e-6 "


def test_the_forest_figure_labels_each_value_rounded_to_its_sd(monkeypatch):
    monkeypatch.setattr(fig_params, "png", lambda fig: fig)
    fig = fig_params.forest_figure(_ctx(True), None)
    labels = [t.get_text() for t in fig.axes[0].get_yticklabels()]
    k = next(x for x in labels if x.startswith("K "))
    assert k.split("\n")[0] == "K (×1e-3 V·s/rad)"
    assert re.fullmatch(r"61\.999\d", k.split("\n")[1])  # not "0.062"
    b = next(x for x in labels if x.startswith("B "))
    assert b == "B (×1e-6 N·m·s/rad)\n" + row_format(MEAN["B"], SD["B"]).value(
        _ctx(True).best["B"])


def test_the_forest_plot_marks_the_closed_form_only_where_it_has_a_value(monkeypatch):
    ctx = _ctx(True)  # the closed form has no Tc: None in the summary, as in the tables
    points = fig_params.forest_points(ctx)
    assert list(points) == list(NAMES)
    assert points["Tc"]["closed_form"] is None
    assert points["K"]["closed_form"] == pytest.approx(
        100.0 * (CF["K"] / ctx.best["K"] - 1.0), rel=1e-12)
    lo, hi = points["K"]["map_2sd"]
    assert lo < points["K"]["map"] < hi and points["K"]["truth"] is None
    monkeypatch.setattr(fig_params, "png", lambda fig: fig)
    ax = fig_params.forest_figure(ctx, None).axes[0]
    squares = [line for line in ax.get_lines() if line.get_marker() == "s"]
    assert len(squares) == len(NAMES) - 1  # one per parameter but Tc, none at -100 %
    assert all(line.get_xdata()[0] > -100.0 for line in squares)


def test_a_value_in_running_text_carries_its_scale_after_the_sd():
    assert value_sd(5.955208e-3, 2e-4) == "5.96 ± 0.20 ×1e-3"
    assert value_sd(8.34727, 0.1) == "8.35 ± 0.10"
    f = row_format(0.0619991, 3.2e-6)
    assert f.same_scale(1e-4).value(0.0620199) == "62.02"
    assert f.interval(0.061993, 0.0620052) == "[61.9930, 62.0052]"
    assert f.interval(None, 1.0) == "—"


def test_the_comparison_is_titled_for_what_it_compares_with():
    # the reference is the posterior mean, or the MAP without a posterior
    for posterior in (True, False):
        ctx = _ctx(posterior)
        table = comparison_table(ctx, [])
        assert "posterior" not in table.title
        assert table.header[3] == ("posterior mean" if posterior else "MAP")


def test_the_closed_form_s_causes_write_amounts_as_the_tables_write_the_parameter():
    """Each part of a closed-form difference on its parameter's scale, to the decimals
    its sd supports, with its unit: no '+0.000137 of the +2.08e-05 V·s/rad'."""
    from pmdc_bayes import closed_form, load_session
    from pmdc_bayes.report.comparison import compare_closed_form

    session = load_session("demo")
    ctx = _ctx(True)
    ctx.session, ctx.cf = session, closed_form(session)
    ctx.values["closed_form"] = dict(ctx.cf.params(), Tc=0.0)
    rows = {r["name"]: r for r in compare_closed_form(ctx)}
    text = " ".join(" ".join(r["causes"]) for r in rows.values())
    assert not re.search(r"(?<![×\d.])\d+(\.\d+)?e[-+]\d", text)  # no "2.08e-05" in the text
    k = rows["K"]["causes"]
    assert re.search(r"gives K = 62\.0199 ×1e-3 V·s/rad; with the posterior mean Ra = "
                     r"8\.499\d\d Ω it gives 61\.\d{4} ×1e-3 V·s/rad, so Ra accounts for "
                     r"\+0\.\d{4} ×1e-3 V·s/rad of the \+0\.02\d\d ×1e-3 V·s/rad difference",
                     k[0]), k[0]
    assert re.search(r"Tc = 2\.5\d{3} ×1e-3 N·m at ω = .* Tc/ω = \+10\.\d{3} ×1e-6 N·m·s/rad",
                     rows["B"]["causes"][1]), rows["B"]["causes"][1]
    assert re.search(r"up to \d+\.\d\d ×1e-6 kg·m²\)", " ".join(rows["J"]["causes"]))
    assert "(8.35 ± 0.10 Ω)" in rows["Ra"]["causes"][0]
    assert rows["K"]["headline"].startswith("K: the closed form is +0.034 % from the "
                                            "posterior mean, +6.")


def test_the_diagnostics_name_the_stages_in_words():
    from pmdc_bayes.report.tables import diagnostics_table

    ctx = _ctx(True)
    ctx.summary["fit"] = {"status": "converged", "message": "converged", "starts": []}
    ctx.summary["diagnostics"] = {"gates_passed": True, "wall_s": {
        "closed_form": 0.01, "map": 33.7, "adequacy": 1.0, "mcmc": 14.3, "report": 11.3,
        "total": 60.3}}
    row = next(r for r in diagnostics_table(ctx).rows if r[0] == "wall time (s)")
    assert row[1] == "closed form 0.0, MAP 33.7, adequacy 1.0, MCMC 14.3, report 11.3, total 60.3"


def test_the_rig_s_parameters_are_explained_in_words_under_the_table():
    from pmdc_bayes.report.tables import parameter_table

    ctx = _ctx(False)
    assert "rig's parameters" not in parameter_table(ctx).note  # the motor's alone
    name = "dead_time_step_12v"
    ctx.names = (*NAMES, name)
    ctx.summary["parameters"][name] = {"unit": "s", "closed_form": None, "map": 2.1e-3,
                                       "map_sd": 1.2e-4}
    ctx.model.registry[name] = SimpleNamespace(
        transform="identity", description="dead time of trace 'step_12v'")
    table = parameter_table(ctx)
    assert table.rows[-1][:4] == (name, "×1e-3 s", "— (none)", "2.10 ± 0.12")
    assert table.note.endswith("The rig's parameters (named as in summary.json): "
                               "dead_time_step_12v: dead time of trace 'step_12v'.")


def test_a_steady_row_says_when_its_miss_was_read_on_the_noise_prior():
    from types import SimpleNamespace

    from pmdc_bayes.report.adequacy import adequacy_section

    def row(noise):
        return {"trace": "steady", "signal": "speed", "unit": "rad/s", "n": 1,
                "rms_miss_fraction": 0.02, "largest_miss_fraction": 0.02,
                "noise": noise, "p_value": 0.4}

    summary = {"adequacy": {"findings": [], "diagnosis": [], "level": 0.05,
                            "channels": {"point: speed": row("prior"),
                                         "steady: speed": row("scatter")}}}
    sec = adequacy_section(SimpleNamespace(summary=summary))
    (table,) = [x for x in sec.blocks if getattr(x, "title", "") == "Per channel"]
    cells = {r[0]: r[5] for r in table.rows}
    assert cells["point: speed"].endswith("on its noise prior)"), cells
    assert "noise prior" not in cells["steady: speed"], cells
