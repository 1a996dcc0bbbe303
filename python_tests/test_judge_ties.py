"""Two effects that explain what is left equally well (tether.discover.judge.refuse_tied_effects):
where the best passing candidates of a step are of two effects whose BIC changes lie less than
CRITERIA.effect_tie_bic apart, the record does not tell the effects apart and neither is named; the
verdict of each says so ("undetermined"). The figures are the second generator's open-draw record
b20 (a load test of Findley creep, whose creep grows as sinh of the load): after creep, hysteresis
and a cubic stiffness each took the record from 1.38 to 0.97 x noise, BIC -499 and -498."""
from __future__ import annotations

from tether.discover.judge import CRITERIA, refuse_tied_effects
from tether.discover.records import CandidateResult


def _candidate(effect: str, bic: float, accepted: bool = True) -> CandidateResult:
    return CandidateResult(effect=effect, model=f"linear+{effect}", added_parameters=2, rms=0.97, heldout_rms=1.1,
                           bic_change=bic, signature=0.0, signature_text="", verdict="gap 0.96 -> 0.00 sigma",
                           accepted=accepted)


def test_two_effects_whose_bic_changes_lie_within_the_tie_are_both_refused_and_say_why():
    hyst, stiff, damp = _candidate("hysteresis", -498.7), _candidate("nonlinear_stiffness", -497.7), \
        _candidate("nonlinear_damping", -300.0)
    assert refuse_tied_effects([hyst, stiff, damp])
    assert not (hyst.accepted or stiff.accepted or damp.accepted)
    assert (hyst.tied_with, stiff.tied_with, damp.tied_with) == ("nonlinear_stiffness", "hysteresis", "")
    assert "neither is named" in hyst.verdict and "-499 against -498" in hyst.verdict
    assert "tie" in damp.verdict


def test_a_clear_winner_and_a_single_effect_are_no_tie():
    win, other = _candidate("hysteresis", -510.0), _candidate("nonlinear_stiffness", -510.0 + CRITERIA.effect_tie_bic)
    assert not refuse_tied_effects([win, other])
    assert win.accepted and other.accepted and not win.tied_with      # (the step then outranks the other)
    # two laws of one effect are not two effects; a refused candidate does not tie
    assert not refuse_tied_effects([_candidate("hysteresis", -499.0), _candidate("hysteresis", -498.5)])
    assert not refuse_tied_effects([_candidate("hysteresis", -499.0),
                                    _candidate("nonlinear_stiffness", -498.5, accepted=False)])
