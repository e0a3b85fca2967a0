"""What ``pmdc-bayes fit`` prints: the verdict before any number, the candidate models
of ``--compare``, the headline a result's repr and the report open with (each value
rounded to its uncertainty beside the closed form and its error, the fit % per trace,
what the data cannot determine), then the details (MAP and posterior columns) and the
findings."""

from __future__ import annotations

from ._errors import EXIT_FAILED, EXIT_INADEQUATE
from ._format import row_format
from ._headline import headline_text, pi_loop_text, spread_text
from .inference.adequacy.findings import Severity
from .io.units import display_unit

__all__ = ["print_fit", "print_adequacy", "gate_failure_text", "run_outcome"]


def print_adequacy(adequacy: dict) -> bool:
    """The verdict, before any number; for an inadequate model, what failed and what
    the pattern suggests.  Returns whether the model is adequate."""
    fails = [f for f in adequacy["findings"] if Severity(f["severity"]) is Severity.FAIL]
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

        why = ("--compare" if summary["model_selection"].get("compare", True)
               else "the data reject the session's model; --no-search skips it")
        print(f"The model, found by a search ({why}):")
        for line in format_selection(summary["model_selection"]):
            print(f"  {line}")
    print(headline_text(summary))
    if "pi_loop" in summary:
        print(pi_loop_text(summary["pi_loop"]) + ".")
    print(f"\nDetails of the fit of {summary['session']['motor']} "
          f"({summary['session']['friction']} friction): {summary['fit']['message']}")
    has_post = "mean" in next(iter(summary["parameters"].values()))
    width = max([9] + [len(n) for n in summary["parameters"]]) + 1
    head = f"{'parameter':<{width}}{'closed form':>13}{'MAP':>13}{'± sd':>11}"
    if has_post:
        head += f"{'mean':>13}{'± sd':>11}{'94 % HDI':>26}{'R-hat':>7}{'ESS':>7}"
    if not adequate:
        print("Values CONDITIONAL on a model the data reject:")
    print(head + "  unit")
    for name, row in summary["parameters"].items():
        sds = [x for x in (row.get("map_sd"), row.get("sd")) if x is not None and x > 0]
        f = row_format(row["mean"] if has_post else row["map"], min(sds) if sds else None)
        line = (f"{name:<{width}}{f.value(row['closed_form']):>13}{f.value(row['map']):>13}"
                f"{f.sd(row['map_sd']):>11}")
        if has_post:
            hdi = f"[{f.value(row['hdi_3%'])}, {f.value(row['hdi_97%'])}]"
            line += (f"{f.value(row['mean']):>13}{f.sd(row['sd']):>11}{hdi:>26}"
                     f"{row['r_hat']:>7.3f}{row['ess_bulk']:>7.0f}")
        print(f"{line}  {f.suffix}{display_unit(row['unit'])}")
    rig = [f"{name}: {row['description']}" for name, row in summary["parameters"].items()
           if row.get("block", "motor") not in ("motor", "friction") and row.get("description")]
    if rig:
        print("The rig's parameters: " + "; ".join(rig) + ".")
    for row in summary.get("laplace_check", []):
        if row["flagged"]:
            print(f"- {row['name']}: posterior sd is {row['ratio']:.2f} x the Laplace sd "
                  f"({row['note']}).")
    spread = spread_text(summary.get("diagnostics", {}))
    if spread:
        print(f"- {spread}.")
    print(f"Wrote {out}")
    return adequate


def gate_failure_text(diag: dict, n_params: int) -> str:
    """The posterior's failed gates in one line: the run's stop, how many parameters
    miss R-hat or ESS (summary.json lists each), and the widest direction."""
    failures = list(diag.get("failures", []))
    capped = [f for f in failures if f.startswith("run capped: ")]
    per_param = [f for f in failures if not f.startswith("run capped: ")]
    names = list(dict.fromkeys(f.split(": ", 1)[0] for f in per_param))
    parts = [f[len("run capped: "):] for f in capped]
    if names:
        parts.append(f"R-hat or ESS short of the gates for {len(names)} of {n_params} "
                     f"parameters ({per_param[0]}{', …' if len(per_param) > 1 else ''}; "
                     "summary.json lists each)")
    spread = spread_text(diag)
    if spread:
        parts.append(spread)
    return "; ".join(parts)


def run_outcome(summary: dict, *, allow_unconverged: bool = False,
                allow_inadequate: bool = False, advice: bool = True) -> tuple[int, list[str]]:
    """A finished run's exit code and its errors, in the order they are told: a fit that
    did not converge first (the verdict was judged where the MAP is not), then the
    model's inadequacy (which ends the run unless allowed), then a posterior that failed
    its gates.  ``advice`` adds what to rerun with."""
    status, errors = 0, []
    if summary["fit"]["status"] != "converged" and not allow_unconverged:
        errors.append(f"the fit did not converge: {summary['fit']['message']}")
        status = EXIT_FAILED
    adequacy = summary["adequacy"]
    first = next((f for f in adequacy["findings"] if Severity(f["severity"]) is Severity.FAIL),
                 None)
    if first is not None:
        hint = next(iter(adequacy.get("diagnosis") or []), "")
        hint = f"; likely: {hint}" if hint and adequacy.get("proposals") else ""
        errors.append(f"model inadequate: {first['where']}: {first['message']}{hint}"
                      + ("" if allow_inadequate or not advice else
                         " (see the report; rerun with --allow-inadequate to go on)"))
        if not allow_inadequate:
            return status or EXIT_INADEQUATE, errors
    diag = summary["diagnostics"]
    if diag.get("gates_passed") is False and not allow_unconverged:
        errors.append("the posterior failed its convergence gates: "
                      + gate_failure_text(diag, len(summary["parameters"]))
                      + (" (rerun with --allow-unconverged to accept)" if advice else ""))
        status = EXIT_FAILED
    return status, errors
