"""One step of a campaign discovery (discover.campaign): the candidate effects, each fitted to every
record (Campaign.candidate_fit), judged by the one judge on the campaign's error in noise units and on
the held-out parts, ranked by each record's error against its own, the best that passes added, with
who revealed it. A mixin of discover.campaign.Campaign (docs/campaign-discovery.md, "The search")."""

from __future__ import annotations

import math

import numpy as np

from ..models import EFFECTS, ModelSpec
from .campaign_records import CampaignCandidate, CampaignFit, CampaignStep, in_noise_units, ranked_bic_change
from .evidence import regimes
from .fitting import ModelFit, _side_by_side, fit_cost
from .judge import (_bic, _gap, _slack_acts, bic_change, closed_loops, friction_verdict, full_data_verdict,
                    heldout_verdict, leaves_unexplained, loops_verdict, model_speed, refuse_tied_effects,
                    slack_heldout_unasked, tie_stop_reason)
from .laws import (EFFECT, RIVAL_LAWS, WIDER_LAWS, _law_of, _models_for, _with_law, candidates,
                   tried_in_campaigns, unrevealed)
from .starts import candidate_starts


class Steps:
    """The steps of discover.campaign.Campaign (its records, current fit, candidate fits and settle)."""

    def candidate_models(self) -> list:
        """(effect, model, lead record, starts) of every candidate: the effects any record can reveal
        that the model lacks, each with its laws (laws._models_for; Kawabata's branches only where
        every record is a load test); its lead, of the records that can reveal it the one the model
        misses most (in units of its noise), and the one-record search's starts on that record;
        Campaign.lead_fit may lead the candidate's fit by another record that can reveal it."""
        out = []
        payload = any(r.trace.rig == "payload" for r in self.records)
        for e in EFFECTS:
            able = [i for i, r in enumerate(self.records) if e in candidates(r.trace)]
            if not able or e in self.cur.effects:
                continue
            i = self.worst_record(self.cur, able)
            for new in _models_for(self.cur.spec, e, self.records[i].trace):
                if (payload and new.hysteresis == "kawabata") or not tried_in_campaigns(e, new):
                    continue
                out.append((e, new, i, self.starts_on(i, new)))
        return out

    def led_by(self, cands: list, fits: list) -> list:
        """The candidates (effect, model, lead, starts) with the lead each fit took (Campaign.lead_fit)
        and its starts."""
        return [c if f.lead is None or f.lead == c[2] else (c[0], c[1], f.lead, self.starts_on(f.lead, c[1]))
                for c, f in zip(cands, fits)]

    def starts_on(self, i: int, new: ModelSpec) -> list:
        """The one-record search's starts of ``new`` (the current model and one effect) on record i,
        warm from the current model with the record's nuisance values (starts.candidate_starts)."""
        r = self.records[i]
        base = ModelFit(spec=self.cur.spec.for_experiment(r.trace.experiment), effects=self.cur.effects,
                        params={**self.cur.params, **r.nz}, free=list(self.cur.free), rms=self.cur.rms_records[i],
                        predicted=self.cur.predicted[i])
        return candidate_starts(base, new.for_experiment(r.trace.experiment), r.sc, r.trace)

    def wider_candidates(self, cands: list, fits: list) -> list:
        """(effect, model, lead, starts) of the wider law (laws.WIDER_LAWS) of each candidate whose
        own law does not reveal its effect on its lead record (reveals: the record that shows the
        effect best, by the one-record rule on its own samples) and leaves that record unexplained
        (a gap of CRITERIA.unexplained_gap or more): fitted in the same step as a law of the same
        effect, where the lead's rig tries it. The wider law is otherwise tried only at the end and
        only for a named effect (wider_laws): an effect whose own law cannot reproduce the record
        that reveals it earns its place, if at all, on the records that cannot, and may never be
        named to be widened (docs/campaign-discovery.md, fourth round)."""
        out = []
        for (e, new, i, _), f in zip(cands, fits):
            other = self.wider_law_model(e, new, i) if f.ok else None
            if other is None:
                continue
            r = self.records[i]
            added = f.n_free - self.cur.n_free
            if (self.reveals(i, self.cur.rms_records[i], f.rms_records[i], added)
                    or not leaves_unexplained(f.rms_records[i], r.sigma)):
                continue
            self.say(f"  {e}: its law {_law_of(new, e)} leaves {r.name} at {f.rms_records[i] / r.sigma:.2f} x its "
                     f"noise ({self.cur.rms_records[i] / r.sigma:.2f} before): the wider law {_law_of(other, e)} "
                     f"is fitted too")
            out.append((e, other, i, self.starts_on(i, other)))
        return out

    def wider_law_model(self, e: str, new: ModelSpec, i: int) -> ModelSpec | None:
        """``new`` with effect ``e``'s wider law (laws.WIDER_LAWS) in place of its own, where ``new``
        has the own law and record i's rig tries the wider one; None otherwise."""
        law, wider = WIDER_LAWS.get(e, (None, None))
        if law is None or _law_of(new, e) != law:
            return None
        if not EFFECT[e].law(wider).tried_on(self.records[i].trace.rig):
            return None
        return _with_law(new, e, wider)

    def reveals(self, i: int, before: float, after: float, added: int) -> bool:
        """Does a model with ``added`` parameters more, record i's error going from ``before`` to
        ``after``, earn its place on that record's samples alone (the one-record rule: its own gap at
        most halved, its own BIC lower)?"""
        r = self.records[i]
        bic = _bic(after, added, r.n) - _bic(before, 0, r.n)
        return full_data_verdict(r.sigma, before, after, bic, added)[0]

    def step(self) -> bool:
        cands = self.candidate_models()
        if not cands:
            self.stop = "no effect is left that a record can reveal"
            return False
        self.say(f"step {len(self.steps) + 1}: {len(cands)} candidates on {len(self.records)} records")
        before = self.cur
        factor = 1.0 if before is self.fits[0] else self.cap_factor_for(before)
        refit = self.refit_current(factor)
        cur = self.cur
        if self.within_noise(cur):
            return True                 # the run stops there: every record within the noise
        if self.refine_first():
            return True                 # the next step starts from the refined laws
        if cur is not before:
            cands = self.candidate_models()     # their leads and starts from the refitted model

        def fitted(c, own):
            return self.candidate_fit(c[0], c[1], cur.effects + (c[0],), c[2], c[3], own, factor)

        def cost(c):
            return fit_cost(c[1], self.records[c[2]].trace.experiment)

        fits = _side_by_side(fitted, cands, cost=cost)
        cands = self.led_by(cands, fits)
        wider = [] if self.budget_hit else self.wider_candidates(cands, fits)
        cands, fits = cands + wider, fits + _side_by_side(fitted, wider, cost=cost)
        results = self.judge_all(cands, fits)
        if self.budget_hit:
            self.stop = f"the time budget of {self.budget:.0f} s was spent during step {len(self.steps) + 1}"
            return False
        passing = [c for c in results if c.accepted]
        win = self.heldout_tests(passing)
        tied = [c.effect for c in passing if c.tied_with]
        if win is None and passing and not tied and not self.budget_hit:
            win, wider_results = self.wider_after_heldout(passing, cands, fitted)
            results += wider_results
        step = CampaignStep(effect=None, model_before=cur.model, model_after=None, rms_before=cur.rms, rms_after=None,
                            records_before=list(cur.rms_records), records_after=None, candidates=results,
                            fit_before=cur, refit=refit)
        self.steps.append(step)
        if win is None:
            self.stop = tie_stop_reason(tied) if tied else "no candidate earns its parameters on the campaign"
            return False
        self.add(step, win)
        if not self.budget_hit:
            self.retest_named(step)
        return True


    def judge_all(self, cands: list, fits: list) -> list:
        """Each candidate judged (judge) and reported; the best of each effect (passing first, then
        by the records' BIC change), ranked by the records' BIC change. Each law's fit is kept for
        the rival law at the end (rival_law)."""
        by_effect: dict = {}
        for (e, new, _, _), f in zip(cands, fits):
            if e in RIVAL_LAWS and f.ok:
                self.rivals.setdefault(e, {})[_law_of(new, e)] = dict(f.params)
            c = self.judge(e, f)
            self.say(f"  + {e} ({new.canonical}): campaign RMS error {f.rms:.2f} x noise ({self.per_record(f)}), "
                     f"BIC {c.bic_change:+.0f}, by record {c.records_bic_change:+.0f}"
                     + (" passes" if c.accepted else f": {c.verdict}") + f" ({f.seconds:.1f} s)")
            if e not in by_effect or ((c.accepted, -c.records_bic_change)
                                      > (by_effect[e].accepted, -by_effect[e].records_bic_change)):
                by_effect[e] = c
        return sorted(by_effect.values(), key=lambda c: c.records_bic_change)

    def wider_after_heldout(self, refused: list, cands: list, fitted) -> tuple:
        """Where every candidate that passed on the whole campaign failed its held-out test: each of
        them in its effect's own law fitted again with the wider law (laws.WIDER_LAWS), where this
        step has not fitted that law, and judged the same way (the whole campaign, then the held-out
        parts). Two laws that fit the records alike may extrapolate unlike: the held-out test is
        the one that tells them apart, so the wider law must reach it (docs/campaign-discovery.md,
        session 37). (the winner or None, the wider laws' candidates as judge_all ranks them)"""
        done = {(e, _law_of(new, e)) for e, new, _, _ in cands}
        more = []
        for c in refused:
            e, law = c.effect, _law_of(c.fit.spec, c.effect)
            _, new, i, _ = next(x for x in cands if x[0] == e and _law_of(x[1], e) == law)
            other = self.wider_law_model(e, new, i)
            if other is not None and (e, _law_of(other, e)) not in done:
                more.append((e, other, i, self.starts_on(i, other)))
        if not more:
            return None, []
        self.say("  no candidate passes its held-out test: the wider law of "
                 + ", ".join(f"{e} ({_law_of(x, e)})" for e, x, _, _ in more) + " is fitted too")
        results = self.judge_all(more, _side_by_side(fitted, more))
        return self.heldout_tests([c for c in results if c.accepted]), results

    def refit_current(self, factor: float) -> dict:
        """The current model fitted the way its candidates are (candidate_fit with no effect added,
        its lead the record it misses most), so that no candidate is credited with what that refit
        alone gains (docs/campaign-discovery.md, fifth round); where it lowers the campaign's error
        it is settled and carried on as the current state, against which every candidate is judged."""
        cur = self.cur
        i = self.worst_record(cur)
        f = self.candidate_fit("", cur.spec, cur.effects, i, self.starts_on(i, cur.spec), cap_factor=factor)
        kept = f.ok and f.rms < cur.rms and not self.budget_hit
        self.say(f"  the current model {cur.model} fitted as a candidate is (lead {self.records[i].name}): "
                 f"{cur.rms:.2f} -> {f.rms:.2f} x noise ({self.per_record(f) if f.ok else f.message}): "
                 + ("carried on" if kept else "kept as it was") + f" ({f.seconds:.1f} s)")
        if kept:
            self.adopt(f)
        return {"rmse_over_noise_before": cur.rms, "rmse_over_noise_refit": f.rms, "kept": kept}

    def heldout_tests(self, passing: list) -> CampaignCandidate | None:
        """The held-out test, best first, for up to ``heldout_candidates`` of the candidates that
        pass on the whole campaign, more while none of those passes it (Search.heldout_tests' rule;
        testing only the best two, a campaign of seed 1000 stopped where the cubic law and a
        damping ranked above creep on the BIC); the rest are not tested. Each is judged on the
        held-out parts of the records that show its effect (showing), before and after: another
        record's part moves with the shared law, not with the effect, as in add().
        Slack is not asked where no such record goes slack in its held-out part (the one-record
        rule, judge.slack_heldout_unasked). The winner: the best that passes."""
        cur, win, tested = self.cur, None, 0
        before: dict = {}
        for c in passing:
            if tested >= self.heldout_candidates and win is not None:
                break
            tested += 1
            able = self.showing(c)
            unasked = c.effect == "slack" and slack_heldout_unasked(
                c.added_parameters, self.slack_in_held_parts(c.fit, able))
            if unasked:
                ok, why = True, unasked
            else:
                if able not in before:
                    before[able] = self.cur_held if able is None else self.heldout_of(cur, able)
                c.heldout_rms = self.heldout_of(c.fit, able)
                ok, why = heldout_verdict(1.0, before[able], c.heldout_rms, cur.rms, c.fit.rms)
            c.verdict += f"; {why}" + ("" if able is None else " (the records that show it)")
            self.say(f"  {c.effect}: held-out {why}" + ("" if able is None else
                     " on " + ", ".join(self.records[i].name for i in able)))
            if ok and win is None:
                win = c
            c.accepted = ok
        for c in passing[tested:]:
            c.accepted = False
            c.verdict += "; not tested on the held-out parts (a better candidate was)"
        if refuse_tied_effects(passing, rank=lambda c: c.records_bic_change):
            return None
        for c in passing:
            c.accepted = c is win
        return win

    def revealing(self, c: CampaignCandidate) -> list:
        """The records that reveal ``c``'s effect (shown_by) as the current model becomes ``c``'s."""
        return self.shown_by(c.effect, self.cur, c.fit, c.added_parameters)

    def shown_by(self, effect: str, without: CampaignFit, with_: CampaignFit, added: int) -> list:
        """The records that reveal ``effect`` from the fit ``without`` it to the fit ``with_`` it: of
        those that can (laws.unrevealed), those where it meets the one-record rule on their own
        samples (reveals: their own error before and after, their own BIC with its ``added``
        parameters)."""
        return [i for i, (r, b, a) in enumerate(zip(self.records, without.rms_records, with_.rms_records))
                if not unrevealed(r.trace, effect) and self.reveals(i, b, a, added)]

    def showing(self, c: CampaignCandidate) -> tuple | None:
        """The records whose held-out parts judge ``c``: those that reveal its effect (revealing), else
        those that can; None where that is every record. Where the effect shows, the other records'
        parts move with the shared law, not with the effect, and one predicted worse by a law the
        model still lacks would refuse an effect its own record predicts well (tuning campaign 1008,
        docs/campaign-discovery.md, session 39)."""
        return self.showing_records(c.effect, self.revealing(c))

    def showing_records(self, effect: str, shown: list) -> tuple | None:
        """The records that show ``effect``: ``shown``, those that reveal it (shown_by), else those
        that can (laws.unrevealed); None where that is every record."""
        among = tuple(shown) or self.able_to_reveal(effect)
        return None if among is not None and len(among) == len(self.records) else among

    def record_fit(self, f: CampaignFit, i: int) -> ModelFit:
        """The campaign fit ``f`` on record i alone: its law with the record's nuisance values."""
        return ModelFit(spec=f.spec, effects=f.effects, params={**f.params, **f.nz[i]}, free=f.free,
                        rms=f.rms_records[i], predicted=f.predicted[i])

    def slack_in_held_parts(self, f: CampaignFit, among: tuple | None) -> bool:
        """Whether ``f`` goes slack in the held-out part of any of the records ``among`` (default all)."""
        among = range(len(self.records)) if among is None else among
        return any(regimes(self.records[i].trace, self.record_fit(f, i))["slack"][self.records[i].held].any()
                   for i in among)

    def able_to_reveal(self, effect: str) -> tuple | None:
        """The indices of the records that can reveal ``effect`` (laws.unrevealed), or None where
        every record can."""
        able = tuple(i for i, r in enumerate(self.records) if not unrevealed(r.trace, effect))
        return None if len(able) == len(self.records) else able

    def revealed_named(self, effect: str) -> tuple | None:
        """The records that revealed the named ``effect`` (the last step that added it), else those
        that can reveal it (able_to_reveal). A named law's shape, finer bank or wider law is led by
        the worst of these: another record's misfit may be an effect the model still lacks (a creep
        test missed for want of creep bent the cubic's power term to it, tuning campaign 3000,
        docs/campaign-discovery.md, session 43)."""
        names = next((s.revealed_by for s in reversed(self.steps) if s.effect == effect), [])
        shown = tuple(i for i, r in enumerate(self.records) if r.name in names)
        return shown or self.able_to_reveal(effect)

    def rms_among(self, f: CampaignFit, among: tuple | None) -> float:
        """The campaign's error in noise units on the records ``among`` (indices; every record where None)."""
        if among is None:
            return f.rms
        return in_noise_units([f.rms_records[i] for i in among], [self.records[i] for i in among])

    def effect_verdict(self, effect: str, without: CampaignFit, with_: CampaignFit, bic: float,
                       added: int) -> tuple[bool, str]:
        """The one-record rule (judge.full_data_verdict) on the campaign for ``effect``, from the fit
        ``without`` it to the fit ``with_`` it: the BIC over every record; the gap above the noise on
        the records that reveal the effect (shown_by), else on those that can (laws.unrevealed), as
        its held-out test reads them. Another record's error moves with the shared law, not with the
        effect, and one missed far above its noise for an effect the model still lacks would hide
        the gap this one closes where it shows (docs/campaign-discovery.md, "The search")."""
        shown = self.shown_by(effect, without, with_, added)
        among = self.showing_records(effect, shown)
        ok, why = full_data_verdict(1.0, self.rms_among(without, among), self.rms_among(with_, among), bic, added)
        if among is None:
            return ok, why
        return ok, why + (" (the records that reveal it)" if shown else " (the records that can reveal it)")

    def judge(self, effect: str, f: CampaignFit) -> CampaignCandidate:
        """The one-record rule on the campaign's error in noise units (sigma = 1, effect_verdict); slack, which adds
        no parameter, only where it acts in some record (judge._slack_acts); hysteresis only where its
        loops earn their place (judge.loops_verdict); a Coulomb friction only where it acts as dry
        friction on some record (judge.friction_verdict)."""
        cur = self.cur
        dk = f.n_free - cur.n_free
        c = CampaignCandidate(effect=effect, fit=f, added_parameters=dk, bic_change=bic_change(cur, f, self.n),
                              records_bic_change=ranked_bic_change(self.records, cur, f, dk, self.n))
        if not f.ok:
            c.verdict = f"the fit failed: {f.message}"
            return c
        c.accepted, c.verdict = self.effect_verdict(effect, cur, f, c.bic_change, dk)
        if c.accepted and effect == "slack":
            acts = [r for i, r in enumerate(self.records) if _slack_acts(
                r.trace, cur.spec.for_experiment(r.trace.experiment), self.record_fit(f, i), r.sigma, "")[0]]
            if not acts:
                c.accepted, c.verdict = False, "slack never acts in the fitted model on any record"
        if c.accepted and effect == "hysteresis":
            params, terms = closed_loops(f.spec, f.params)
            closed = self.as_fitted(f, params=params) if terms else f
            c.accepted, c.verdict = loops_verdict(1.0, closed.rms, f.rms, f.free, terms, self.n, c.verdict)
        if c.accepted and effect == "nonlinear_damping":
            c.accepted, c.verdict = friction_verdict(f.spec, f.params, lambda: [
                model_speed(r.trace, self.record_fit(f, i).predicted) for i, r in enumerate(self.records)
                if r.trace.rig == "payload"], c.verdict)
        return c

    def add(self, step: CampaignStep, win: CampaignCandidate) -> None:
        """The winner's effect added; who revealed it (of the records that can reveal it, laws.unrevealed,
        those where it meets the one-record rule on their own samples: their own error before and
        after, their own BIC with the added parameters; a record that cannot reveal it is not
        credited with the error it loses as the shared law moves); the nuisance and the law settled
        again."""
        cur, f = self.cur, win.fit
        shown = self.showing(win)
        step.effect, step.model_after, step.rms_after = win.effect, f.model, f.rms
        step.records_after = list(f.rms_records)
        step.fit_after = f
        revealed = [self.records[i].name for i in self.revealing(win)]
        if revealed:
            step.revealed_how = "each named record alone: its gap above the noise shrinks as the one-record rule asks"
        else:
            # a record that cannot reveal it is not credited with what it gains as the shared law moves
            gains = [-math.inf if unrevealed(r.trace, win.effect) else (_gap(b, r.sigma) - _gap(a, r.sigma)) / r.sigma
                     for r, b, a in zip(self.records, cur.rms_records, f.rms_records)]
            revealed = [self.records[int(np.argmax(gains))].name]
            step.revealed_how = ("jointly: no record alone meets the one-record rule; named is the record whose gap "
                                 "above the noise shrinks most")
        step.revealed_by = revealed
        self.say(f"added {win.effect}: campaign RMS error {cur.rms:.2f} -> {f.rms:.2f} x noise; revealed by "
                 f"{', '.join(revealed)}")
        settled = self.settle(f)
        self.cur = settled
        # the current held-out error is every record's: the winner's was read on the records that show
        # its effect, or not at all (slack), where those are not all
        every = shown is None and not math.isnan(win.heldout_rms)
        self.cur_held = win.heldout_rms if settled is f and every else self.heldout_of(settled)
        self.fits.append(self.cur)
