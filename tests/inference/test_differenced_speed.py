"""A speed logged as an encoder's counts differenced over each sample interval (the
fuzzer's "encoder speed" rig): read as a speed its errors are anti-correlated and the
adequacy checks reject it; with the encoder's counts_per_rev declared the trace is read
as the counted angle and fitted as the rig ran."""

import numpy as np
import pytest

from pmdc_bayes.inference.adequacy.verdict import assess
from pmdc_bayes.inference.fit.joint import fit_map
from pmdc_bayes.inference.model.objective import build_model
from pmdc_bayes.inference.model.seed import fit_seed
from pmdc_bayes.io.loader import load_session
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
