"""The search's choice among a step's candidates asks for verdicts only as far as it
needs (each costs the adequacy checks of a fit), and chooses exactly as the rule that
checks every candidate first: on random steps, the same candidate and reason.  A step
tries changes to the model's structure before coloured noise, and every single addition
also where the data do not reject the model."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from pmdc_bayes.search import ADD_MARGIN, _better, _forward
from pmdc_bayes.terms import NOISE


class _Stub:
    """A fitted candidate whose verdict is counted when asked for."""

    def __init__(self, name, log_evidence, adequate, converged=True, undetermined=()):
        self.terms = frozenset({name})
        self.log_evidence = log_evidence
        self.fit = SimpleNamespace(ok=converged)
        self.undetermined = undetermined
        self._adequate, self.asked = adequate, 0

    @property
    def ok(self):
        self.asked += 1
        return self._adequate and self.fit.ok \
            and math.isfinite(self.log_evidence)


def _eager(current, cands):
    """The rule with every verdict read first: adequate candidates before the others,
    each group in order of evidence."""
    for c in sorted(cands, key=lambda c: (-c.ok, -c.log_evidence if
                                          math.isfinite(c.log_evidence) else math.inf)):
        if not c.fit.ok or not math.isfinite(c.log_evidence):
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


class _Step:
    """A search whose candidates' evidence and verdicts are given: ``table`` maps a move
    (a frozenset of terms) to (log Z, adequate); the moves fitted are recorded."""

    def __init__(self, proposed, singles, table):
        self._proposed, self._singles, self.table = proposed, singles, table
        self.fitted = []

    def proposed(self, current):
        return list(self._proposed)

    def singles(self, current):
        return list(self._singles)

    def evaluate(self, moves, parent, kind):
        self.fitted += moves
        out = []
        for move in moves:
            z, adequate = self.table[move]
            out.append(_Stub("+".join(sorted(move)), z, adequate))
        return out


NOISY = frozenset({NOISE + "step"})
LAG, DROP, DEAD = (frozenset({t}) for t in ("speed_lag", "voltage_drop", "dead_time"))


def test_a_structural_addition_comes_before_noise_that_gains_more():
    """Noise gains most (it soaks up any misfit), yet a structural addition the data
    accept is taken first, and the noise is not even fitted."""
    search = _Step([NOISY, LAG], [DROP], {NOISY: (500.0, True), LAG: (60.0, True),
                                          DROP: (10.0, False)})
    best, why, source, tried = _forward(search, _Stub("ideal", 0.0, False))
    assert best.terms == frozenset({"speed_lag"}) and source == "proposed by the verdict"
    assert NOISY not in search.fitted and DROP not in search.fitted


def test_noise_is_taken_where_no_change_of_structure_helps():
    search = _Step([NOISY], [LAG, DROP], {NOISY: (80.0, True), LAG: (-2.0, False),
                                          DROP: (1.0, False)})
    best, _, _, tried = _forward(search, _Stub("ideal", 0.0, False))
    assert best.terms == NOISY
    assert search.fitted == [LAG, DROP, NOISY] and len(tried) == 3


def test_an_adequate_model_still_takes_an_addition_the_evidence_strongly_supports():
    """The verdict proposes nothing for a model the data do not reject; every single
    addition is tried, and one gaining more than the margin is taken."""
    gain = ADD_MARGIN + 4.0
    search = _Step([], [LAG, DEAD, NOISY], {LAG: (1.0, True), DEAD: (gain, True),
                                            NOISY: (2.0, True)})
    best, why, source, _ = _forward(search, _Stub("ideal", 0.0, True))
    assert best.terms == frozenset({"dead_time"}) and source == "every single addition tried"
    assert f"{gain:+.1f}" in why and NOISY not in search.fitted


def test_an_adequate_model_is_kept_when_no_addition_gains_enough():
    search = _Step([], [LAG, DEAD, NOISY], {LAG: (ADD_MARGIN - 0.5, True),
                                            DEAD: (-4.0, True), NOISY: (1.0, True)})
    best, _, _, tried = _forward(search, _Stub("ideal", 0.0, True))
    assert best is None and search.fitted == [LAG, DEAD, NOISY] and len(tried) == 3


def test_noise_on_one_sensor_s_other_traces_comes_with_the_proposed_structure():
    """Where the model holds coloured noise on one trace, the same on another is tried
    with the proposed structure, before every other single addition, and once."""
    search = _Step([NOISY, LAG], [DROP], {NOISY: (50.0, False), LAG: (20.0, False),
                                          DROP: (90.0, False)})
    best, _, source, tried = _forward(search, _Stub(NOISE + "load", 0.0, False))
    assert best.terms == NOISY and source == "proposed by the verdict"
    assert search.fitted == [NOISY, LAG] and len(tried) == 2
    search = _Step([NOISY, LAG], [DROP], {NOISY: (1.0, False), LAG: (-1.0, False),
                                          DROP: (2.0, False)})
    best, _, _, tried = _forward(search, _Stub(NOISE + "load", 0.0, False))
    assert best is None and search.fitted == [NOISY, LAG, DROP] and len(tried) == 3


@pytest.mark.parametrize("overflows, faulty, adequate, only_if_rejected, expected", [
    (True, False, True, True, "FIT_FAILED"),
    (False, True, False, False, "FAULTY_DATA"),
    (False, False, True, True, "ADEQUATE_START"),
    (False, False, True, False, None),
    (False, False, False, True, None),
])
def test_the_search_ends_at_its_start_for_a_named_reason(overflows, faulty, adequate,
                                                          only_if_rejected, expected):
    from pmdc_bayes.search import Stop, _first_stop

    start = SimpleNamespace(fit=SimpleNamespace(overflows=overflows),
                            adequacy=SimpleNamespace(faulty_data=faulty), ok=adequate)
    stop = _first_stop(start, only_if_rejected)
    assert stop is (None if expected is None else Stop[expected])


class _Walk:
    """A whole search over given models: ``table`` maps a model's terms to (log Z,
    adequate); the verdict of a rejected model proposes ``proposals`` (in order)."""

    def __init__(self, table, proposals, max_fits=32):
        self.table, self._proposals, self.max_fits = table, proposals, max_fits
        self.done, self.fitted = {}, []

    def fits_left(self):
        return self.max_fits - len(self.fitted)

    def proposed(self, current):
        return [] if current._adequate else [m for m in self._proposals
                                             if not m <= current.terms]

    def singles(self, current):
        return [m for m in (LAG, DROP, DEAD) if not m <= current.terms]

    def evaluate(self, moves, parent, kind):
        out = []
        for move in moves:
            terms = parent.terms - move if kind == "remove" else parent.terms | move
            if terms not in self.done:
                z, adequate = self.table.get(terms, (-50.0, False))
                c = _Stub("x", z, adequate)
                c.terms, c.parent, c.why = terms, parent, ""
                self.done[terms] = c
                self.fitted.append(terms)
            out.append(self.done[terms])
        return out

    def let_go(self, current, everything=False):
        pass


@pytest.mark.parametrize("only_if_rejected", [True, False])
def test_a_plain_fit_stops_at_the_first_model_the_data_do_not_reject(only_if_rejected):
    """A plain fit's search takes the proposed lag the data accept and stops there,
    having fitted only it; ``--compare`` tries every addition to it as well, and takes
    one the evidence strongly supports."""
    from pmdc_bayes.search import Stop, _walk

    table = {frozenset(): (0.0, False), LAG: (40.0, True),
             LAG | DROP: (40.0 + ADD_MARGIN + 1.0, True), LAG | DEAD: (39.0, True)}
    search = _Walk(table, [LAG])
    start = _Stub("ideal", 0.0, False)
    start.terms, start.why = frozenset(), ""
    chosen, stop = _walk(search, start, frozenset(), only_if_rejected)
    if only_if_rejected:
        assert chosen.terms == LAG and stop is Stop.ADEQUATE_REACHED
        assert search.fitted == [LAG]
    else:
        assert chosen.terms == LAG | DROP and stop is Stop.NOTHING_BETTER
        assert LAG | DEAD in search.fitted


class _Held(_Stub):
    """A candidate of a search state: its model counts the times its programs are let
    go; its verdict made or not; fitted by a no-op."""

    def __init__(self, name, log_evidence, parent=None, checked=False):
        super().__init__(name, log_evidence, True)
        self.parent, self.checked = parent, checked
        self.model = SimpleNamespace(released=0)
        self.model.release = lambda: setattr(self.model, "released", self.model.released + 1)

    def run(self, seed, superset):
        pass


def test_a_candidate_s_programs_are_let_go_once_the_search_cannot_ask_for_them():
    """Right after its fit, a candidate whose evidence is so far below its parent's that
    it can be neither taken, nor kept by a removal, nor reported as a tie; after a step,
    every candidate whose verdict is made too; at the end, all but the chosen one and
    the supersets'."""
    from pmdc_bayes.search import REMOVE_MARGIN, TIE
    from pmdc_bayes.search_state import SearchState

    within = max(TIE, REMOVE_MARGIN)
    state = SearchState.__new__(SearchState)
    supersets = SimpleNamespace(released=0)
    supersets.release = lambda: setattr(supersets, "released", supersets.released + 1)
    state.order, state.keep_within, state.seed, state.say = [], within, 0, lambda text: None
    state.supersets = supersets
    current = _Held("speed_lag", 0.0)
    state._fitted(current, None)
    far = state._fitted(_Held("dead_time", -within - 0.1, current), None)
    near = state._fitted(_Held("voltage_drop", -within + 0.1, current), None)
    checked = state._fitted(_Held("current_lag", -1.0, current, checked=True), None)
    better = state._fitted(_Held("speed_gain", 5.0, current), None)
    assert [c.model.released for c in (current, far, near, checked, better)] == [0, 1, 0, 0, 0]
    # the removal rule asks no verdict of what is let go: its loss exceeds the margin
    assert current.log_evidence - far.log_evidence > REMOVE_MARGIN
    state.let_go(better)  # the search moved on to `better`: `near` is now far below it
    assert [c.model.released > 0 for c in (current, far, near, checked, better)] == [
        True, True, True, True, False]
    assert supersets.released == 0
    state.let_go(better, everything=True)
    assert better.model.released == 0 and supersets.released == 1
