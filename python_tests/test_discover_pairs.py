"""The pair step (discover/pairs.py): where no candidate of a step earns its place alone and the model
still misses the record, the refused candidate that lowered the BIC most is fitted beside each other
missing effect, and the pair is judged as one candidate (judge.pair_verdict: against the current
model, and each effect against the pair without it; then the held-out test). The search's fits are
replaced by a table of outcomes, so what is checked is the step's own logic: what it fits, what it
adds and what it records; the judging rule is checked against the BIC worked by hand."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from tether.discover import judge, pairs, search
from tether.discover.fitting import ModelFit
from tether.discover.records import CandidateResult, Step
from tether.models import parse_model

SIGMA = 1e-4
N = 4000


def _fit(model: str, effects: tuple, rms_over_noise: float, n_free: int) -> ModelFit:
    return ModelFit(spec=parse_model(model, "forced"), effects=effects, params={}, free=[f"p{i}" for i in range(n_free)],
                    rms=rms_over_noise * SIGMA, predicted=np.zeros(3))


def _bic(rms_over_noise: float, k: int) -> float:
    return N * math.log((rms_over_noise * SIGMA) ** 2) + k * math.log(N)


LINEAR = _fit("linear", (), 20.0, 3)
CUBIC = _fit("cubic", ("nonlinear_stiffness",), 12.0, 4)
DAMPED = _fit("linear+nonlinear_damping", ("nonlinear_damping",), 14.0, 6)
PAIR = parse_model("cubic+nonlinear_damping", "forced").canonical
#: the damping's other law beside the cubic: dry friction, which this record's damping is not
FRICTION_PAIR = parse_model("cubic+coulomb", "forced").canonical
FRICTION = _fit(FRICTION_PAIR, ("nonlinear_stiffness", "nonlinear_damping"), 11.5, 6)


def _refused(fm: ModelFit, effect: str) -> CandidateResult:
    return CandidateResult(effect=effect, model=fm.model, added_parameters=fm.n_free - LINEAR.n_free, rms=fm.rms,
                           heldout_rms=float("nan"), bic_change=judge.bic_change(LINEAR, fm, N), signature=0.0,
                           signature_text="", fit=fm, accepted=False, verdict="the gap shrinks too little")


class _Trace:
    experiment, rig = "forced", "payload"


def _search(monkeypatch, outcomes: dict, held: dict) -> tuple[search.Search, list]:
    """A Search in a step whose candidates were refused: LINEAR its model; ``outcomes`` the fit of
    each model asked for (by its name), ``held`` its held-out error over noise; the models asked for
    are returned in the list."""
    s = search.Search.__new__(search.Search)
    asked = []

    def fit(tr, sp, eff, starts, scales, **kw):
        asked.append(sp.canonical)
        return outcomes[sp.canonical]

    monkeypatch.setattr(pairs, "candidate_starts", lambda *a: [None])
    monkeypatch.setattr(pairs, "_heldout", lambda tr, spec, params, held_out: held[spec.canonical] * SIGMA)
    s.fit = fit
    s.part_fit = lambda c, own_thread=False: c.fit
    s.cur, s.cur_held, s.fits = LINEAR, 25.0 * SIGMA, [LINEAR]
    s.sigma, s.n, s.sc, s.trace, s.part, s.sc_part = SIGMA, N, None, _Trace(), None, None
    s.held_out = np.arange(N) >= 2400
    s.w_sim_start, s.n_free_start = 1, 3
    s.extension_cap_factor = lambda m: 1.0
    s.base_effects, s.budget_hit, s.say = (), False, lambda line: None
    s.steps, s.removals, s.refinements, s.retested_at = [], [], [], 0
    s.shape_free, s.shape_held = (), ()
    return s, asked


def _step(s) -> Step:
    st = Step(model_before=LINEAR.model, rms_before=LINEAR.rms, heldout_before=s.cur_held, windows=[], regimes={},
              candidates=[])
    s.steps.append(st)
    return st


def test_a_pair_verdict_asks_each_effect_to_earn_its_place_beside_the_other():
    """20 x noise before; the pair at 1.05 x with 4 more parameters passes against the linear model
    (BIC worked by hand) and against each effect alone (12 and 14 x); a pair at 2.95 x adds
    the damping as a passenger of a cubic that reaches 3.0 x alone: refused, and the verdict names it."""
    pair = _fit("cubic+nonlinear_damping", ("nonlinear_stiffness", "nonlinear_damping"), 1.05, 7)
    ok, why = judge.pair_verdict(SIGMA, LINEAR, pair, [("nonlinear_stiffness", DAMPED), ("nonlinear_damping", CUBIC)], N)
    assert ok, why
    assert f"BIC {_bic(1.05, 7) - _bic(20.0, 3):+.0f}" in why
    rider = _fit("cubic+nonlinear_damping", ("nonlinear_stiffness", "nonlinear_damping"), 2.95, 7)
    cubic_alone = _fit("cubic", ("nonlinear_stiffness",), 3.0, 4)
    ok, why = judge.pair_verdict(SIGMA, LINEAR, rider, [("nonlinear_stiffness", DAMPED),
                                                        ("nonlinear_damping", cubic_alone)], N)
    assert not ok and "nonlinear_damping does not earn its place beside the other" in why, why


def test_two_effects_refused_alone_are_added_as_a_pair_in_two_steps(monkeypatch):
    """The cubic (the lowest BIC of the refused) leads; fitted beside the damping it explains the
    record (1.05 x, held-out 1.2 x against 25 x): both are added, the cubic's step and the damping's,
    from the same model before to the same model after, each with its pair's verdict."""
    pair = _fit("cubic+nonlinear_damping", ("nonlinear_stiffness", "nonlinear_damping"), 1.05, 7)
    s, asked = _search(monkeypatch, {PAIR: pair, FRICTION_PAIR: FRICTION}, {PAIR: 1.2, FRICTION_PAIR: 12.0})
    results = [_refused(CUBIC, "nonlinear_stiffness"), _refused(DAMPED, "nonlinear_damping")]
    monkeypatch.setattr(pairs, "candidates", lambda tr: ("nonlinear_stiffness", "nonlinear_damping"))
    assert s.pair_worth_trying(results)
    found = s.pair_of_refused(results)
    assert asked == [PAIR, FRICTION_PAIR]           # the damping's laws beside the lead, each
    assert found is not None and [c.effect for c in found] == ["nonlinear_stiffness", "nonlinear_damping"]
    s.add_pair(found, results, _step(s), [])
    assert [st.effect for st in s.steps] == ["nonlinear_stiffness", "nonlinear_damping"]
    assert all(st.model_before == "linear" and st.rms_after == pair.rms for st in s.steps)
    assert s.cur is pair and s.fits[-1] is pair
    assert "as a pair with nonlinear_damping" in s.steps[0].candidates[0].verdict
    assert "as a pair with nonlinear_stiffness" in s.steps[1].evidence


@pytest.mark.parametrize("pair_rms, held, why", [(11.9, 1.2, "passenger"), (1.05, 24.0, "held-out part")])
def test_a_pair_that_fails_either_rule_adds_nothing(monkeypatch, pair_rms, held, why):
    """A pair whose second effect only rides on the first, or whose fit to the first part predicts
    the rest no better, is refused: no step, the model unchanged."""
    pair = _fit("cubic+nonlinear_damping", ("nonlinear_stiffness", "nonlinear_damping"), pair_rms, 7)
    s, _ = _search(monkeypatch, {PAIR: pair, FRICTION_PAIR: FRICTION}, {PAIR: held, FRICTION_PAIR: 12.0})
    monkeypatch.setattr(pairs, "candidates", lambda tr: ("nonlinear_stiffness", "nonlinear_damping"))
    results = [_refused(CUBIC, "nonlinear_stiffness"), _refused(DAMPED, "nonlinear_damping")]
    assert s.pair_of_refused(results) is None, why
    assert s.cur is LINEAR and s.steps == []


def test_no_pair_is_tried_where_the_model_is_within_the_unexplained_gap(monkeypatch):
    """At 1.3 x noise (a gap below CRITERIA.unexplained_gap sigma) the search stops as before; with
    no refused candidate that lowered the BIC there is no lead either."""
    s, _ = _search(monkeypatch, {}, {})
    s.cur = _fit("linear", (), 1.3, 3)
    near = _fit("cubic", ("nonlinear_stiffness",), 1.2, 4)
    assert not s.pair_worth_trying([CandidateResult("nonlinear_stiffness", "cubic", 1, near.rms, float("nan"), -5.0, 0.0, "",
                                           fit=near)])
    s.cur = LINEAR
    worse = _refused(_fit("cubic", ("nonlinear_stiffness",), 20.5, 4), "nonlinear_stiffness")
    assert not s.pair_worth_trying([worse])


def test_the_pairs_stage_runs_only_after_a_search_that_stopped_without_a_winner(monkeypatch):
    """The plan's stage "pairs" is due where the last search for effects stopped with no candidate
    earning its place and the model misses the record (20 x noise); not where that search stopped
    for another reason, nor where the refined model is within the unexplained gap (1.3 x)."""
    s, _ = _search(monkeypatch, {}, {})
    s.no_winner = False
    assert not s.pairs_due()
    s.no_winner = True
    assert s.pairs_due()
    s.cur = _fit("linear", (), 1.3, 3)
    assert not s.pairs_due()


def test_a_pairs_stage_that_names_nothing_leaves_the_search_as_it_was(monkeypatch):
    """The stage's own search for effects may refit the model on its way (a slack candidate's refit
    that never goes slack is kept by a step without a winner); where it names no pair, the model,
    its fits, steps and stop reason are those from before, the stop reason saying pairs were tried."""
    s, _ = _search(monkeypatch, {}, {})
    s.stop, s.no_winner = "no candidate earns its parameters", True
    refit = _fit("linear", (), 19.0, 3)

    def search_effects():
        s.steps.append(Step(model_before="linear", rms_before=LINEAR.rms, heldout_before=s.cur_held, windows=[],
                            regimes={}, candidates=[]))
        s.cur, s.stop = refit, "no candidate earns its parameters; the slack candidate's refit is kept"
        s.fits.append(refit)

    s.search_effects = search_effects
    s.search_pairs()
    assert s.cur is LINEAR and s.fits == [LINEAR] and s.steps == []
    assert s.stop == "no candidate earns its parameters; no pair of effects earns its place either"
