"""What ``pmdc-bayes fit`` prints: the verdict before any number, the candidate models
of ``--compare``, the parameter table and the findings."""

from __future__ import annotations

__all__ = ["print_fit", "print_adequacy"]


def print_adequacy(adequacy: dict) -> bool:
    """The verdict, before any number; for an inadequate model, what failed and what
    the pattern suggests.  Returns whether the model is adequate."""
    fails = [f for f in adequacy["findings"] if f["severity"] == "fail"]
    if not fails:
        n = len(adequacy["findings"])
        print("Model adequate: the data do not reject the fitted model"
              + (f" ({n} warning{'s' * (n != 1)} in the report)." if n else "."))
        return True
    print("MODEL INADEQUATE: the data reject the fitted model.")
    for f in fails:
        print(f"  {f['where']}: {f['message']} [{f['check']}]")
    print("What to add:")
    for line in adequacy["diagnosis"]:
        print(f"  - {line}")
    return False


def print_fit(summary: dict, out) -> bool:
    """A finished fit's summary on the terminal; returns whether the model is adequate."""
    adequate = print_adequacy(summary["adequacy"])
    if "model_selection" in summary:
        from .selection import format_selection

        print("Candidate models (--compare):")
        for line in format_selection(summary["model_selection"]):
            print(f"  {line}")
    print(f"Fit of {summary['session']['motor']} ({summary['session']['friction']} friction): "
          f"{summary['fit']['message']}")
    has_post = "mean" in next(iter(summary["parameters"].values()))
    width = max([9] + [len(n) for n in summary["parameters"]]) + 1
    head = f"{'parameter':<{width}}{'closed form':>13}{'MAP':>13}{'± sd':>11}"
    if has_post:
        head += f"{'mean':>13}{'± sd':>11}{'94 % HDI':>26}{'R-hat':>7}{'ESS':>7}"
    if not adequate:
        print("Values CONDITIONAL on a model the data reject:")
    print(head + "  unit")
    for name, row in summary["parameters"].items():
        cf = "—" if row["closed_form"] is None else f"{row['closed_form']:.5g}"
        line = f"{name:<{width}}{cf:>13}{row['map']:>13.6g}{row['map_sd']:>11.3g}"
        if has_post:
            hdi = f"[{row['hdi_3%']:.5g}, {row['hdi_97%']:.5g}]"
            line += (f"{row['mean']:>13.6g}{row['sd']:>11.3g}{hdi:>26}{row['r_hat']:>7.3f}"
                     f"{row['ess_bulk']:>7.0f}")
        print(f"{line}  {row['unit']}")
    for line in summary["identifiability"]["findings"]:
        print(f"- {line}")
    for row in summary.get("laplace_check", []):
        if row["flagged"]:
            print(f"- {row['name']}: posterior sd is {row['ratio']:.2f} x the Laplace sd "
                  f"({row['note']}).")
    print(f"Wrote {out}")
    return adequate
