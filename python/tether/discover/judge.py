"""The judge: every threshold of acceptance in one place (Criteria), the BIC change computed once
(bic_change), and the rules side by side: an effect on the whole record (full_data_verdict) and on
the held-out part (heldout_verdict), slack that must act (_slack_acts), hysteresis whose loops
must earn their place (_loops_open), a friction that must act as dry friction (friction_verdict),
two effects added as a pair (pair_verdict), a shape (_shape_judged), a rival law (_law_judged), two
laws that tie in a step (rival_tie), two optima of one model (optimum_judged: the Iwan bank's
restart in rival.py, the rival branch), and when the damping table is tried (_partial_damping_gain,
table_to_try).
docs/discovery.md, "The criteria, and why", tells the measurements behind each value."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..models import ModelSpec
from ..traces import Trace
from .fitting import ModelFit, predict
from .laws import DAMPING_TABLE, LOOP_TERMS, RIVAL_LAWS, _law_of, takes_damping_table
from .records import CandidateResult


@dataclass(frozen=True)
class Criteria:
    """The thresholds that judge (gaps and errors in units of the noise sigma; the gap of an RMS
    error is sqrt(rms^2 - sigma^2), _gap). One line of why each; the story is docs/discovery.md."""

    #: the model reproduces the record at rms <= within_noise sigma: nothing left to explain
    within_noise: float = 1.1
    #: the held-out test fits this first part of the record (whole periods) and predicts the rest
    fit_part: float = 0.6
    #: an effect must shrink the whole record's gap to this fraction: beyond a spare parameter's reach
    gap_fraction: float = 0.5
    #: ... and the held-out part's gap to this fraction: a law that only bends to the first part fails
    heldout_gap_fraction: float = 0.7
    #: both fractions rise by up to this much for gross gaps: two missing effects may share one gap
    relax_by: float = 0.3
    #: ... from this gap [sigma] on, fully over one decade of gap (log scale)
    relax_from_gap: float = 3.0
    #: the held-out fraction, relaxed, never above this: the held-out part must still improve
    heldout_fraction_cap: float = 0.9
    #: the held-out part is quiet where the model predicts it within the noise (a gap under
    #: unexplained_gap) and misses the whole record by this many times that gap or more: what is
    #: missing lies in the part the fit sees (a dry friction that has stopped the swing), and the
    #: held-out test asks only that the candidate keep predicting it within the noise
    heldout_quiet_ratio: float = 3.0
    #: a whole-record gap this gross [sigma] ...: a fit to the first part is bent by all that is missing
    gross_gap: float = 20.0
    #: ... shrunk to this fraction by the candidate: the held-out test is not asked
    gross_gap_shrink: float = 0.5
    #: an effect without parameters (slack) must shrink the gap to this fraction: it cannot bend to noise
    zero_parameter_fraction: float = 0.9
    #: ... and lower the BIC by this much at least
    zero_parameter_bic: float = -10.0
    #: slack acts only where the model with slack off differs by more than this share of sigma
    slack_acts: float = 0.01
    #: an error lower by less than this share is no gain (fits not carried on, refits not kept)
    least_gain: float = 1e-3
    #: the held-out test judges a shape or a law only where the model predicts the held-out part at
    #: most this many times worse than it fits the whole record (a forced record drifts in phase)
    shape_heldout_informative: float = 3.0
    #: a shape that shrinks the gap to this fraction is not asked the held-out test: a fit of the
    #: first part then drifts along the law's flat directions, and its prediction says little
    shape_gap_shrink: float = 0.5
    #: a polynomial damping that lowers the BIC and leaves at most this fraction of the gap is tried
    #: again with the table of c(x): a damping of another shape
    damping_table_trigger: float = 0.8
    #: the Iwan bank's last stages run where the bank misses the record by this gap [sigma] or more
    iwan_stages_gap: float = 1.0
    #: the final model leaves something unexplained where its gap is this many sigma or more (RMS
    #: error >= 1.41 x noise): the residual then holds at least as much as the noise itself; a
    #: refined model that misses by less is not searched again for a further effect
    unexplained_gap: float = 1.0
    #: a Coulomb friction acts as dry friction only where the model's speed (its 90th percentile
    #: over the record) reaches this many times its smoothing coulomb_v (tanh(3) = 0.995: the force
    #: at full size in the fast part of the motion); a smoothing wider than that is a viscous
    #: damping that saturates with speed, which made up for another law's shape
    friction_saturates: float = 3.0
    #: two laws of one effect tie in the step that names it where the loser's gap is at most this
    #: multiple of the winner's: fitted beside the effects named so far, they are not told apart
    #: there, and an effect named later may decide (branch.py carries the loser on)
    rival_tie: float = 1.25
    #: two effects tie in a step where both pass and their BIC changes differ by less than this: the
    #: record does not tell them apart (a BIC difference under 2 is "not worth more than a bare
    #: mention", Kass and Raftery 1995), and naming either would be a guess: neither is named
    effect_tie_bic: float = 2.0


#: the criteria every discovery run judges by
CRITERIA = Criteria()


def bic_change(before: ModelFit, after: ModelFit, n: int) -> float:
    """The BIC of ``after`` less that of ``before``, on the n samples both were fitted to (BIC =
    n ln(rms^2) + k ln(n), k the free parameters); +inf where ``after``'s fit failed."""
    if not after.ok:
        return float("inf")
    return _bic(after.rms, after.n_free, n) - _bic(before.rms, before.n_free, n)


def rival_tie(win: CandidateResult, others: Sequence[CandidateResult], sigma: float) -> CandidateResult | None:
    """The candidate of ``win``'s rival law (RIVAL_LAWS) that passes the whole record's rule and
    misses it by a gap at most CRITERIA.rival_tie times the winner's (the closest such); None where
    there is none."""
    law, rivals = _law_of(win.fit.spec, win.effect), RIVAL_LAWS.get(win.effect, ())
    if law not in rivals:
        return None
    others_laws = set(rivals) - {law}
    tied = [c for c in others if c.accepted and c.fit is not None and c.fit.ok
            and _law_of(c.fit.spec, c.effect) in others_laws
            and _gap(c.rms, sigma) <= CRITERIA.rival_tie * _gap(win.rms, sigma)]
    return min(tied, key=lambda c: c.rms, default=None)


def refuse_tied_effects(results: Sequence, rank: Callable[[object], float] | None = None) -> bool:
    """Where the best passing candidate of a step and the best passing one of another effect lower
    the BIC by amounts less than CRITERIA.effect_tie_bic apart, the record cannot tell the two
    effects apart: every passing candidate is refused, the two tied ones saying so (tied_with).
    ``rank``: the BIC change a step ranks by (a candidate's bic_change; a campaign's, each record's
    against its own). True where they tie."""
    rank = rank or (lambda c: c.bic_change)
    passing = sorted((c for c in results if c.accepted), key=rank)
    if not passing:
        return False
    win = passing[0]
    other = next((c for c in passing[1:] if c.effect != win.effect), None)
    if other is None or not rank(other) - rank(win) < CRITERIA.effect_tie_bic:
        return False
    for a, b in ((win, other), (other, win)):
        a.tied_with = b.effect
        a.verdict += (f"; passes, but so does {b.effect} (BIC {rank(a):+.0f} against {rank(b):+.0f}, less "
                      f"than {CRITERIA.effect_tie_bic:g} apart): the record does not tell the two apart, and neither "
                      f"is named")
    for c in passing:
        c.accepted = False
        if c is not win and c is not other:
            c.verdict += f"; passes, but {win.effect} and {other.effect} do better and tie"
    return True


def tie_stop_reason(tied: Sequence[str]) -> str:
    """Why a search stops where two effects tie (refuse_tied_effects)."""
    return (f"{' and '.join(tied)} explain what is left equally well (their BIC changes less than "
            f"{CRITERIA.effect_tie_bic:g} apart): neither is named")


def slack_heldout_unasked(added_parameters: int, slack_in_held_part: bool) -> str | None:
    """Why the held-out test is not asked of slack, or None where it is: slack adds no parameter to
    overfit with, and a record that goes slack only in the part a fit sees leaves nothing for the
    held-out part to judge."""
    if added_parameters == 0 and not slack_in_held_part:
        return ("held-out test not asked: the record goes slack only in the part the fit sees, and slack adds "
                "no parameter")
    return None


def same_terms(a: ModelFit, b: ModelFit) -> bool:
    """Whether two fits are of one model with the same free terms (two optima of one least-squares
    problem)."""
    return a.spec == b.spec and sorted(a.free) == sorted(b.free)


def optimum_judged(rms_before: float, rms: float, sigma: float) -> tuple[bool, str]:
    """The verdict between two optima of one model with the same free terms (same_terms: the Iwan
    bank's idle elements restarted, the search carried on by another path): the lower error is the
    better fit of the same model; what the model adds was judged when it was built."""
    if rms < rms_before:
        return True, (f"the same model with the same terms at another optimum: RMS error {rms_before / sigma:.2f} -> "
                      f"{rms / sigma:.2f} x noise")
    return False, f"the same model with the same terms: RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise"


def _partial_damping_gain(cr: "CandidateResult", sigma: float, rms_before: float) -> bool:
    """A polynomial damping candidate that closes part of the gap but is not accepted."""
    fm = cr.fit
    if cr.effect != "nonlinear_damping" or cr.accepted or fm is None or not fm.ok or not table_to_try(fm):
        return False
    g0, g1 = _gap(rms_before, sigma), _gap(fm.rms, sigma)
    return g0 > 0 and cr.bic_change < 0 and g1 <= CRITERIA.damping_table_trigger * g0


def table_to_try(fm: ModelFit) -> bool:
    """Whether the table of c(x) is still to try on ``fm``: its damping law takes the table
    (laws.takes_damping_table: c(x), not the Coulomb friction) and the fit has not freed it yet."""
    return takes_damping_table(fm.spec) and not set(DAMPING_TABLE) <= set(fm.shape)


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
    if diff > CRITERIA.slack_acts * sigma:
        return True, verdict
    return False, (f"slack never acts in the fitted model (with slack off it simulates the same to "
                   f"{diff / sigma:.1g} x noise): the gain is the refit's, not slack's")


def acts_as_itself(trace: Trace, spec: ModelSpec, fm: ModelFit, sigma: float, effect: str,
                   verdict: str) -> tuple[bool, str]:
    """An effect that passes on the error earns its place only by what it does: slack where it acts
    (_slack_acts; ``spec`` the model before it), hysteresis where its loops do (_loops_open), a
    Coulomb friction where its force saturates (friction_verdict)."""
    if effect == "slack":
        return _slack_acts(trace, spec, fm, sigma, verdict)
    if effect == "hysteresis":
        return _loops_open(trace, fm, sigma, verdict)
    if effect == "nonlinear_damping":
        return friction_verdict(fm.spec, fm.params, lambda: [model_speed(trace, fm.predicted)], verdict)
    return True, verdict


def model_speed(trace: Trace, predicted: np.ndarray | None) -> np.ndarray:
    """The elongation rate of a payload record's fitted model (the derivative of its predicted
    displacement; of the measured one where there is no prediction)."""
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured if predicted is None or len(predicted) != len(t) else predicted, float)
    return np.gradient(y, t) if len(t) > 1 else np.zeros(len(t))


def friction_verdict(spec: ModelSpec, params: dict, speeds: Callable[[], Sequence[np.ndarray]],
                     verdict: str) -> tuple[bool, str]:
    """A damping law with Coulomb friction earns its place only where the friction acts as dry
    friction on some record (``speeds()``: the model's speed along each, asked for only where the
    law has the friction): where its speed reaches CRITERIA.friction_saturates times the smoothing
    coulomb_v."""
    if spec.damping != "coulomb":
        return True, verdict
    v_s = float(params.get("coulomb_v", 0.0))
    fast = max((float(np.percentile(np.abs(v), 90)) for v in speeds() if len(v)), default=0.0)
    if fast >= CRITERIA.friction_saturates * v_s:
        return True, verdict
    return False, (f"its friction does not act as dry friction: its sign is smoothed over coulomb_v = {v_s:.3g} m/s "
                   f"and the model's speed reaches {fast:.3g} m/s (90th percentile), less than "
                   f"{CRITERIA.friction_saturates:g} times that: a viscous damping that saturates with speed")


def closed_loops(spec: ModelSpec, params: dict) -> tuple[dict, tuple]:
    """``params`` with the loop terms of ``spec``'s hysteresis law at zero (Law.loop_terms: the law
    is then an elastic curve), and those terms; ``params`` and () where the law has none."""
    terms = LOOP_TERMS.get(_law_of(spec, "hysteresis"), ())
    return {**params, **{k: 0.0 for k in terms}}, terms


def loops_verdict(sigma: float, rms_closed: float, rms: float, free: list, terms: tuple, n: int,
                  verdict: str) -> tuple[bool, str]:
    """A hysteresis candidate (RMS error ``rms``, ``free`` its free terms) earns its place only where its
    loops do, by the whole record's rule against the same fit with them closed (``rms_closed``; no
    refit: a bound in the loops' favour). A Bouc-Wen force with beta = 0 and gamma < 0 followed a
    log-cosh stiffness the cubic missed, and hysteresis was named for it."""
    if not terms or not math.isfinite(rms_closed):
        return True, verdict
    k = len([t for t in terms if t in free])
    bic = _bic(rms, len(free), n) - _bic(rms_closed, len(free) - k, n)
    ok, why = full_data_verdict(sigma, rms_closed, rms, bic, k)
    if ok:
        return True, verdict
    return False, (f"its loops do not earn their place: with {', '.join(terms)} at zero (no loop) the fitted "
                   f"model simulates to {rms_closed / sigma:.2f} x noise against {rms / sigma:.2f} ({why}): the "
                   f"gain is an elastic curve's, not hysteresis's")


def _loops_open(trace: Trace, fm: ModelFit, sigma: float, verdict: str) -> tuple[bool, str]:
    """loops_verdict on one record."""
    params, terms = closed_loops(fm.spec, fm.params)
    if not terms:
        return True, verdict
    try:
        closed = predict(trace, fm.spec, params)
    except (RuntimeError, ValueError):
        return True, verdict                      # cannot simulate with the loops closed: they act
    rms = float(np.sqrt(np.mean((closed - np.asarray(trace.measured, float)) ** 2)))
    return loops_verdict(sigma, rms, fm.rms, fm.free, terms, len(trace.measured), verdict)


def _bic(rms: float, k: int, n: int) -> float:
    return n * math.log(max(rms, 1e-300) ** 2) + k * math.log(n)


def _gap(rms: float, sigma: float) -> float:
    """The part of an RMS error the noise does not explain: sqrt(rms^2 - sigma^2)."""
    return math.sqrt(max(rms ** 2 - sigma ** 2, 0.0))


def leaves_unexplained(rms: float, sigma: float) -> bool:
    """Whether a model that misses a record by ``rms`` (its noise ``sigma``) leaves something
    unexplained: a gap above the noise of CRITERIA.unexplained_gap sigma or more."""
    return _gap(rms, sigma) >= CRITERIA.unexplained_gap * sigma


def _required_fraction(base: float, gap_over_noise: float) -> float:
    """The fraction a gap must shrink to: ``base`` for gaps up to CRITERIA.relax_from_gap (3 sigma),
    relaxed towards base + CRITERIA.relax_by (0.3; at ten times that gap and beyond). Where the gap
    is many times the noise, two missing effects may each explain only part of it, and a reduction
    by a fifth is still far beyond anything the noise or a spare parameter could produce."""
    x = min(max(math.log10(max(gap_over_noise, 1e-12) / CRITERIA.relax_from_gap), 0.0), 1.0)
    return base + CRITERIA.relax_by * x


def full_data_verdict(sigma: float, rms_before: float, rms_after: float, bic_change: float,
                      added_parameters: int = 1) -> tuple[bool, str]:
    """Whole record: a lower BIC, and the gap above the noise at most CRITERIA.gap_fraction of what it
    was (an effect that adds no parameter: CRITERIA.zero_parameter_fraction, and a BIC lower by
    CRITERIA.zero_parameter_bic)."""
    g0, g1 = _gap(rms_before, sigma), _gap(rms_after, sigma)
    if not g0 > 0 or not rms_after < rms_before:
        return False, f"nothing to gain: RMS error {rms_before / sigma:.2f} -> {rms_after / sigma:.2f} x noise"
    why = []
    zero = added_parameters <= 0
    if not bic_change < (CRITERIA.zero_parameter_bic if zero else 0.0):
        why.append(f"BIC changes by {bic_change:+.1f}")
    frac = CRITERIA.zero_parameter_fraction if zero else _required_fraction(CRITERIA.gap_fraction, g0 / sigma)
    if not g1 <= frac * g0:
        why.append(f"the gap above the noise shrinks only from {g0 / sigma:.2f} to {g1 / sigma:.2f} sigma")
    if why:
        return False, "; ".join(why)
    return True, f"gap {g0 / sigma:.2f} -> {g1 / sigma:.2f} sigma, BIC {bic_change:+.0f}"


def retest_verdict(sigma: float, rms_without: float, rms_with: float, bic_change: float,
                   added_parameters: int) -> tuple[bool, str]:
    """A named effect tested again, the model refitted without it: kept where it earns its place by the
    whole record's rule (full_data_verdict), but not where the model without it reproduces the record
    within the noise (CRITERIA.within_noise): the search adds nothing to such a model, and a re-test
    keeps nothing the search would not have added."""
    if rms_without <= CRITERIA.within_noise * sigma:
        return False, within_noise_without(rms_without / sigma)
    return full_data_verdict(sigma, rms_without, rms_with, bic_change, added_parameters)


def within_noise_without(rms_over_noise: float) -> str:
    """Why a re-test removes an effect the model reproduces the record without (retest_verdict)."""
    return f"without it the model reproduces the record within the noise (RMS error {rms_over_noise:.2f} x noise)"


def pair_verdict(sigma: float, cur: ModelFit, fm: ModelFit, without: Sequence, n: int) -> tuple[bool, str]:
    """Two effects added together (the fit ``fm``): the pair earns its place against the current
    model ``cur`` by the whole record's rule (full_data_verdict, with the parameters of both), and
    each effect earns its own by the same rule against the pair's model without it (``without``:
    (effect, fit of the model without it)): a pair is not a lone effect with a passenger."""
    ok, why = full_data_verdict(sigma, cur.rms, fm.rms, bic_change(cur, fm, n), fm.n_free - cur.n_free)
    if not ok:
        return False, why
    for effect, rf in without:
        keep, own = full_data_verdict(sigma, rf.rms, fm.rms, bic_change(rf, fm, n), fm.n_free - rf.n_free)
        if not keep:
            return False, f"{why}, but {effect} does not earn its place beside the other: {own}"
    return True, why


def heldout_verdict(sigma: float, held_before: float, held_after: float, rms_before: float | None = None,
                    rms_after: float | None = None) -> tuple[bool, str]:
    """The last part of the record, predicted by fits to the first part: the gap above the noise at
    most CRITERIA.heldout_gap_fraction of what it was. Not asked when the current model misses the
    whole record grossly (a gap of CRITERIA.gross_gap sigma or more) and the candidate at least
    halves it (CRITERIA.gross_gap_shrink): then
    the fit to the first part is bent by everything the model still lacks, and its prediction of
    a decayed or quiet last part says little (a free vibration's last 40 % may sit at a few sigma
    while its first part is at a hundred). Where the held-out part is quiet (_heldout_quiet), the
    candidate must only keep predicting it within the noise."""
    if rms_before is not None and rms_after is not None and math.isfinite(rms_after):
        g0, g1 = _gap(rms_before, sigma), _gap(rms_after, sigma)
        if g0 >= CRITERIA.gross_gap * sigma and g1 <= CRITERIA.gross_gap_shrink * g0:
            return True, (f"held-out test not asked: the gap of {g0 / sigma:.0f} sigma is gross and the candidate "
                          f"more than halves it")
    h0, h1 = _gap(held_before, sigma), _gap(held_after, sigma)
    whole = None if rms_before is None else _gap(rms_before, sigma)
    if whole is not None and _heldout_quiet(h0, whole, sigma):
        if h1 < CRITERIA.unexplained_gap * sigma:
            return True, (f"held-out test not asked: the model predicts the held-out part within the noise (gap "
                          f"{h0 / sigma:.2f} sigma) and misses the whole record by {whole / sigma:.2f} "
                          f"sigma; the candidate predicts it within the noise too ({h1 / sigma:.2f} sigma)")
        return False, f"on the quiet held-out part the gap goes from {h0 / sigma:.2f} to {h1 / sigma:.2f} sigma"
    frac = min(_required_fraction(CRITERIA.heldout_gap_fraction, h0 / sigma), CRITERIA.heldout_fraction_cap)
    if not h1 <= frac * h0 or not math.isfinite(held_after):
        return False, f"on the held-out part the gap goes from {h0 / sigma:.2f} to {h1 / sigma:.2f} sigma"
    return True, f"held-out gap {h0 / sigma:.2f} -> {h1 / sigma:.2f} sigma"


def _heldout_quiet(held_gap: float, whole_gap: float, sigma: float) -> bool:
    """Whether the held-out part holds nothing the model misses while the whole record does
    (CRITERIA.heldout_quiet_ratio): it cannot show what a candidate adds there."""
    within = CRITERIA.unexplained_gap * sigma
    return held_gap < within and whole_gap >= CRITERIA.heldout_quiet_ratio * within


def _heldout_judges(held: float, rms: float) -> bool:
    """Whether the held-out prediction can judge a shape or a law: the model predicts the held-out
    part at most CRITERIA.shape_heldout_informative times worse than it fits the whole record."""
    return held <= CRITERIA.shape_heldout_informative * rms


def _shape_heldout_asked(rms_before: float, held_before: float, rms: float, sigma: float) -> bool:
    """Whether a shape (or a finer bank) that fits the whole record at ``rms`` is asked the held-out
    test: where that prediction can judge (_heldout_judges) and the shape does not shrink the gap to
    CRITERIA.shape_gap_shrink or less (the law is named already; the docs say why)."""
    return _heldout_judges(held_before, rms_before) and not _shape_shrinks_gap(rms_before, rms, sigma)


def _shape_shrinks_gap(rms_before: float, rms: float, sigma: float) -> bool:
    return _gap(rms, sigma) <= CRITERIA.shape_gap_shrink * _gap(rms_before, sigma)


def retested_beside_refinements(effects, base_effects, changed) -> list:
    """Of the model's ``effects`` the search named (not in ``base_effects``), those to test again
    after the last stages changed the laws of the effects ``changed``: every one but an effect whose
    own law is the only one that changed (a better law only adds to what it earns), each beside the
    laws that changed (where a stiffness and a hysteresis law both changed, each is tested beside
    the other's new law: a cubic named while the hysteresis law was Bouc-Wen's need not earn its
    place beside a finer Iwan bank). Only the changed laws still in the model count: a law removed
    by an earlier re-test is nothing to be tested beside."""
    still = set(changed) & set(effects)
    return [e for e in effects if e not in base_effects and still - {e}]


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
        f"held-out test not asked: the gap above the noise shrinks from {_gap(rms_before, sigma) / sigma:.2f} to "
        f"{_gap(rms, sigma) / sigma:.2f} sigma" if _shape_shrinks_gap(rms_before, rms, sigma) else
        f"held-out test not asked: the model predicts the held-out part {held_before / rms_before:.0f} times "
        f"worse than it fits the whole record, a test that cannot judge a shape")


def _law_judged(rms_before: float, rms: float, bic: float, held_before: float, held: float, sigma: float,
                law: str) -> tuple[bool, str]:
    """The verdict on an effect's law replaced by another (the rival law, a wider law, the rival
    branch): kept on a lower BIC and error on the whole record and, where the held-out test is asked
    as for a shape (_shape_heldout_asked: the prediction can judge, and the new law does not shrink
    the gap to CRITERIA.shape_gap_shrink or less), a prediction of the held-out part no worse.
    ``held``: the new law's held-out error, NaN where the whole record refused it (its fit of the
    first part not run); ``law``: the law in place."""
    if not (bic < 0.0 and rms < rms_before):
        return False, (f"RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise, BIC changes by {bic:+.1f}: "
                       f"the {law} law stays")
    asked = _shape_heldout_asked(rms_before, held_before, rms, sigma)
    if asked and not held <= held_before:
        return False, (f"RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise, BIC {bic:+.0f}, but the "
                       f"held-out part gets worse: {held_before / sigma:.2f} -> {held / sigma:.2f} x noise")
    if asked:
        why = ""
    elif _shape_shrinks_gap(rms_before, rms, sigma):
        why = (f" (not judged on it: the gap above the noise shrinks from {_gap(rms_before, sigma) / sigma:.2f} to "
               f"{_gap(rms, sigma) / sigma:.2f} sigma)")
    else:
        why = (f" (not judged on it: the model predicts the held-out part {held_before / rms_before:.0f} "
               f"times worse than it fits the whole record)")
    return True, (f"RMS error {rms_before / sigma:.2f} -> {rms / sigma:.2f} x noise, BIC {bic:+.0f}, held-out "
                  f"{held_before / sigma:.2f} -> {held / sigma:.2f} x noise" + why)
