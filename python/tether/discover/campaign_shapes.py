"""The shapes of the named laws on a campaign (the one-record search's refine.refine_shapes): a mixin
of discover.campaign.Campaign."""

from __future__ import annotations

import math

from .campaign_records import _law_only
from .judge import _not_kept_for_budget, _shape_heldout_asked, _shape_judged, bic_change
from .records import Refinement
from .refine import _shape_groups
from .starts import _damping_table_start, _shape_start


class Shapes:
    """Needs Campaign's records, cur, cur_held, refinements, shaped_beside, fit, fit_alone, adopt,
    heldout_of, worst_record, revealed_named."""

    def refine_shapes(self) -> None:
        """Where a record is still missed, the shape terms of each named law (laws.SHAPE_TERMS: the
        cubic's power term, Bouc-Wen's exponent and terms, the Iwan bank's slip strains, the damping
        table), one group at a time from the current model (shape_fit); each judged as in the
        one-record search (judge._shape_judged on the campaign's error in noise units: a lower BIC
        and error, the held-out parts' prediction no worse where asked); the best kept, its terms
        free in every later fit (CampaignFit.shape). A law whose form differs by strain range
        (a tether whose stiffness grows as a power of its strain) is fitted alike on every record
        only in its right shape (docs/campaign-discovery.md, session 40)."""
        cur = self.cur
        if self.budget_hit or self.within_noise(cur):
            return
        groups = [(e, g) for e, g in _shape_groups(cur) if self.shape_open(cur, g)]
        best, first = None, len(self.refinements)
        for effect, group in groups:
            if self.budget_hit:
                _not_kept_for_budget(self.refinements[first:])
                return
            fm = self.shape_fit(cur, effect, group)
            ok, r = self.shape_judged(cur, fm, effect, group)
            if ok and (best is None or r.bic_change < best[0].bic_change):
                best = (r, fm)
        for _, group in groups:
            self.shaped_beside[tuple(group)] = tuple(cur.effects)
        if best is None:
            return
        for r in self.refinements[first:]:        # one group wins; the others stay on record as tried
            if r.accepted and r is not best[0]:
                r.accepted = False
                r.verdict += f"; {' '.join(best[0].parameters)} did better"
        self.adopt(best[1], best[0].heldout_after)

    def shape_open(self, m, group: tuple) -> bool:
        """Whether the shape terms ``group`` are fitted by refine_shapes from ``m``: terms not yet free,
        or a shape kept beside fewer effects than ``m`` names (fitted again from its lead record: a
        shape fitted while a record was missed for an effect not yet named is bent to that record;
        tuning campaign 3000's power term, fitted before creep, left its load test at 5.81 x noise,
        docs/campaign-discovery.md, session 43)."""
        if not set(group) <= set(m.shape) | set(m.free):
            return True
        beside = self.shaped_beside.get(tuple(group))
        return beside is not None and not set(m.effects) <= set(beside)

    def forget_shapes(self, effect: str) -> None:
        """The shapes of ``effect``'s law not fitted again (shape_open) once another move replaced them."""
        for e, group in _shape_groups(self.cur):
            if e == effect:
                self.shaped_beside.pop(tuple(group), None)

    def shape_fit(self, m, effect: str, group: tuple):
        """``m`` with the shape terms ``group`` of ``effect``'s law free, fitted first to the record that
        shows the effect worst (of those that revealed it, revealed_named), its nuisance free, from
        the one-record search's shape starts on it (starts._shape_start; the damping table also from
        the rig's equation error), then to every record jointly from there and from the shape start
        itself (the route the campaign's candidates take; from the shape start alone where that
        record's fit fails)."""
        i = self.worst_record(m, self.revealed_named(effect))
        lead = self.records[i]
        extra = tuple(m.shape) + tuple(g for g in group if g not in m.shape)
        flat = _shape_start({**m.params, **m.nz[i]}, group, lead.sc)
        starts = [flat]
        if any(g.startswith("c_table_") for g in group) and lead.trace.rig == "payload":
            table = _damping_table_start(lead.trace, m.spec, flat, flat["c_table_dx"])
            starts += [] if table is None else [{**flat, **table}]
        factor = self.cap_factor_for(m)
        self.say(f"shape of {effect} ({' '.join(group)}), fitted to {lead.name} first")
        alone = self.fit_alone(i, m.spec, m.effects, starts, extra, None if self.cap is None else self.cap * factor)
        shaped = {**m.params, **_law_only(flat, m.spec)}
        if alone.ok:
            starts, nzs = self.lead_starts(m.spec, {**m.params, **_law_only(alone.params, m.spec)}, m.nz, i, alone)
            fm = self.fit(m.spec, m.effects, starts + [shaped], start_nzs=nzs + [[dict(nz) for nz in m.nz]],
                          extra=extra, cap_factor=factor)
        else:
            self.say(f"  its fit to {lead.name} alone failed ({alone.message}): fitted to every record from the start")
            fm = self.fit(m.spec, m.effects, [shaped], nzs=m.nz, extra=extra, cap_factor=factor)
        return self.nuisance_then_law(fm, cap_factor=factor)

    def shape_judged(self, cur, fm, effect: str, group: tuple) -> tuple:
        """The shape fit ``fm`` judged against ``cur`` (refine_shapes) and put on record. (kept, the Refinement)"""
        held, bic = float("nan"), float("inf")
        if not fm.ok:
            ok, verdict = False, f"the fit failed: {fm.message}"
        else:
            ok, verdict, held, bic = self.shape_verdict(cur, fm, "the terms do not earn their place")
        r = Refinement(effect, tuple(group), cur.rms, fm.rms if fm.ok else math.inf, self.cur_held, held, bic, ok,
                       verdict, {k: float(fm.params[k]) for k in group if k in fm.params} if fm.ok else {})
        self.refinements.append(r)
        self.say(f"  shape of {effect} ({' '.join(group)}): {'kept' if ok else 'not kept'}: {verdict}"
                 + (f" ({self.per_record(fm)})" if fm.ok else ""))
        return ok, r

    def shape_verdict(self, cur, fm, refused: str) -> tuple:
        """Terms freed beyond a named law's (a shape, a finer bank) in the fit ``fm``, judged against
        ``cur`` by the shape rule (judge._shape_judged on the campaign's error in noise units: a lower
        BIC and error, the held-out parts' prediction no worse where asked); ``refused``: why they
        stay out where the BIC or the error does not fall. (kept, verdict, held-out error, BIC change)"""
        held, bic = float("nan"), bic_change(cur, fm, self.n)
        if bic < 0.0 and fm.rms < cur.rms and _shape_heldout_asked(cur.rms, self.cur_held, fm.rms, 1.0):
            held = self.heldout_of(fm)
        ok, verdict = _shape_judged(cur.rms, fm.rms, bic, self.cur_held, held, 1.0,
                                    f"RMS error {cur.rms:.2f} -> {fm.rms:.2f} x noise, BIC changes by {bic:+.1f}: "
                                    + refused)
        return ok and not self.budget_hit, verdict, held, bic
