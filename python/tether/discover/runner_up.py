"""The runner-up swap of a discovery (the plan's stage "runner-ups"). A step names the effect that
lowers the BIC most beside the effects named so far; a candidate of another effect that passed the
same rules but lowered the BIC less is the step's runner-up. Once later effects are in, the
runner-up may explain what the named effect was added for better than it does (a creep test of a
stiffening tether: before creep is in, a Bouc-Wen force bends to the creep as well as to the
stiffness and wins the first step; beside creep it is the elastic law that fits). Where the model
still misses the record (above CRITERIA.within_noise), each named effect's runner-up is fitted in
its place beside the rest of the model and kept as a rival law is (judge._law_judged: a lower BIC
and error, the held-out prediction no worse). A kept swap is recorded as a step that adds the
runner-up, whose re-test removes the effect it replaces, and every other named effect is tested
again beside it. A mixin of search.Search (docs/discovery.md, "The runner-up")."""

from __future__ import annotations

import math

from ..models import parse_model
from .fitting import _heldout, ModelFit
from .judge import CRITERIA, _law_judged, acts_as_itself, bic_change
from .laws import _law_of, _models_for, _without
from .rival import _law_terms
from .records import CandidateResult, Removal, Retest, Step
from .starts import _reduced_starts, candidate_starts, kept_shape


class RunnerUpSwap:
    """The plan's stage "runner-ups" (swap_runner_ups), on search.Search's state."""

    def runner_ups(self) -> list[tuple[int, str, CandidateResult]]:
        """(step number, the effect the step named, the step's runner-up: the candidate of an effect
        the model lacks that lowered the BIC most among those set aside for it), for each named
        effect whose step had one."""
        out = []
        for k, st in enumerate(self.steps, 1):
            if st.effect not in self.cur.effects or st.effect in self.base_effects:
                continue
            aside = [c for c in st.candidates if c.outranked_by == st.effect and c.effect not in self.cur.effects
                     and math.isfinite(c.bic_change)]
            if aside:
                out.append((k, st.effect, min(aside, key=lambda c: c.bic_change)))
        return out

    def runner_ups_due(self) -> bool:
        """The plan's condition: the model misses the record (above CRITERIA.within_noise), the budget
        is not spent, and a named effect's step had a runner-up."""
        return (not self.budget_hit and self.cur.rms > CRITERIA.within_noise * self.sigma
                and bool(self.runner_ups()))

    def swap_runner_ups(self) -> None:
        """Each named effect's runner-up fitted in its place (runner_up_in_place), in the order of the
        steps; a swap kept changes the model the next one starts from."""
        for k, effect, runner_up in self.runner_ups():
            if self.budget_hit or self.cur.rms <= CRITERIA.within_noise * self.sigma:
                break
            if effect in self.cur.effects and runner_up.effect not in self.cur.effects:
                self.runner_up_in_place(k, effect, runner_up)

    def runner_up_in_place(self, k: int, effect: str, runner_up: CandidateResult) -> bool:
        """The current model with ``runner_up``'s law in ``effect``'s place: the model without
        ``effect`` refitted (as a re-test does), then the runner-up added to it, from its law's terms
        of its step fit beside that model's values and from the registry's starts, judged against the
        current model; kept where it wins (True). The swap extends the model without ``effect``: a
        start that gains on that model is carried to convergence, though its first iterations may
        still miss the record more than the current model does."""
        cur, sigma, n = self.cur, self.sigma, self.n
        factor = self.candidate_cap_factor()
        reduced = _without(cur.spec, effect).for_experiment(self.trace.experiment)
        rest = tuple(x for x in cur.effects if x != effect)
        base = self.fit(self.trace, reduced, rest, _reduced_starts(cur, reduced, self.sc), self.sc, cap_factor=factor,
                        **kept_shape(cur, reduced))
        law = _law_of(parse_model(runner_up.model, self.trace.experiment), runner_up.effect)
        new = next((m for m in _models_for(reduced, runner_up.effect, self.trace)
                    if _law_of(m, runner_up.effect) == law), None)
        if not base.ok or new is None:
            return False
        own = {k: v for k, v in runner_up.values.items() if k in _law_terms(runner_up.effect, law)}
        starts = ([{**base.params, **own}] if own else []) + candidate_starts(base, new, self.sc, self.trace)
        fm = self.fit(self.trace, new, rest + (runner_up.effect,), starts, self.sc, baseline_rms=base.rms,
                      cap_factor=factor)
        held, bic = float("nan"), bic_change(cur, fm, n) if fm.ok else float("inf")
        if fm.ok and bic < 0.0 and fm.rms < cur.rms:
            pf = self.fit(self.part, new, fm.effects, [fm.params], self.sc_part, cap_factor=factor)
            held = _heldout(self.trace, new, pf.params, self.held_out) if pf.ok else float("inf")
        ok, verdict = _law_judged(cur.rms, fm.rms, bic, self.cur_held, held, sigma, effect) if fm.ok else \
            (False, f"the fit failed: {fm.message}")
        if ok:
            ok, verdict = acts_as_itself(self.trace, base.spec, fm, sigma, runner_up.effect, verdict)
        self.say(f"  {runner_up.effect} in place of {effect} (its runner-up in step {k}): "
                 f"{'kept' if ok else 'not kept'}: {verdict}")
        if ok:
            self.put_in_place(k, effect, runner_up.effect, base, fm, held, bic, verdict)
        return ok

    def put_in_place(self, k: int, effect: str, other: str, base: ModelFit, fm: ModelFit, held: float, bic: float,
                     verdict: str) -> None:
        """``fm`` (``other`` in ``effect``'s place) adopted, recorded as a step that adds ``other`` to
        ``base`` (the model without ``effect``) and whose re-test removes ``effect``; the other named
        effects then tested again beside it."""
        cur, n = self.cur, self.n
        cand = CandidateResult(effect=other, model=fm.model, added_parameters=fm.n_free - base.n_free, rms=fm.rms,
                               heldout_rms=held, bic_change=bic_change(base, fm, n), signature=0.0,
                               signature_text="", fit=fm, verdict=f"in place of {effect}: {verdict}", accepted=True)
        why = f"its runner-up in step {k}, {other}, in its place: {verdict}"
        self.steps.append(Step(model_before=cur.model, rms_before=cur.rms, heldout_before=self.cur_held, windows=[],
                               regimes={}, candidates=[cand], effect=other,
                               evidence=f"{other} in place of {effect}, its runner-up in step {k}",
                               rms_after=fm.rms, model_after=fm.model,
                               retests=[Retest(effect, -bic, False, why, other)]))
        self.removals.append(Removal(effect, cur.model, fm.model, cur.rms, fm.rms, why))
        self.say(f"added {other} in place of {effect}: RMS error {cur.rms / self.sigma:.2f} -> "
                 f"{fm.rms / self.sigma:.2f} x noise")
        self.adopt_model(fm, held)
        self.retest_named(other)
