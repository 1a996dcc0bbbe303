"""The Iwan bank's reseeding moves on a campaign (the one-record search's rival.finer_bank): a
mixin of discover.campaign.Campaign."""

from __future__ import annotations

from ..models import IWAN_EPS, IWAN_K
from .judge import _law_judged, bic_change
from .records import Refinement
from .rival import bank_cap_factor, finer_banks
from .campaign_records import _law_only


class Reseeding:
    """Needs Campaign's records, cur, cur_held, refinements, fit, fit_alone, adopt, heldout_of,
    worst_record, revealed_named and Shapes.shape_verdict, forget_shapes."""

    def finer_bank(self) -> None:
        """The campaign's search fits an Iwan bank of IWAN_FIT_ELEMENTS elements on a fixed grid of
        slip strains; a smooth friction loop needs more, and a bank made finer and fitted to every
        record at once stops far off (a tuning campaign of hysteresis and slack: 10.45, 4.78, 1.31 x
        noise, where the generator's law gives 0.97, 0.94, 1.02). Where a record is still missed,
        the bank is made finer (finer_fit) and kept as a finer bank is in the one-record search
        (judge._shape_judged on the campaign's error in noise units: a lower BIC and error, the
        held-out parts' prediction no worse where asked). Its terms stay free in every later fit
        (CampaignFit.shape). docs/campaign-discovery.md."""
        cur = self.cur
        if self.budget_hit or self.within_noise(cur):
            return
        out = self.finer_fit(cur)
        if out is not None:
            self.bank_judged(cur, *out)

    def finer_fit(self, m):
        """``m``'s Iwan bank made finer (rival._finer_spread, rival._finer_kept: sixteen elements,
        every slip strain free) and fitted first to the record that shows the hysteresis worst (of
        those that revealed it, revealed_named), its nuisance free, then to every record jointly
        from there (the route the campaign's candidates take). (the fit or None where the lead's fit
        failed, why it failed, the bank's elements before, the terms freed); None where ``m`` has no
        bank to make finer."""
        bank = [n for n in IWAN_K if n in m.free]
        if m.spec.hysteresis != "iwan" or not bank or len(bank) >= len(IWAN_K):
            return None
        able = self.revealed_named("hysteresis")
        banks = finer_banks(m.params, bank)
        if able == () or not banks:
            return None
        i = self.worst_record(m, able)
        lead = self.records[i]
        self.say(f"a finer Iwan bank ({len(IWAN_K)} elements for {len(bank)}), fitted to {lead.name} first")
        extra = tuple(m.shape) + tuple(n for n in IWAN_K + IWAN_EPS if n not in m.free and n not in m.shape)
        factor = self.cap_factor_for(m) * bank_cap_factor(len(IWAN_K))
        alone = self.fit_alone(i, m.spec, m.effects, [{**m.params, **m.nz[i], **b} for b in banks], extra,
                               None if self.cap is None else self.cap * factor)
        terms = tuple(n for n in extra if n not in m.shape)
        if not alone.ok:
            return None, f"on {lead.name}: {alone.message}", len(bank), terms
        starts, nzs = self.lead_starts(m.spec, {**m.params, **_law_only(alone.params, m.spec)}, m.nz, i, alone)
        fm = self.fit(m.spec, m.effects, starts, start_nzs=nzs, extra=extra, cap_factor=factor)
        return self.nuisance_then_law(fm, cap_factor=factor), fm.message, len(bank), terms

    def bank_judged(self, cur, fm, failed: str, elements: int, terms: tuple) -> None:
        """The finer bank ``fm`` (None where its fit to the lead record failed, ``failed`` saying why)
        judged against ``cur`` (finer_bank), put on record, and kept where it passes."""
        held, bic = float("nan"), float("nan")
        if fm is None or not fm.ok:
            ok, verdict, fm = False, f"the fit failed: {failed}", None
        else:
            ok, verdict, held, bic = self.shape_verdict(cur, fm, f"the bank of {elements} stays")
            if ok:
                verdict = f"{len(IWAN_K)} elements for {elements}: {verdict}"
        self.refinements.append(Refinement(
            "hysteresis", terms, cur.rms, fm.rms if fm else float("inf"), self.cur_held, held, bic, ok, verdict,
            {t: float(fm.params[t]) for t in IWAN_K + IWAN_EPS} if fm else {}, finer=True))
        self.say(f"  a finer Iwan bank: {'kept' if ok else 'not kept'}: {verdict}"
                 + (f" ({self.per_record(fm)})" if fm else ""))
        if ok:
            self.forget_shapes("hysteresis")        # its slip strains, every one free, replace the bank's shape
            self.adopt(fm, held)

    def reseeded_rival(self, cur, fm, held: float, bic: float, verdict: str, law: str):
        """The rival hysteresis law's fit ``fm``, refused against ``cur``, after its bank is made finer
        (finer_fit), judged again as the rival is (judge._law_judged): the one-record search's
        rival._reseeded_rival, which asks it only of a rival better on the record but worse on the
        held-out part; on a campaign the bank of eight on its grid is no verdict on the law either
        (a tuning campaign of Iwan friction: the rival of eight 4.57 x noise against Bouc-Wen's 3.82,
        made finer 2.03). (fit, held-out error, BIC change, kept, verdict), ``fm``'s own where there
        is no finer bank to fit."""
        out = self.finer_fit(fm)
        if out is None or out[0] is None or not out[0].ok:
            if out is not None:
                self.say(f"  its finer bank's fit failed: {out[1]}")
            return fm, held, bic, False, verdict
        fm2 = out[0]
        bic2 = bic_change(cur, fm2, self.n)
        held2 = self.heldout_of(fm2) if bic2 < 0.0 and fm2.rms < cur.rms else float("nan")
        ok2, verdict2 = _law_judged(cur.rms, fm2.rms, bic2, self.cur_held, held2, 1.0, law)
        return fm2, held2, bic2, ok2, verdict2 + " (its Iwan bank made finer)"
