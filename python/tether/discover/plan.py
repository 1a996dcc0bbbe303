"""The search plan as data (issue 25): the stages of a discovery run in their order, each a name, a
condition on the search state and its proposer, a method of search.Search that proposes, has the
judge (judge.py) judge each proposal, adopts or refuses it and records it (Step, Removal,
Refinement). Search.run is the loop over PLAN; docs/discovery.md, "The plan", is this table in words.
The conditions read the state a Search keeps (search.Search: budget_hit, search_again, rival_kept
and the methods named below; branch.py the rival branch's)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable


@dataclass(frozen=True)
class Stage:
    """One stage of the plan: ``when`` its condition on the search state (``condition`` in words),
    ``proposer`` the name of the Search method that runs it (``proposes`` in words), ``judge``
    what judges its proposals."""

    name: str
    condition: str
    when: Callable[[object], bool]
    proposer: str
    proposes: str
    judge: str


_ALWAYS = "always"

#: the plan of every discovery run: its stages, in order
PLAN = (
    Stage("effects", _ALWAYS, lambda s: True, "search_effects",
          "each effect the record can reveal and the model lacks, with each of its laws, step by step; after a "
          "step, each effect named before the winner, removed",
          "full_data_verdict, heldout_verdict (and acts_as_itself); a removal: retest_verdict"),
    Stage("runner-ups", "the model misses the record (above CRITERIA.within_noise), the budget is not spent, and "
          "a named effect's step set a candidate of another effect aside for it", lambda s: s.runner_ups_due(),
          "swap_runner_ups", "each named effect's runner-up (the candidate its step set aside with the lowest BIC) "
          "in its place beside the rest of the model; where kept, each other named effect removed",
          "_law_judged (and acts_as_itself); a removal: retest_verdict"),
    Stage("shapes", "the budget is not spent", lambda s: not s.budget_hit, "refine_shapes_first",
          "the shape groups of the named laws (SHAPE_TERMS), one at a time from the final model",
          "_shape_judged"),
    Stage("effects again", "a shape was kept and the refined model misses the record by CRITERIA.unexplained_gap "
          "or more", lambda s: s.search_again, "search_effects_again",
          "the search for effects once more from the refined model, its shape terms free (a shorter work cap)",
          "as in the first search"),
    Stage("shapes again", "the second search ran, the budget is not spent, and the second search named an effect "
          "or a named law has shapes not yet refined", lambda s: s.search_again and not s.budget_hit and (
              s.named_again() or s.shapes_left()), "refine_shapes_again",
          "the shape groups of the laws not refined yet", "_shape_judged"),
    Stage("pairs", "the last search for effects stopped with no candidate earning its place, the model misses the "
          "record by CRITERIA.unexplained_gap or more, and the budget is not spent", lambda s: s.pairs_due(),
          "search_pairs", "the search for effects once more; where a step has no winner, the refused candidate that "
          "lowered the BIC most beside each other missing effect, as one candidate (pairs.py); then the shapes of "
          "the laws it named", "as in the first search; a pair: pair_verdict, heldout_verdict (and acts_as_itself)"),
    Stage("reseed", "a named law has reseeding moves (the Iwan bank), the model misses the record by "
          "CRITERIA.iwan_stages_gap or more, and the budget is not spent", lambda s: s.reseedable(), "reseed",
          "the law's reseeding moves in turn (Law.reseed: the idle Iwan elements restarted, a finer bank); where "
          "one is kept and the gap stays, the other laws' shapes beside the reseeded law",
          "a lower error (the restart), _shape_judged (the finer bank, the shapes)"),
    Stage("rival law", "the budget is not spent and the hysteresis step fitted the rival law",
          lambda s: not s.budget_hit and s.has_rival(), "swap_rival",
          "the hysteresis law's rival in its place (rival_law, where its own conditions hold), then its shapes",
          "_law_judged; the shapes: _shape_judged"),
    Stage("reseed the rival", "the rival law was kept, and the reseed stage's condition holds",
          lambda s: s.rival_kept and s.reseedable(), "reseed", "as the reseed stage, for the rival law",
          "as the reseed stage"),
    Stage("other rival laws", "the budget is not spent", lambda s: not s.budget_hit, "swap_other_rival_laws",
          "each other named law's rival in its place (Law.rival: cubic and bilinear, c(x) and dry friction), where "
          "the model still misses the record", "_law_judged"),
    Stage("wider laws", "the budget is not spent", lambda s: not s.budget_hit, "swap_wider_laws",
          "each named law's wider law in its place (WIDER_LAWS), where the model still misses the record; where not "
          "kept, once more with its first shape group free",
          "_law_judged"),
    Stage("stand-ins", "the budget is not spent and a named effect does not act as itself (acts_as_itself) beside "
          "another named effect that has other laws", lambda s: s.stand_ins_due(), "swap_stand_ins",
          "that effect removed with each other law of each other named effect in place (every law the rig can hold), "
          "until one is adopted; then each other named effect removed", "retest_verdict (as a re-test)"),
    Stage("re-test", "a last stage changed a law after the last step's re-tests, and the budget is not spent",
          lambda s: not s.budget_hit and bool(s.laws_changed()), "retest_after_refinements",
          "each other named effect removed, one removal at a time", "retest_verdict"),
    Stage("rival branch", "a step found two laws of its effect tied (CRITERIA.rival_tie), the model misses the "
          "record by CRITERIA.unexplained_gap or more, and the budget left holds the time taken since that step",
          lambda s: s.branch_due(),
          "carry_rival_branch", "the search as it goes on from that step with the tied law in the winner's place, "
          "through the stages above", "_law_judged (the branch's final model against the search's)"),
    Stage("final fit", _ALWAYS, lambda s: True, "final_fit",
          "the final model fitted from the searched optimum (on the whole record where the search thinned it)",
          "kept where no worse"),
)
