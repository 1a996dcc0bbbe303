"""A named effect that stands in for another effect's law (the plan's stage "stand-ins"). An effect
earns its place by the error it removes, and a re-test asks whether it still does beside the other
named effects with their laws as they are. But it may have earned it by doing another law's work: a
Bouc-Wen force with beta ~ 0 and gamma < 0 is an exponential elastic law in disguise, and in a creep
test of an exponentially stiffening tether it wins step 1 and survives its re-test, since the
cubic the search named beside it cannot follow the exponential law without it. Such an effect does
not act as itself (judge.acts_as_itself: its loops closed, the record is fitted as well). Where a
named effect does not, it is removed with each other law of each other named effect in place (the
laws the record's rig can hold, laws.EFFECTS); where it no longer earns its place beside one of them
by the re-test's rule (retest_verdict), that model is adopted, recorded as a removal, and the
other named effects are tested again beside it. A mixin of search.Search (docs/discovery.md, "The
stand-ins")."""

from __future__ import annotations

from dataclasses import replace

from .judge import acts_as_itself, bic_change, retest_verdict
from .laws import EFFECT, _law_of, _with_law, _without
from .records import Removal
from .rival import _rival_starts
from .starts import _reduced_starts


class StandIn:
    """The plan's stage "stand-ins" (swap_stand_ins), on search.Search's state."""

    #: (the model judged, its impostors): the plan's condition and the stage ask of the same model
    _impostors_of: tuple | None = None

    def impostors(self) -> list[str]:
        """The named effects (not the start model's) that do not act as themselves in the current
        model (acts_as_itself; slack judged against the model without it)."""
        cur = self.cur
        if self._impostors_of is not None and self._impostors_of[0] is cur:
            return list(self._impostors_of[1])
        out = []
        for e in cur.effects:
            if e in self.base_effects:
                continue
            acts, _ = acts_as_itself(self.trace, _without(cur.spec, e).for_experiment(self.trace.experiment), cur,
                                     self.sigma, e, "")
            if not acts:
                out.append(e)
        self._impostors_of = (cur, out)
        return list(out)

    def stand_in_laws(self, effect: str) -> list[tuple[str, str]]:
        """(other named effect, one of its other laws) for each law of each other named effect with
        a law of its own that the record's rig can hold (a law reached only as another's rival or
        wider law, such as primary creep, too)."""
        cur = self.cur
        out = []
        for f in cur.effects:
            if f == effect or EFFECT[f].law_field is None:
                continue
            own = _law_of(cur.spec, f)
            out += [(f, law.name) for law in EFFECT[f].laws
                    if law.name != own and law.tried_on(self.trace.rig)]
        return out

    def stand_ins_due(self) -> bool:
        """The plan's condition: the budget is not spent and a named effect does not act as itself
        beside another named effect that has other laws."""
        return not self.budget_hit and any(self.stand_in_laws(e) for e in self.impostors())

    def swap_stand_ins(self) -> None:
        """Each named effect that does not act as itself, removed with each other law of each other
        named effect in place (stand_in), until one is adopted or none is left."""
        for e in self.impostors():
            for f, law in self.stand_in_laws(e):
                if self.budget_hit:
                    return
                if self.stand_in(e, f, law):
                    return

    def stand_in(self, effect: str, other: str, law: str) -> bool:
        """The current model without ``effect`` and with ``law`` as ``other``'s law, fitted from the
        current model's values and the law's starts; adopted where ``effect`` does not earn its
        place beside it (retest_verdict, as a re-test asks). True where it was."""
        cur, sigma, exp = self.cur, self.sigma, self.trace.experiment
        reduced = _without(cur.spec, effect).for_experiment(exp)
        new = _with_law(reduced, other, law).for_experiment(exp)
        rest = tuple(x for x in cur.effects if x != effect)
        without = replace(cur, spec=reduced, params={k: v for k, v in cur.params.items()
                                                     if k in reduced.parameters or k not in cur.spec.parameters})
        starts = _rival_starts(self.trace, without, new, other, {}, self.sc) + _reduced_starts(cur, new, self.sc)[:1]
        fm = self.fit(self.trace, new, rest, starts, self.sc, cap_factor=self.candidate_cap_factor())
        if not fm.ok:
            self.say(f"  {effect} standing in for {other}'s {law} law: the fit failed: {fm.message}")
            return False
        keep, why = retest_verdict(sigma, fm.rms, cur.rms, bic_change(fm, cur, self.n), cur.n_free - fm.n_free)
        self.say(f"  {effect} standing in for {other}'s {law} law: without it, with that law, the RMS error is "
                 f"{fm.rms / sigma:.2f} x noise: {'it stays' if keep else 'removed'} ({why})")
        if keep:
            return False
        self.removals.append(Removal(effect, cur.model, fm.model, cur.rms, fm.rms,
                                     f"it stood in for {other}'s {law} law (it does not act as itself): beside that "
                                     f"law it no longer earns its parameters: {why}"))
        self.adopt_model(fm, self.heldout_of(fm))
        self.retest([x for x in rest if x not in self.base_effects and x != other], f"{other}'s {law} law")
        return True
