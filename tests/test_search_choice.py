"""The search's choice among a step's candidates asks for verdicts only as far as it
needs (each costs the adequacy checks of a fit), and chooses exactly as the rule that
checks every candidate first: on random steps, the same candidate and reason."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes.search import ADD_MARGIN, _better


class _Stub:
    """A fitted candidate whose verdict is counted when asked for."""

    def __init__(self, name, log_evidence, adequate, converged=True, undetermined=()):
        self.terms = frozenset({name})
        self.log_evidence = log_evidence
        self.fit = SimpleNamespace(status="converged" if converged else "max_steps")
        self.undetermined = undetermined
        self._adequate, self.asked = adequate, 0

    @property
    def ok(self):
        self.asked += 1
        return self._adequate and self.fit.status == "converged" \
            and math.isfinite(self.log_evidence)


def _eager(current, cands):
    """The rule with every verdict read first: adequate candidates before the others,
    each group in order of evidence."""
    for c in sorted(cands, key=lambda c: (-c.ok, -c.log_evidence if
                                          math.isfinite(c.log_evidence) else math.inf)):
        if c.fit.status != "converged" or not math.isfinite(c.log_evidence):
            continue
        gain = c.log_evidence - current.log_evidence
        if current.ok and (c.undetermined or not c.ok):
            continue
        if gain > ADD_MARGIN or (not current.ok and c.ok and gain >= 0):
            return c
    return None


@pytest.mark.parametrize("seed", range(40))
def test_the_choice_is_the_eager_rule_s_with_fewer_verdicts(seed):
    rng = np.random.default_rng(seed)
    current = _Stub("current", 0.0, bool(rng.integers(2)))
    cands = [_Stub(f"c{k}", float(rng.normal(0, 8)) if rng.random() > 0.1 else -math.inf,
                   bool(rng.random() < 0.5), converged=bool(rng.random() > 0.1),
                   undetermined=("x",) if rng.random() < 0.2 else ())
             for k in range(int(rng.integers(1, 7)))]
    expected = _eager(current, cands)
    for c in cands:
        c.asked = 0
    chosen, why = _better(current, cands)
    assert chosen is expected
    assert (why == "") == (chosen is None)
    # no candidate below an adequate choice is asked for its verdict; below a rejected
    # one (where the current model is rejected too), none that loses evidence
    if chosen is not None and chosen._adequate:
        assert all(c.asked == 0 for c in cands if c.log_evidence < chosen.log_evidence)
    floor = current.log_evidence + (ADD_MARGIN if current._adequate else 0.0)
    assert all(c.asked == 0 for c in cands if c.log_evidence < floor)


def test_a_step_whose_best_is_adequate_checks_only_it():
    current = _Stub("current", 0.0, False)
    cands = [_Stub("a", 40.0, True), _Stub("b", 30.0, True), _Stub("c", 5.0, False)]
    chosen, why = _better(current, cands)
    assert chosen is cands[0] and "log Z +40.0" in why
    assert [c.asked for c in cands] == [1, 0, 0]
