"""The judge: when an effect, a shape or a law earns its place (docs/discovery.md tells why)."""

from __future__ import annotations

import math

import numpy as np

from ..models import ModelSpec
from ..traces import Trace
from .fitting import ModelFit, predict
from .laws import DAMPING_TABLE
from .records import CandidateResult


#: the held-out test judges a shape term only where the final model predicts the held-out part at
#: most this many times worse than it fits the whole record (a lightly damped forced record drifts
#: in phase over its last part whatever the shape: the test then says nothing about the shape)
SHAPE_HELDOUT_INFORMATIVE = 3.0


#: the model reproduces the record when its RMS error is at most this multiple of the noise
WITHIN_NOISE = 1.1


#: the first part of the record the held-out fits see (periodic records: whole periods)
FIT_PART = 0.6


#: a damping candidate whose polynomial c(x) lowers the BIC and leaves at most this fraction of the
#: gap, yet not the fraction the verdict asks, is fitted again with the table of c(x): a damping of
#: another shape (a saturating Gaussian c(x) under a Bouc-Wen force: the polynomial took the gap
#: from 3.78 to 2.54 sigma and the damping went unnamed)
DAMPING_TABLE_TRIGGER = 0.8


def _partial_damping_gain(cr: "CandidateResult", sigma: float, rms_before: float) -> bool:
    """A polynomial damping candidate that closes part of the gap but is not accepted."""
    fm = cr.fit
    if (cr.effect != "nonlinear_damping" or cr.accepted or fm is None or not fm.ok
            or set(DAMPING_TABLE) <= set(fm.shape)):
        return False
    g0, g1 = _gap(rms_before, sigma), _gap(fm.rms, sigma)
    return g0 > 0 and cr.bic_change < 0 and g1 <= DAMPING_TABLE_TRIGGER * g0


def _slack_acts(trace: Trace, spec: ModelSpec, fm: ModelFit, sigma: float, verdict: str) -> tuple[bool, str]:
    """Slack adds no parameter, so a refit with it can win on the optimizer's luck alone (a damping
    table refitted with slack on went 4.9 -> 1.1 x noise on a record that never goes slack, and
    slack got the credit). It earns its place only where it acts: where the fitted model's
    simulation with slack off differs from it by more than a hundredth of the noise."""
    try:
        taut = predict(trace, spec, fm.params)
    except (RuntimeError, ValueError):
        return True, verdict                      # cannot even simulate without slack: it acts
    diff = float(np.max(np.abs(taut - fm.predicted))) if np.all(np.isfinite(taut)) else float("inf")
    if diff > 0.01 * sigma:
        return True, verdict
    return False, (f"slack never acts in the fitted model (with slack off it simulates the same to "
                   f"{diff / sigma:.1g} x noise): the gain is the refit's, not slack's")


def _bic(rms: float, k: int, n: int) -> float:
    return n * math.log(max(rms, 1e-300) ** 2) + k * math.log(n)


def _gap(rms: float, sigma: float) -> float:
    """The part of an RMS error the noise does not explain: sqrt(rms^2 - sigma^2)."""
    return math.sqrt(max(rms ** 2 - sigma ** 2, 0.0))


#: a candidate must shrink the gap above the noise to at most this fraction, on the whole record ...
GAP_FRACTION = 0.5


#: ... and on the held-out part (judged by a fit to the first part only)
HELDOUT_GAP_FRACTION = 0.7


def _required_fraction(base: float, gap_over_noise: float) -> float:
    """The fraction a gap must shrink to: ``base`` for gaps up to 3 sigma, relaxed towards
    base + 0.3 (at 30 sigma and beyond). Where the gap is many times the noise, two missing
    effects may each explain only part of it, and a reduction by a fifth is still far beyond
    anything the noise or a spare parameter could produce."""
    x = min(max(math.log10(max(gap_over_noise, 1e-12) / 3.0), 0.0), 1.0)
    return base + 0.3 * x


#: an effect without parameters of its own (slack) needs a smaller shrink of the gap, at this
#: fraction, and a BIC lower by at least ZERO_PARAMETER_BIC: it cannot bend to the noise, it changes
#: the model only where the record shows the physics (the tether would be in compression)
ZERO_PARAMETER_FRACTION = 0.9


ZERO_PARAMETER_BIC = -10.0


def full_data_verdict(sigma: float, rms_before: float, rms_after: float, bic_change: float,
                      added_parameters: int = 1) -> tuple[bool, str]:
    """Whole record: a lower BIC, and the gap above the noise at most GAP_FRACTION of what it was
    (ZERO_PARAMETER_FRACTION for an effect that adds no parameter)."""
    g0, g1 = _gap(rms_before, sigma), _gap(rms_after, sigma)
    if not g0 > 0 or not rms_after < rms_before:
        return False, f"nothing to gain: RMS error {rms_before / sigma:.2f} -> {rms_after / sigma:.2f} x noise"
    why = []
    zero = added_parameters <= 0
    if not bic_change < (ZERO_PARAMETER_BIC if zero else 0.0):
        why.append(f"BIC changes by {bic_change:+.1f}")
    frac = ZERO_PARAMETER_FRACTION if zero else _required_fraction(GAP_FRACTION, g0 / sigma)
    if not g1 <= frac * g0:
        why.append(f"the gap above the noise shrinks only from {g0 / sigma:.2f} to {g1 / sigma:.2f} sigma")
    if why:
        return False, "; ".join(why)
    return True, f"gap {g0 / sigma:.2f} -> {g1 / sigma:.2f} sigma, BIC {bic_change:+.0f}"


#: a whole-record gap at least this many sigma, at least halved by the candidate: the held-out test
#: is not asked (see heldout_verdict)
GROSS_GAP = 20.0


def heldout_verdict(sigma: float, held_before: float, held_after: float, rms_before: float | None = None,
                    rms_after: float | None = None) -> tuple[bool, str]:
    """The last part of the record, predicted by fits to the first part: the gap above the noise at
    most HELDOUT_GAP_FRACTION of what it was. Not asked when the current model misses the whole
    record grossly (a gap of GROSS_GAP sigma or more) and the candidate at least halves it: then
    the fit to the first part is bent by everything the model still lacks, and its prediction of
    a decayed or quiet last part says little (a free vibration's last 40 % may sit at a few sigma
    while its first part is at a hundred)."""
    if rms_before is not None and rms_after is not None and math.isfinite(rms_after):
        g0, g1 = _gap(rms_before, sigma), _gap(rms_after, sigma)
        if g0 >= GROSS_GAP * sigma and g1 <= 0.5 * g0:
            return True, (f"held-out test not asked: the gap of {g0 / sigma:.0f} sigma is gross and the candidate "
                          f"more than halves it")
    h0, h1 = _gap(held_before, sigma), _gap(held_after, sigma)
    if not h1 <= min(_required_fraction(HELDOUT_GAP_FRACTION, h0 / sigma), 0.9) * h0 or not math.isfinite(held_after):
        return False, f"on the held-out part the gap goes from {h0 / sigma:.2f} to {h1 / sigma:.2f} sigma"
    return True, f"held-out gap {h0 / sigma:.2f} -> {h1 / sigma:.2f} sigma"


def _heldout_judges(held: float, rms: float) -> bool:
    """Whether the held-out prediction can judge a shape or a law: the model predicts the held-out
    part at most SHAPE_HELDOUT_INFORMATIVE times worse than it fits the whole record."""
    return held <= SHAPE_HELDOUT_INFORMATIVE * rms


def _not_kept_for_budget(records) -> None:
    """Refinements judged while the time budget ran out are kept on record, not in the model."""
    for r in records:
        if r.accepted:
            r.accepted = False
            r.verdict += "; not kept: the time budget ran out during this stage"


def _shape_judged(rms_before: float, rms: float, bic: float, held_before: float, held: float, sigma: float,
                  refused: str) -> tuple[bool, str]:
    """The verdict on terms added to a named law's shape: kept on a lower BIC and error on the whole
    record and, where the held-out test was asked (``held`` not NaN), a prediction of the held-out
    part no worse; ``refused``: the verdict where the BIC or the error does not fall."""
    if not (bic < 0.0 and rms < rms_before):
        return False, refused
    if not math.isnan(held) and not held <= held_before:
        return False, (f"RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise, BIC {bic:+.0f}, but the "
                       f"held-out part gets worse: {held_before / sigma:.2f} -> {held / sigma:.2f} x noise")
    return True, f"RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise, BIC {bic:+.0f}, " + (
        f"held-out {held_before / sigma:.2f} -> {held / sigma:.2f} x noise" if math.isfinite(held) else
        f"held-out test not asked: the model predicts the held-out part {held_before / rms_before:.0f} times "
        f"worse than it fits the whole record, a test that cannot judge a shape")
