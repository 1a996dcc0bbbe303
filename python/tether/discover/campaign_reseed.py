"""The Iwan bank's reseeding moves on a campaign (the one-record search's rival.finer_bank): a
mixin of discover.campaign.Campaign."""

from __future__ import annotations

import math

import numpy as np

from ..models import IWAN_EPS, IWAN_K
from .fitting import fit_model
from .judge import _shape_heldout_asked, _shape_judged, bic_change
from .laws import unrevealed
from .records import Refinement
from .rival import _bank_params, _finer_kept, _finer_spread, _slip_of, bank_cap_factor
from .campaign_records import _law_only


class Reseeding:
    """Needs Campaign's records, cur, cur_held, fits, refinements, fit, settle, heldout_of."""

    def finer_bank(self) -> None:
        """The campaign's search fits an Iwan bank of IWAN_FIT_ELEMENTS elements on a fixed grid of
        slip strains; a smooth friction loop needs more, and a bank made finer and fitted to every
        record at once stops far off (a tuning campaign of hysteresis and slack: 10.45, 4.78, 1.31 x
        noise, where the generator's law gives 0.97, 0.94, 1.02). Where a record is still missed,
        the bank is made finer (rival._finer_spread, rival._finer_kept) and fitted, slip strains
        too, first to the record that shows the hysteresis worst with its nuisance free, then to
        every record jointly from there (the route the campaign's candidates take); kept as a finer
        bank is in the one-record search (judge._shape_judged on the campaign's error in noise
        units: a lower BIC and error, the held-out parts' prediction no worse where asked). Its
        terms stay free in every later fit (CampaignFit.shape). docs/campaign-discovery.md."""
        cur = self.cur
        bank = [n for n in IWAN_K if n in cur.free]
        if (self.budget_hit or self.within_noise(cur) or cur.spec.hysteresis != "iwan" or not bank
                or len(bank) >= len(IWAN_K)):
            return
        able = [i for i, r in enumerate(self.records) if not unrevealed(r.trace, "hysteresis")]
        if not able:
            return
        i = max(able, key=lambda j: cur.rms_records[j] / self.records[j].sigma)
        lead = self.records[i]
        k = np.array([float(cur.params.get(n, 0.0)) for n in bank])
        e = np.array([float(cur.params[_slip_of(n)]) for n in bank])
        banks = [b for b in (_finer_spread(k, e, len(IWAN_K)), _finer_kept(k, e, len(IWAN_K))) if b is not None]
        if not banks:
            return
        self.say(f"a finer Iwan bank ({len(IWAN_K)} elements for {len(bank)}), fitted to {lead.name} first")
        extra = tuple(cur.shape) + tuple(n for n in IWAN_K + IWAN_EPS if n not in cur.free and n not in cur.shape)
        factor = self.cap_factor_for(cur) * bank_cap_factor(len(IWAN_K))
        alone = fit_model(lead.trace, cur.spec.for_experiment(lead.trace.experiment), cur.effects,
                          [{**cur.params, **lead.nz, **_bank_params(k2, e2)} for k2, e2 in banks], lead.sc,
                          nuisance=lead.nuisance, extra=extra, deadline=self.deadline,
                          work_cap=None if self.cap is None else self.cap * factor)
        fm = None
        if alone.ok:
            nzs = [dict(r.nz) for r in self.records]
            nzs[i] = dict(alone.nuisance)
            fm = self.fit(cur.spec, cur.effects, [{**cur.params, **_law_only(alone.params, cur.spec)}],
                          nzs=nzs, extra=extra, cap_factor=factor)
            fm = self.nuisance_then_law(fm, cap_factor=factor)
        self.bank_judged(cur, fm, len(bank), tuple(n for n in extra if n not in cur.shape),
                         fm.message if fm is not None else f"on {lead.name}: {alone.message}")

    def bank_judged(self, cur, fm, elements: int, terms: tuple, failed: str) -> None:
        """The finer bank ``fm`` (None where its fit to the lead record failed, ``failed`` saying why)
        judged against ``cur`` (finer_bank), put on record, and kept where it passes."""
        held, bic = float("nan"), float("nan")
        if fm is None or not fm.ok:
            ok, verdict, fm = False, f"the fit failed: {failed}", None
        else:
            bic = bic_change(cur, fm, self.n)
            if bic < 0.0 and fm.rms < cur.rms and _shape_heldout_asked(cur.rms, self.cur_held, fm.rms, 1.0):
                held = self.heldout_of(fm)
            ok, verdict = _shape_judged(cur.rms, fm.rms, bic, self.cur_held, held, 1.0,
                                        f"RMS error {cur.rms:.2f} -> {fm.rms:.2f} x noise, BIC changes by "
                                        f"{bic:+.1f}: the bank of {elements} stays")
            ok = ok and not self.budget_hit
            if ok:
                verdict = f"{len(IWAN_K)} elements for {elements}: {verdict}"
        self.refinements.append(Refinement(
            "hysteresis", terms, cur.rms, fm.rms if fm else float("inf"), self.cur_held, held, bic, ok, verdict,
            {t: float(fm.params[t]) for t in IWAN_K + IWAN_EPS} if fm else {}, finer=True))
        self.say(f"  a finer Iwan bank: {'kept' if ok else 'not kept'}: {verdict}"
                 + (f" ({self.per_record(fm)})" if fm else ""))
        if ok:
            self.cur = self.settle(fm)
            self.cur_held = held if self.cur is fm and math.isfinite(held) else self.heldout_of(self.cur)
            self.fits.append(self.cur)

