"""The held-out rule of discovery's judge (tether.discover.judge.heldout_verdict) on a quiet held-out
part: where the model already predicts the last part of the record within the noise and misses the
whole record by a few sigma, that part cannot show what a candidate adds (a dry friction that has
stopped the swing before the held-out part begins), and the candidate must only keep predicting it
within the noise. Errors in units of the noise (sigma = 1)."""
from __future__ import annotations

import math

from tether.discover.judge import CRITERIA, heldout_verdict


def _rms(gap: float) -> float:
    """The RMS error whose gap above the noise is ``gap`` sigma."""
    return math.sqrt(1.0 + gap ** 2)


def test_a_quiet_held_out_part_asks_only_that_the_candidate_keep_it_within_the_noise():
    # open-draw record b13, step 4: Bouc-Wen and slack at 5.19 x noise (gap 5.09), the held-out part at a
    # gap of 0.09; the dry friction takes the whole record to 0.99 x and the held-out part to 0.10
    ok, why = heldout_verdict(1.0, _rms(0.09), _rms(0.10), 5.19, 0.99)
    assert ok and "not asked" in why and "0.09" in why
    # a candidate that spoils the quiet part is refused
    ok, why = heldout_verdict(1.0, _rms(0.09), _rms(2.0), 5.19, 0.99)
    assert not ok and "quiet" in why


def test_the_quiet_rule_needs_a_whole_record_gap_of_a_few_sigma():
    # the whole record at a gap under CRITERIA.heldout_quiet_ratio sigma: the usual rule (the held-out gap
    # must shrink), which refuses a candidate that leaves it as it was
    whole = _rms(0.9 * CRITERIA.heldout_quiet_ratio * CRITERIA.unexplained_gap)
    ok, why = heldout_verdict(1.0, _rms(0.5), _rms(0.5), whole, 1.0)
    assert not ok and "quiet" not in why
    ok, _ = heldout_verdict(1.0, _rms(0.5), _rms(0.5), _rms(1.1 * CRITERIA.heldout_quiet_ratio), 1.0)
    assert ok


def test_a_held_out_part_that_misses_is_judged_as_before():
    # the held-out part at a gap of 2 sigma (not quiet): the gap must shrink to the fraction
    assert not heldout_verdict(1.0, _rms(2.0), _rms(1.9), 5.19, 0.99)[0]
    assert heldout_verdict(1.0, _rms(2.0), _rms(0.5), 5.19, 0.99)[0]
