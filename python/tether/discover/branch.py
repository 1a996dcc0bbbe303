"""The rival branch of a discovery (the plan's stage "rival branch"): where the step that names an
effect of several laws finds two of them tied (judge.rival_tie), a copy of the search is set aside
with the rival law in the winner's place; once the search has run its stages and its model still
leaves something unexplained, the copy runs the same stages from there, and its final model
replaces the search's where it judges better (judge._law_judged: a lower BIC and error, the held-out
prediction no worse; judge.optimum_judged, a lower error, where the two are one model with the same
free terms). A mixin of search.Search (docs/discovery.md, "The rival branch")."""

from __future__ import annotations

import copy
import time
from dataclasses import replace

from .judge import _gap, _law_judged, leaves_unexplained, bic_change, optimum_judged, rival_tie, same_terms
from .laws import RIVAL_LAWS, _law_of
from .plan import PLAN
from .records import CandidateResult, Refinement, Step


class RivalBranch:
    """fork_at_tie at a step, carry_rival_branch at the end (search.Search's state)."""

    def fork_at_tie(self, win: CandidateResult, step: Step, windows: list) -> None:
        """Where ``win``'s law ties with a rival law of its effect (judge.rival_tie), a copy of the
        search as it would go on with the rival in its place: self.branch (once per run, in the first
        search for effects)."""
        if self.branched or self.branch is not None or self.stages or win.effect not in RIVAL_LAWS:
            return
        tie = rival_tie(win, self.law_candidates.get(win.effect, ()), self.sigma)
        if tie is None:
            return
        mine, theirs = _law_of(win.fit.spec, win.effect), _law_of(tie.fit.spec, win.effect)
        gaps = f"{_gap(win.rms, self.sigma) / self.sigma:.2f} against {_gap(tie.rms, self.sigma) / self.sigma:.2f} sigma"
        carried = replace(tie, verdict=f"{tie.verdict}; ties with the {mine} law ({gaps}): carried on in its place")
        alt = copy.copy(self)
        alt.steps = [*self.steps[:-1], replace(step, candidates=[carried if c is win else c for c in step.candidates],
                                               retests=[])]
        alt.removals, alt.refinements = list(self.removals), list(self.refinements)
        alt.fits, alt.stages = list(self.fits), list(self.stages)
        alt.rivals, alt.branched, alt.branch = {}, True, None
        alt.fork = (carried, windows, len(self.steps), mine)
        alt.forked_at = time.perf_counter()
        self.branch = alt
        self.say(f"  {win.effect}: the {theirs} law ties with the {mine} law: the search will carry it on too "
                 f"if the model still misses the record at the end")

    def branch_due(self) -> bool:
        """A rival branch was set aside, the model still misses the record by CRITERIA.unexplained_gap
        or more, and the budget is not spent and holds at least the time the search took since the
        fork (what the branch will take, about)."""
        if self.branch is None or self.budget_hit:
            return False
        now = time.perf_counter()
        affordable = self.deadline is None or self.deadline - now >= now - self.branch.forked_at
        return affordable and leaves_unexplained(self.cur.rms, self.sigma)

    def carry_rival_branch(self) -> None:
        """The branch carried on through the plan's stages (the final fit aside); its model judged
        against the search's (judge._law_judged; judge.optimum_judged where both are the same model with
        the same free terms), and the branch's whole account taken where it is kept."""
        alt, cur, sigma = self.branch, self.cur, self.sigma
        self.say(f"carrying on the search with the law that tied in step {alt.fork[2]} (the model misses the "
                 f"record at {cur.rms / sigma:.2f} x noise)")
        alt.resume_branch()
        self.budget_hit = self.budget_hit or alt.budget_hit
        bic = bic_change(cur, alt.cur, self.n)
        carried, _, step_no, named = alt.fork
        if same_terms(cur, alt.cur):
            ok, verdict = optimum_judged(cur.rms, alt.cur.rms, sigma)
        else:
            ok, verdict = _law_judged(cur.rms, alt.cur.rms, bic, self.cur_held, alt.cur_held, sigma,
                                      _law_of(cur.spec, carried.effect))
        if ok and alt.budget_hit:
            ok, verdict = False, verdict + "; not kept: the time budget ran out in the branch"
        tied = _law_of(carried.fit.spec, carried.effect)
        record = Refinement(carried.effect, (), cur.rms, alt.cur.rms, self.cur_held, alt.cur_held, bic, ok,
                            f"the search carried on from step {step_no} with the law that tied there: {verdict}",
                            law=f"{named} -> {tied}, from step {step_no} on")
        self.say(f"  the branch with {alt.cur.model}: {'kept' if ok else 'not kept'}: {verdict}")
        if not ok:
            self.refinements.append(record)
            return
        alt.refinements.append(record)
        for name in ("cur", "cur_held", "fits", "steps", "removals", "refinements", "shape_free", "shape_held",
                     "retested_at", "rival_kept", "search_again", "stop"):
            setattr(self, name, getattr(alt, name))

    def resume_branch(self) -> None:
        """The tied law added as the step's winner (its held-out error measured), the effects named
        before it re-tested, then the plan's stages up to the final fit."""
        carried, windows, _, _ = self.fork
        carried.heldout_rms = self.heldout_of(carried.fit)
        self.add(carried, [], self.steps[-1], windows)
        self.retest_named(carried.effect)
        for stage in PLAN:
            if stage.proposer not in ("carry_rival_branch", "final_fit") and stage.when(self):
                getattr(self, stage.proposer)()
                self.stages.append(stage.name)
