"""The pair step of a discovery (the plan's stage "pairs"): where the search for effects stopped with
no candidate earning its place, the named laws' shapes are refined, and the model still misses the
record by CRITERIA.unexplained_gap or more, two missing
effects may each explain too little of the gap alone (a creep test with a cubic elastic law: creep
alone cannot follow the stiffness, the cubic alone cannot follow the creep, and the held-out part
refuses both). The refused candidate that lowered the BIC most is fitted beside each other missing
effect, with each of its laws, and the pair is judged as one candidate by the same rules
(judge.pair_verdict). A mixin of search.Search (docs/discovery.md, "Two effects that only earn
their place together")."""

from __future__ import annotations

from dataclasses import replace

from .document import _evidence
from .fitting import _heldout, _side_by_side
from .judge import acts_as_itself, bic_change, heldout_verdict, leaves_unexplained, pair_verdict
from .laws import _models_for, _replaced, _without, candidates
from .records import CandidateResult, Step
from .starts import candidate_starts


class PairStep:
    """The plan's stage "pairs" (search_pairs): pair_of_refused after a step without a winner,
    add_pair where a pair earns its place (search.Search's state)."""

    def pairs_due(self) -> bool:
        """The plan's condition: the search for effects stopped with no candidate earning its place
        (after the named laws' shapes were refined: a law of the wrong shape leaves a gap that a
        pair would take), the model misses the record by CRITERIA.unexplained_gap or more, and the
        budget is not spent."""
        return self.no_winner and not self.budget_hit and leaves_unexplained(self.cur.rms, self.sigma)

    def search_pairs(self) -> None:
        """The search for effects once more from the current model, a step without a winner trying
        pairs; the shapes of the laws it names, refined. Where it names nothing, the search is left
        as it was (its model, fits, steps and stop reason): the stage only adds pairs."""
        before = (self.cur, self.cur_held, list(self.fits), list(self.steps), list(self.removals), self.stop)
        self.no_winner, self.pairs_on = False, True
        self.say(f"searching for effects that earn their place only as a pair (RMS error "
                 f"{self.cur.rms / self.sigma:.2f} x noise)")
        self.search_effects()
        self.pairs_on = False
        if self.cur.effects == before[0].effects:
            self.cur, self.cur_held, self.fits, self.steps, self.removals, stop = before
            self.stop = stop + ("; " + self.out_of_budget("while pairs of effects were fitted") if self.budget_hit
                                else "; no pair of effects earns its place either")
        elif not self.budget_hit:
            self.reshape(self.refined_effects(), where="while the shapes of the laws named as a pair were refined")

    def pair_worth_trying(self, results: list) -> bool:
        """The model misses the record by CRITERIA.unexplained_gap or more, the budget is not spent,
        and a refused candidate lowered the error (a lead for a pair)."""
        return (not self.budget_hit and leaves_unexplained(self.cur.rms, self.sigma)
                and _pair_lead(results, self.cur.rms) is not None)

    def pair_of_refused(self, results: list) -> tuple[CandidateResult, CandidateResult] | None:
        """The lead (the refused candidate with the lowest BIC change) beside each other missing
        effect, each with its laws, fitted from the lead's optimum; the best pair that earns its place
        on the whole record and on the held-out part, as two candidates (the lead's effect and the
        partner's, one fit), or None."""
        lead = _pair_lead(results, self.cur.rms)
        alone = {c.effect: c for c in results if c.fit is not None and c.fit.ok}
        jobs = [(e, new) for e in candidates(self.trace) if e not in self.cur.effects and e != lead.effect
                for new in _models_for(lead.fit.spec, e, self.trace)]
        if not jobs:
            return None
        self.say(f"no effect earns its place alone; {lead.effect} beside each other effect, as a pair")
        factor = self.extension_cap_factor(lead.fit)
        fits = _side_by_side(lambda job, own: self.fit(
            self.trace, job[1], lead.fit.effects + (job[0],), candidate_starts(lead.fit, job[1], self.sc, self.trace),
            self.sc, extra=lead.fit.shape, held=_replaced(lead.fit.shape), own_thread=own, baseline_rms=lead.rms,
            cap_factor=factor), jobs)
        judged = []
        for (e, _), fm in zip(jobs, fits):
            self.say(f"  + {lead.effect} and {e}: RMS error {fm.rms / self.sigma:.2f} x noise ({fm.seconds:.1f} s)")
            if not fm.ok or self.budget_hit:
                continue
            ok, why = self.pair_judged(fm, lead, alone.get(e), e)
            self.say(f"  {lead.effect} and {e}: {'earn' if ok else 'do not earn'} their place: {why}")
            if ok:
                judged.append((bic_change(self.cur, fm, self.n), e, fm, why))
        for _, e, fm, why in sorted(judged, key=lambda j: j[0]):
            pair = self.pair_heldout(lead, alone.get(e), e, fm, why)
            if pair is not None:
                return pair
        return None

    def pair_judged(self, fm, lead: CandidateResult, partner: CandidateResult | None, e: str) -> tuple[bool, str]:
        """The pair's fit ``fm`` against the current model and against each of its effects alone
        (judge.pair_verdict), and each effect acting as itself (judge.acts_as_itself)."""
        cur, sigma = self.cur, self.sigma
        # each effect's model without it: the other effect alone (the current model where that failed)
        without = [(lead.effect, partner.fit if partner is not None else cur), (e, lead.fit)]
        ok, why = pair_verdict(sigma, cur, fm, without, self.n)
        for effect in (lead.effect, e):
            if ok:
                ok, why = acts_as_itself(self.trace, _without(fm.spec, effect), fm, sigma, effect, why)
        return ok, why

    def pair_heldout(self, lead: CandidateResult, partner: CandidateResult | None, e: str, fm, why: str):
        """The pair's held-out test (judge.heldout_verdict); where it passes, the two candidates (the
        partner's with the signature of its own candidate in the step, where it had one)."""
        dk, bic = fm.n_free - self.cur.n_free, bic_change(self.cur, fm, self.n)
        first = replace(lead, model=fm.model, added_parameters=dk, rms=fm.rms, bic_change=bic, fit=fm,
                        part_fit=None, outranked_by="")
        first.part_fit = pf = self.part_fit(first)
        held = _heldout(self.trace, fm.spec, pf.params, self.held_out) if pf.ok else float("inf")
        ok, held_why = heldout_verdict(self.sigma, self.cur_held, held, self.cur.rms, fm.rms)
        self.say(f"  {lead.effect} and {e}: held-out RMS error {held / self.sigma:.2f} x noise (was "
                 f"{self.cur_held / self.sigma:.2f}): {held_why}")
        if not ok or self.budget_hit:
            return None
        both = f"{why}; {held_why}"
        first.heldout_rms, first.accepted = held, True
        first.verdict = f"alone: {lead.verdict}; as a pair with {e}: {both}"
        second = CandidateResult(effect=e, model=fm.model, added_parameters=dk, rms=fm.rms, heldout_rms=held,
                                 bic_change=bic, signature=partner.signature if partner else 0.0,
                                 signature_text=partner.signature_text if partner else "", fit=fm, part_fit=pf,
                                 accepted=True, verdict=f"alone: {partner.verdict if partner else 'not fitted'}; "
                                                        f"as a pair with {lead.effect}: {both}")
        return first, second

    def add_pair(self, pair: tuple, results: list, step: Step, windows: list) -> None:
        """The pair added as two steps from the same model (the lead's step, then the partner's), and
        the effects named before them re-tested beside both."""
        first, second = pair
        cur = self.cur
        step.candidates = [first] + list(results)
        self.add(first, results, step, windows)
        partner = Step(model_before=cur.model, rms_before=cur.rms, heldout_before=step.heldout_before,
                       windows=windows, regimes=step.regimes, candidates=[second])
        self.steps.append(partner)
        partner.effect, partner.rms_after, partner.model_after = second.effect, second.rms, second.label
        partner.evidence = _evidence(second, windows)
        self.say(f"added {first.effect} and {second.effect} as a pair")
        self.retest_named(first.effect, second.effect)


def _pair_lead(results: list, rms: float) -> CandidateResult | None:
    """The refused candidate that lowered the error and the BIC most, or None."""
    refused = [c for c in results if not c.accepted and c.fit is not None and c.fit.ok and c.rms < rms
               and c.bic_change < 0]
    return min(refused, key=lambda c: c.bic_change, default=None)
