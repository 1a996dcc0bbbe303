"""Discovery over a test campaign (issue 29): several records of one tether, one model that explains
them all, and which record revealed each effect.

The records share the tether's material law, damping, hysteresis and creep parameters; each keeps
its own length, mass, gravity and initial state (its JSON) and its own noise and nuisance
parameters (discover.nuisance.nuisance_parameters). The identification engine fits one parameter
set to several experiments; a record's nuisance values enter that joint fit baked into a copy of
the record (its offset taken off the measured column, its mass and initial state in its metadata,
nuisance.baked), and are fitted in turn by one short fit per record with the shared law held
(Campaign.settle). The search is the one-record search's, on the whole campaign: each step first
fits the current model the way its candidates are fitted and keeps the better (Campaign.refit_current),
then each candidate
effect the records can reveal (the union of laws.candidates) is fitted to all records jointly,
each weighted by its own noise (tether.fit.fit_traces), and judged by the one judge
(judge.full_data_verdict, judge.heldout_verdict) on the campaign's error in noise units (every
residual divided by its record's noise), its gap and held-out test on the records that can reveal
the effect (Campaign.effect_verdict, Campaign.heldout_tests); those
that pass are ranked by each record's error against its own (campaign_records.ranked_bic_change), and an
effect whose own law does not reveal it on its lead record is fitted with its wider law in the same
step (Campaign.wider_candidates). Per
step every record's error before and after says which record revealed the effect (the one-record
rule on that record's samples). Each named effect is re-tested once a later one is in
(Campaign.retest_named); where a record is still missed at the end, the named laws' shapes are
freed (Campaign.refine_shapes), the Iwan bank is made finer
(Campaign.finer_bank: on the record that shows it worst first, then jointly; its terms stay free in
later fits, CampaignFit.shape) and the named effects' wider laws are tried (Campaign.wider_laws),
and where one of these keeps a law the steps resume once (Campaign.resume_steps); records beyond their share of the search's samples are searched
thinned and the final model fitted to every sample (Campaign.on_whole_records). A record the
final model misses and whose own fit of the law earns its parameters against the shared one is
flagged as contradicting the others. docs/campaign-discovery.md tells the design and the measured
figures."""

from __future__ import annotations

import copy
import math
import time
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from .. import identify_native as idn
from .. import nuisance as NZ
from ..blas import in_one_blas_thread
from ..fit.experiments import fitted_count
from ..models import ELASTIC_PARAMETERS, HYSTERESIS_PARAMETERS, ModelSpec, parse_model
from ..noise import estimate_noise
from ..traces import Trace
from .document import ordinal
from .fitting import (CAP_SIMULATIONS, DEFAULT_BUDGET, ENGINE_OPTIONS, ModelFit, _clean_start, fit_model, predict,
                      work_ratio)
from .judge import (CRITERIA, _gap, _law_judged, bic_change, leaves_unexplained, retested_beside_refinements,
                    within_noise_without)
from .laws import (HELD_AT_START, RIVAL_LAWS, WIDER_LAWS, _law_of, _models_for, _with_law, _without, candidates,
                   free_parameters)
from .nuisance import baked, nuisance_parameters, nuisance_start
from .records import DiscoveryError, Refinement, Removal, Retest
from .rival import _law_converted, _wider_law_starts
from .samples import SEARCH_SAMPLES, WHOLE_RECORD_ITERATIONS, heldout_split, search_thinning, thinned
from .scales import _scales
from .starts import _reduced_starts

#: quick iterations of each start of a candidate with several (as fit_model's)
QUICK_ITERATIONS = 12
#: rounds of the nuisance-then-law alternation after the start model and after each added effect
SETTLE_ROUNDS = 2


from .campaign_contradictions import Contradictions
from .campaign_reseed import Reseeding
from .campaign_shapes import Shapes
from .campaign_step import Steps
from .campaign_records import (CampaignCandidate, CampaignDiscovery, CampaignFit, CampaignInputError,  # noqa: F401
                               CampaignStep, Record, _law_only, check_campaign, in_noise_units,
                               ranked_bic_change)


@in_one_blas_thread
def discover_campaign(traces: Sequence[Trace], start: str = "linear", progress: Callable[[str], None] | None = None,
                      max_steps: int = 5, heldout_candidates: int = 2, budget: float | None = DEFAULT_BUDGET,
                      mass_band: float | None = None, free_nuisance: bool = True) -> CampaignDiscovery:
    """Discover the effects of one tether over several records of it (the module docstring)."""
    check_campaign(traces)
    return Campaign(traces, start, progress, max_steps, heldout_candidates, budget, mass_band, free_nuisance).run()


class Campaign(Steps, Contradictions, Reseeding, Shapes):
    """One campaign discovery: the records, the current joint fit and its held-out error, the steps."""

    def __init__(self, traces, start, progress, max_steps, heldout_candidates, budget, mass_band, free_nuisance):
        self.t_begin = time.perf_counter()
        self.say = progress or (lambda s: None)
        self.budget = budget
        self.deadline = None if budget is None else self.t_begin + float(budget)
        self.budget_hit = False
        self.max_steps, self.heldout_candidates = max_steps, heldout_candidates
        self.records = [self.record(tr, mass_band, free_nuisance, SEARCH_SAMPLES // len(traces)) for tr in traces]
        self.n = sum(r.n for r in self.records)
        for r in self.records:
            parse_model(start, r.trace.experiment)
        self.spec = parse_model(start)
        self.base_effects = tuple(self.spec.effects)
        self.n_nuisance = sum(len(r.nuisance) for r in self.records)
        self.steps: list[CampaignStep] = []
        self.removals: list[Removal] = []
        self.refinements: list[Refinement] = []
        self.fits: list[CampaignFit] = []
        self.cur: CampaignFit | None = None   # the current model, from the start model's fit on
        self.rivals: dict = {}            # effect -> {law: the shared law of its candidate's fit}
        self.retested_at = 0              # refinements up to here were followed by the re-tests
        self.shaped_beside: dict = {}     # a shape group -> the effects named when it was last fitted
        self.refined_for: tuple = ()      # the named effects the last stages last ran for (refine_first)
        self.stop = ""
        self.cap: float | None = None
        self.cur_work: dict = {}          # one simulation's work of the current model: own_work_ratio

    def record(self, trace: Trace, mass_band, free_nuisance, samples: int) -> Record:
        """One record, its noise estimated on every sample; searched on every k-th sample where it
        has more than its share ``samples`` of the one-record search's simulated samples
        (samples.search_thinning: the campaign's simulations cost what one record's do), its final
        model fitted to every sample (on_whole_records)."""
        trace = copy.copy(trace)
        trace.mass_uncertainty_rel = NZ.mass_band_rel(trace, mass_band) if trace.rig == "payload" else None
        noise = estimate_noise(trace)
        if not noise.sigma > 0:
            raise CampaignInputError(f"{trace.csv_path}: the measured column shows no noise (a noise-free record): "
                                     "there is no scale to judge a gap against")
        every = search_thinning(trace, noise.sigma, samples)
        searched = thinned(trace, every) if every > 1 else trace
        part, held = heldout_split(searched, CRITERIA.fit_part)
        # (a law's state, NZ.LAW_STATE: the Iwan bank's memory, a preload's creep, is a record's nuisance
        # only in models with that law: the campaign's joint fits and counts of parameters do not follow the law yet)
        nuisance = tuple(n for n in nuisance_parameters(trace) if n not in NZ.LAW_STATE) if free_nuisance else ()
        self.say(f"{trace.name} ({trace.experiment}, {len(trace.time)} samples): noise {noise.sigma:.3g} m "
                 f"({noise.method})" + (f"; searched on every {ordinal(every)} sample ({len(searched.time)})"
                                        if every > 1 else ""))
        return Record(searched, nuisance, noise, part, held, _scales(searched), whole=trace, every=every)

    # ---- fits
    def law_names(self, spec: ModelSpec) -> list:
        """The shared law's free names: what any record's experiment frees (laws.free_parameters)."""
        names: list = []
        for r in self.records:
            names += [n for n in free_parameters(spec, r.trace.experiment) if n not in names]
        return names

    def evaluate(self, spec: ModelSpec, effects, params: dict, free: list, nzs: list, message: str = "",
                 seconds: float = 0.0, shape: Sequence[str] = ()) -> CampaignFit:
        """The campaign fit of ``params`` (the shared law) with each record's nuisance ``nzs``: the
        predictions of every whole record, their errors, the campaign's in noise units; ``shape``:
        the shape terms the fit freed beyond the law's (as_fitted)."""
        preds, rms = [], []
        for r, nz in zip(self.records, nzs):
            try:
                y = predict(r.trace, spec, {**params, **nz})
            except RuntimeError:
                y = np.full(r.n, np.nan)
            e = float(np.sqrt(np.mean((y - r.trace.measured) ** 2)))
            e = e if math.isfinite(e) else float("inf")
            preds.append(y)
            rms.append(e)
        return CampaignFit(spec=spec, effects=tuple(effects), params=dict(params), free=list(free),
                           rms=in_noise_units(rms, self.records), rms_records=rms, predicted=preds,
                           nz=[dict(nz) for nz in nzs], n_nuisance=self.n_nuisance, message=message, seconds=seconds,
                           ok=all(math.isfinite(e) for e in rms), shape=tuple(shape))

    def as_fitted(self, m: CampaignFit, params: dict | None = None, nzs: list | None = None) -> CampaignFit:
        """``m`` evaluated again (on the records as they are now), with other ``params`` or nuisance
        ``nzs`` where given; its free terms and shape kept."""
        return self.evaluate(m.spec, m.effects, m.params if params is None else params, m.free,
                             m.nz if nzs is None else nzs, m.message, m.seconds, m.shape)

    def engine_fit(self, traces: list, spec: ModelSpec, names: list, start: dict | None, fixed: dict,
                   max_iterations: int, work_cap: float | None, own_thread: bool):
        """One tether.fit.fit_traces run on baked records; (result or None, message). A fit past its
        work cap or the budget's deadline is abandoned (fitting._fit_once's rule)."""
        from ..fit import fit_traces

        options = dict(ENGINE_OPTIONS)
        if own_thread:
            options["n_threads"] = 1
        if self.deadline is not None and time.perf_counter() >= self.deadline:
            self.budget_hit = True
            return None, "stopped: the discovery's time budget is spent"
        options.update(idn.deadlines(wall_seconds=None if self.deadline is None else self.deadline - time.perf_counter()))
        if work_cap is not None:
            options["max_rhs_evaluations"] = float(work_cap)
        try:
            return fit_traces(traces, spec, free=names, start=start, fixed=fixed or None,
                              max_iterations=max_iterations, **options), ""
        except idn.DeadlinePassed as exc:
            if exc.clock == "wall":
                self.budget_hit = True
            return None, "stopped: the time budget is spent" if exc.clock == "wall" else "abandoned at its work cap"
        except (RuntimeError, ValueError) as exc:
            return None, " ".join(str(exc).split())

    def fit(self, spec: ModelSpec, effects, starts: Sequence[dict | None], nzs: list | None = None,
            parts: bool = False, own_thread: bool = False, max_iterations: int = 100, cap_factor: float = 1.0,
            start_nzs: Sequence[list] | None = None, extra: Sequence[str] = ()) -> CampaignFit:
        """The shared law of ``spec`` fitted to every record (or every record's first part), each
        record's nuisance held at ``nzs`` (or, start by start, at ``start_nzs``: the nuisance values
        that go with each start); from each start a few iterations where there are several, the best
        carried on; ``extra``: shape terms freed beyond the law's (those of ``spec``; a fit that
        extends or refits a model passes that model's shape, so that what a reseeding move freed
        stays free). The work caps are the search's times ``cap_factor`` (a model that simulates
        slower). The result is evaluated on the whole records (CampaignFit)."""
        t0 = time.perf_counter()
        nzs = [dict(r.nz) for r in self.records] if nzs is None else nzs
        start_nzs = [nzs] * len(starts) if start_nzs is None else list(start_nzs)
        names = self.law_names(spec)
        shape = tuple(n for n in extra if n in spec.parameters and n not in names)
        names += list(shape)
        sc = self.records[0].sc
        fixed_keys = [k for k in HELD_AT_START if k in spec.parameters and k not in names]

        def baked_records(k):
            return [baked(r.part if parts else r.trace, nz) for r, nz in zip(self.records, start_nzs[k])]

        def one(k, iterations, cap):
            start = starts[k]
            st = None if start is None else _clean_start(names, start, sc)
            fixed = {n: float(start[n]) for n in fixed_keys if start and n in start}
            return self.engine_fit(baked_records(k), spec, names, st, fixed, iterations, cap, own_thread)

        def z(res) -> float:
            """The fit's error in noise units (fit_traces' rms is the plain one over the samples fitted)."""
            n = [fitted_count(r.part) if parts else r.n for r in self.records]
            return in_noise_units(res.rms_per_trace, self.records, n)

        cap = None if self.cap is None else self.cap * cap_factor * self.own_work_ratio(spec, effects, starts[0], nzs)
        best, best_k, msg = None, 0, ""
        if len(starts) > 1:
            for k in range(len(starts)):
                r, m = one(k, QUICK_ITERATIONS, None if cap is None else 0.5 * cap)
                if r is None:
                    msg = m
                    continue
                if best is None or z(r) < z(best):
                    best, best_k = r, k
            if best is not None:
                r, m = one(best_k, max_iterations, None if cap is None else 2 * cap)
                if r is not None and z(r) <= z(best):
                    best = r
        else:
            best, msg = one(0, max_iterations, None if cap is None else 2 * cap)
        if best is None:
            return CampaignFit(spec=spec, effects=tuple(effects), params={}, free=names, rms=float("inf"),
                               rms_records=[float("inf")] * len(self.records), predicted=[], nz=nzs,
                               n_nuisance=self.n_nuisance, ok=False, message=msg or "fit failed",
                               seconds=time.perf_counter() - t0, shape=shape)
        params = {k: float(v) for k, v in best.parameters.items()}
        return self.evaluate(spec, effects, params, list(best.free), start_nzs[best_k], best.message,
                             time.perf_counter() - t0, shape)

    def refit_nuisance(self, spec: ModelSpec, params: dict, nzs: list | None = None, own_thread: bool = False,
                       keep: int | None = None) -> list:
        """Each record's nuisance values fitted with the shared law ``params`` held (a short fit per
        record, from ``nzs``, default the records' current values); a record whose fit fails, and
        record ``keep``, keep their values."""
        from ..fit import fit_traces

        nzs = [r.nz for r in self.records] if nzs is None else nzs
        options = {**ENGINE_OPTIONS, **({"n_threads": 1} if own_thread else {})}
        out = []
        law = _law_only(params, spec)
        for i, (r, nz) in enumerate(zip(self.records, nzs)):
            if not r.nuisance or i == keep:
                out.append({} if not r.nuisance else dict(nz))
                continue
            start = {}
            for k in r.nuisance:
                lo, hi, s, _ = NZ.nuisance_box(r.trace, k)
                start[k] = min(max(float(nz.get(k, s)), lo), hi)
            try:
                res = fit_traces([r.trace], spec, free=list(r.nuisance), start=start, fixed=law, max_iterations=30,
                                 **options)
                out.append({k: float(res.values[k]) for k in r.nuisance})
            except (RuntimeError, ValueError):
                out.append(dict(nz))
        return out

    def lead_starts(self, spec: ModelSpec, law: dict, nzs: list, lead: int, alone: ModelFit,
                    own_thread: bool = False) -> tuple:
        """The starts of a joint fit from ``law``, fitted to record ``lead`` alone (``alone``) and
        completed by the model it extends: the lead's nuisance from that fit, every other record's
        as it is (``nzs``) and, as a second start, refitted under ``law``. Held where the law it
        replaces left them, the others' nuisance values may carry what that law missed and sink the
        start; refitted, they may absorb what the lead's law has wrong of a record that shows it
        better (docs/campaign-discovery.md, "The search"). (starts, start_nzs)"""
        held = [dict(nz) for nz in nzs]
        held[lead] = dict(alone.nuisance)
        refitted = self.refit_nuisance(spec, law, held, own_thread, keep=lead)
        return ([law], [held]) if refitted == held else ([law, law], [held, refitted])

    def candidate_fit(self, effect: str, spec: ModelSpec, effects, lead: int, starts, own_thread: bool = False,
                      cap_factor: float = 1.0) -> CampaignFit:
        """A candidate fitted to the campaign. First to one record alone, the one that shows it best
        (lead_fit), that record's nuisance free: the nuisance values of the model it extends may
        carry what the new effect explains (a free vibration's release point bent by a law without
        slack: held there, a joint fit with slack stopped at 1,100 x noise where the record alone
        reached 1.0 x). Then the shared law to all records from two starts: that record's law (its
        nuisance at its own fit's values, every other record's as it is or refitted under that law:
        lead_starts), and the campaign's current law with the new terms at that record's
        values (every record's nuisance at its current values: one record's law may
        suit that record alone, and a joint fit from it ended above the model it extends, a
        campaign of seed 1000's creep); where that record's fit fails, from the current law and
        from the campaign's data-based estimate. Then once the records' nuisance refitted and the
        law again. The work caps are the search's times ``cap_factor`` (cap_factor_for). The fit's
        ``lead``: the record it was fitted to alone."""
        t0 = time.perf_counter()
        cap = None if self.cap is None else self.cap * cap_factor
        lead, alone = self.lead_fit(effect, spec, effects, lead, starts, own_thread, cap)
        nzs = [dict(x.nz) for x in self.records]
        if alone.ok:
            lead_law = _law_only(alone.params, spec)
            starts, start_nzs = self.lead_starts(spec, {**self.cur.params, **lead_law}, nzs, lead, alone, own_thread)
            f = self.fit(spec, effects, starts + [{**lead_law, **self.cur.params}], start_nzs=start_nzs + [nzs],
                         own_thread=own_thread, cap_factor=cap_factor, extra=self.cur.shape)
        else:
            f = self.fit(spec, effects, [self.cur.params, None], nzs=nzs, own_thread=own_thread,
                         cap_factor=cap_factor, extra=self.cur.shape)
        f = self.nuisance_then_law(f, own_thread, cap_factor)
        f.seconds, f.lead = time.perf_counter() - t0, lead
        return f

    def lead_fit(self, effect: str, spec: ModelSpec, effects, lead: int, starts, own_thread: bool,
                 cap: float | None) -> tuple:
        """The candidate ``spec`` fitted alone to the record that shows it best: to ``lead`` from
        ``starts`` and, for an effect, to every other record that can reveal it, tries its law and
        is missed by CRITERIA.unexplained_gap or more (from the one-record search's starts on it);
        of these, the record whose gap above its noise the candidate's own fit shrinks most, in
        units of its noise. The record the model misses most may be missed for another effect's
        sake: a creep candidate led by a load test missed for its elastic law gained nothing
        there, and led by the creep test took that record from 8.97 to 1.57 x noise (tuning
        campaign 3000, docs/campaign-discovery.md, session 40). (the record's index, its ModelFit)"""
        def gain(i: int) -> float:
            r, f = self.records[i], fits[i]
            return (_gap(self.cur.rms_records[i], r.sigma) - _gap(f.rms, r.sigma)) / r.sigma if f.ok else -math.inf

        fits = {lead: self.fit_alone(lead, spec, effects, starts, self.cur.shape, cap, own_thread)}
        for i in self.other_leads(effect, spec, lead):
            fits[i] = self.fit_alone(i, spec, effects, self.starts_on(i, spec), self.cur.shape, cap, own_thread)
        best = max(fits, key=gain)
        return best, fits[best]

    def fit_alone(self, i: int, spec: ModelSpec, effects, starts, extra: Sequence[str], cap: float | None,
                  own_thread: bool = False) -> ModelFit:
        """``spec`` fitted to record i alone from ``starts``, the record's nuisance free, ``extra`` shape
        terms free beside the law's, within the work cap ``cap`` and the budget's deadline: the first
        fit of a candidate, a shape and a finer Iwan bank, each then carried to every record."""
        r = self.records[i]
        return fit_model(r.trace, spec.for_experiment(r.trace.experiment), effects, starts, r.sc, nuisance=r.nuisance,
                         work_cap=cap, own_thread=own_thread, deadline=self.deadline, extra=extra)

    def other_leads(self, effect: str, spec: ModelSpec, lead: int) -> list:
        """The records but ``lead`` that can reveal ``effect`` (laws.candidates), try the law ``spec``
        gives it (laws._models_for) and that the current model misses by CRITERIA.unexplained_gap or
        more (none for the current model refitted, ``effect`` empty)."""
        if not effect:
            return []
        return [i for i, r in enumerate(self.records) if i != lead and effect in candidates(r.trace)
                and leaves_unexplained(self.cur.rms_records[i], r.sigma)
                and any(m.canonical == spec.canonical for m in _models_for(self.cur.spec, effect, r.trace))]

    def nuisance_then_law(self, f: CampaignFit, own_thread: bool = False, cap_factor: float = 1.0) -> CampaignFit:
        """``f`` with every record's nuisance refitted once under its law and the law fitted again
        (a short fit); kept where it lowers the campaign's error."""
        if not f.ok or self.budget_hit:
            return f
        nzs = self.refit_nuisance(f.spec, f.params, f.nz, own_thread)
        moved = self.as_fitted(f, nzs=nzs)
        if not moved.rms < (1.0 - CRITERIA.least_gain) * f.rms:
            return f
        refit = self.fit(f.spec, f.effects, [f.params], nzs=nzs, own_thread=own_thread, max_iterations=30,
                         cap_factor=cap_factor, extra=f.shape)
        return refit if refit.ok and refit.rms < moved.rms else moved

    def simulation_work(self, spec: ModelSpec, effects, params: dict, free, nzs: list) -> int:
        """The work of one simulation of the campaign (every record) in evaluations of the model's
        equations: the unit of the work caps."""
        before = idn.simulation_work()
        self.evaluate(spec, effects, params, free, nzs)
        return idn.simulation_work() - before

    def own_work_ratio(self, spec: ModelSpec, effects, start: dict | None, nzs: list) -> float:
        """One simulation of the campaign with ``spec`` from ``start`` against one with the current
        model, in work (at least 1): the caps count simulations of the model being fitted where it
        simulates slower (Search.own_work_ratio's rule)."""
        cur = self.cur
        if start is None or cur is None:
            return 1.0
        if id(cur) not in self.cur_work:
            self.cur_work[id(cur)] = self.simulation_work(cur.spec, cur.effects, cur.params, cur.free, cur.nz)
        own = self.simulation_work(spec, effects, _law_only(start, spec), self.law_names(spec), nzs)
        return work_ratio(own, self.cur_work[id(cur)])

    def cap_factor_for(self, m: CampaignFit) -> float:
        """The work cap for fits that extend ``m``, as a multiple of the search's (counted in
        simulations of the campaign with the start model): one simulation of ``m`` over the
        campaign against one of the start model, times the ratio of the free parameters (each
        Jacobian needs one simulation per parameter), at least 1 (Search.extension_cap_factor's
        rule; without it, the fits of a campaign with an Iwan bank were abandoned at the cap)."""
        per_simulation = self.simulation_work(m.spec, m.effects, m.params, m.free, m.nz) / max(self.w_sim_start, 1)
        return max(1.0, per_simulation) * max(1.0, (m.n_free + 1) / (self.n_free_start + 1))

    def settle(self, m: CampaignFit) -> CampaignFit:
        """The nuisance values and the shared law fitted in turn (SETTLE_ROUNDS rounds) from ``m``;
        each round kept where it lowers the campaign's error."""
        for r, nz in zip(self.records, m.nz):
            r.nz = dict(nz)
        for _ in range(SETTLE_ROUNDS):
            if self.budget_hit:
                break
            nzs = self.refit_nuisance(m.spec, m.params)
            moved = self.as_fitted(m, nzs=nzs)
            if not moved.rms < (1.0 - CRITERIA.least_gain) * m.rms:
                break
            for r, nz in zip(self.records, nzs):
                r.nz = dict(nz)
            refit = self.fit(m.spec, m.effects, [m.params], max_iterations=30, extra=m.shape)
            m = refit if refit.ok and refit.rms < moved.rms else moved
        for r, nz in zip(self.records, m.nz):
            r.nz = dict(nz)
        return m

    def adopt(self, m: CampaignFit, held: float = float("nan")) -> None:
        """``m`` settled (settle) as the current model, on record in ``fits``; its held-out error
        ``held`` where the settling kept ``m`` itself and ``held`` was measured, else measured again."""
        self.cur = self.settle(m)
        self.cur_held = held if self.cur is m and not math.isnan(held) else self.heldout_of(self.cur)
        self.fits.append(self.cur)

    def worst_record(self, m: CampaignFit, among: Sequence[int] | None = None) -> int:
        """Of the records ``among`` (indices; every record where None), the one ``m`` misses most in
        units of its noise."""
        among = range(len(self.records)) if among is None else among
        return max(among, key=lambda j: m.rms_records[j] / self.records[j].sigma)

    def heldout_of(self, m: CampaignFit, among: Sequence[int] | None = None) -> float:
        """The campaign's held-out error in noise units: each record's held-out part predicted by the
        law fitted to every record's first part (the nuisance held at the whole records' values),
        pooled over the records ``among`` (indices; default every record)."""
        if not m.ok:
            return float("inf")
        pf = self.fit(m.spec, m.effects, [m.params], nzs=m.nz, parts=True, extra=m.shape)
        if not pf.ok:
            return float("inf")
        among = range(len(self.records)) if among is None else among
        zsq, n = 0.0, 0
        for i in among:
            r, nz = self.records[i], m.nz[i]
            try:
                y = predict(r.trace, m.spec, {**pf.params, **nz})
            except RuntimeError:
                return float("inf")
            zsq += float(np.sum(((y - r.trace.measured)[r.held] / r.sigma) ** 2))
            n += int(np.count_nonzero(r.held))
        v = math.sqrt(zsq / max(n, 1))
        return v if math.isfinite(v) else float("inf")

    # ---- the run
    def run(self) -> CampaignDiscovery:
        self.fit_start()
        self.add_effects()
        self.resume_steps(self.last_stages())
        if any(r.every > 1 for r in self.records):
            self.on_whole_records()
        contradicting, alone = self.contradictions()
        for r, e in zip(self.records, self.cur.rms_records):
            self.say(f"{r.name}: RMS error {e / r.sigma:.2f} x noise")
        return CampaignDiscovery(records=self.records, fits=self.fits, steps=self.steps, start_model=self.spec.canonical,
                                 stop_reason=self.stop, seconds=time.perf_counter() - self.t_begin,
                                 contradicting=contradicting, alone=alone, removals=self.removals,
                                 refinements=self.refinements)

    def add_effects(self) -> None:
        """The steps, until one adds nothing, every record is within the noise, the most steps are
        taken or the budget is spent; the reason on record (stop)."""
        while len(self.steps) < self.max_steps and not self.budget_hit:
            if self.within_noise(self.cur):
                self.stop = "every record is reproduced within the noise"
                return
            if not self.step():
                return
        if self.budget_hit:
            self.stop = self.stop or f"the time budget of {self.budget:.0f} s was spent"
        else:
            self.stop = f"the most steps ({self.max_steps}) were taken"

    def refine_first(self) -> bool:
        """Where the campaign's error leaves a gap below CRITERIA.unexplained_gap (in noise units, the
        one-record search's bar for searching again after its shapes), the last stages run before a
        further step, once for each set of named effects: what is left may be a named law's shape or
        a finer bank, and an effect named for it would then stay (tuning campaign 3021,
        docs/campaign-discovery.md, session 44). Not where they last ran for the same named effects
        (the steps resumed after them). True where they ran."""
        named = tuple(self.named())
        if not named or named == self.refined_for or leaves_unexplained(self.cur.rms, 1.0):
            return False
        self.say(f"near the noise ({self.cur.rms:.2f} x): the named laws refined before a further step")
        self.last_stages()
        return True

    def resume_steps(self, kept: list) -> None:
        """The steps once more where the last stages kept a law (``kept``: its effects) and a record is
        still missed: an effect refused beside a law's wrong form may earn its place once the form is
        right, as one named beside it may not (retest_after_refinements). The last stages again where
        an effect is added. (A tuning campaign of creep, hysteresis and slack: creep refused on its
        held-out parts beside Bouc-Wen, passed beside the finer Iwan bank, every record within 1.02 x
        its noise; docs/campaign-discovery.md.)"""
        if not kept or self.budget_hit or self.within_noise(self.cur) or len(self.steps) >= self.max_steps:
            return
        self.say(f"the steps resume beside the refined laws ({', '.join(kept)})")
        named = len(self.named())
        self.add_effects()
        if len(self.named()) > named:
            self.last_stages()

    def last_stages(self) -> list:
        """Where a record is still missed after the steps: the shapes of the named laws, the rival
        hysteresis law, a finer Iwan bank, the wider laws, then the named effects tested again beside
        what changed; the effects whose law a stage changed (kept refinements)."""
        first = len(self.refinements)
        for stage in (self.refine_shapes, self.rival_law, self.finer_bank, self.wider_laws,
                      self.retest_after_refinements):
            if not self.budget_hit:
                stage()
        self.refined_for = tuple(self.named())
        return sorted({r.effect for r in self.refinements[first:] if r.accepted})

    def per_record(self, m: CampaignFit) -> str:
        """Each record's error in units of its noise, for the progress lines."""
        return ", ".join(f"{r.name} {e / r.sigma:.2f}" for r, e in zip(self.records, m.rms_records))

    def within_noise(self, m: CampaignFit) -> bool:
        return all(e <= CRITERIA.within_noise * r.sigma for e, r in zip(m.rms_records, self.records))

    def wider_laws(self) -> None:
        """The one-record search's wider laws (rival.wider_law) on the campaign: where a record is
        still missed, each named effect that has a wider law (laws.WIDER_LAWS: primary creep for the
        Kelvin cells and slip, the exponential stiffness for the cubic) is fitted again with it in
        its place, from rival._wider_law_starts on the record that shows the effect worst, to every
        record jointly (each record's nuisance refitted once with it), and kept as a rival law is
        (judge._law_judged on the campaign's error in noise units: a lower BIC and error, the
        held-out parts' prediction no worse). (A creep test of the generator's log-kernel creep
        bent the shared law so that a quiet free vibration beside it stayed at 2.5 x its noise.)"""
        for effect, (law, other) in WIDER_LAWS.items():
            cur = self.cur
            if self.budget_hit or self.within_noise(cur) or effect not in cur.effects or _law_of(cur.spec, effect) != law:
                continue
            able = self.revealed_named(effect)
            if able == ():
                continue
            i = self.worst_record(cur, able)
            lead = self.records[i]
            new = _with_law(cur.spec, effect, other)
            base = ModelFit(spec=cur.spec.for_experiment(lead.trace.experiment), effects=cur.effects,
                            params=dict(cur.params), free=list(cur.free), rms=cur.rms_records[i],
                            predicted=cur.predicted[i])     # (the record baked: its nuisance in it)
            starts = _wider_law_starts(baked(lead.trace, lead.nz), base, new.for_experiment(lead.trace.experiment),
                                       effect, law)
            self.swap_law(effect, law, new, [{**cur.params, **st} for st in starts],
                          lambda k, free=tuple(cur.free): k not in free)

    def rival_law(self) -> None:
        """The one-record search's rival law (rival.rival_law) on the campaign: where a record is
        still missed and the hysteresis was not the last effect named or the campaign still leaves
        something unexplained (a gap of CRITERIA.unexplained_gap in some record), the hysteresis law
        is fitted again with its rival in its place (the Iwan bank for Bouc-Wen and back), to every
        record jointly, from the rival's own fit of its step with the current model's other terms,
        with its own elastic law as well, matched to the current law's stiffness and force
        (rival._law_converted), and from the data-based estimate (the only start where the rival's
        fit failed in its step); kept as a wider law is (swap_law).
        A step chooses the law beside the effects named so far; one named after it can change which
        law fits best."""
        effect, cur = "hysteresis", self.cur
        law = cur.spec.hysteresis
        if self.within_noise(cur) or law not in RIVAL_LAWS[effect] or effect not in self.named():
            return
        still_missing = any(leaves_unexplained(e, r.sigma)
                            for e, r in zip(cur.rms_records, self.records))
        if self.named()[-1:] == [effect] and not still_missing:
            return
        other = next(x for x in RIVAL_LAWS[effect] if x != law)
        # (where the rival's fit failed in its step, from the data-based estimate alone: a failed
        # short fit is no verdict on a law, as in the one-record search)
        rival = self.rivals.get(effect, {}).get(other, {})
        new = replace(cur.spec, hysteresis=other)
        mine = {k: v for k, v in cur.params.items() if k in new.parameters and k not in HYSTERESIS_PARAMETERS[law]}
        theirs = {k: v for k, v in rival.items() if k in HYSTERESIS_PARAMETERS[other]}
        their_elastic = {k: v for k, v in rival.items() if k in ELASTIC_PARAMETERS and k in new.parameters}
        L0 = float(self.records[0].trace.length_m)
        starts = [{**mine, **theirs}, {**mine, **theirs, **their_elastic},
                  {**mine, **theirs, **_law_converted(cur.params, law, theirs, L0)}, None]
        self.swap_law(effect, law, new, starts, lambda k: k in HYSTERESIS_PARAMETERS[other])

    def named(self) -> list:
        """The effects the search added that the current model has, in the order they were added."""
        return [s.effect for s in self.steps if s.effect and s.effect in self.cur.effects]

    def swap_law(self, effect: str, law: str, new: ModelSpec, starts: list, reported: Callable[[str], bool]) -> None:
        """``new`` (the current model with another law of ``effect`` in ``law``'s place) fitted to
        every record from ``starts`` (each record's nuisance refitted once with it) and kept as a
        rival law is (judge._law_judged on the campaign's error in noise units: a lower BIC and error,
        the held-out parts' prediction no worse; a hysteresis rival refused is judged again with its
        Iwan bank made finer, reseeded_rival); on record as a Refinement whose terms are the fit's
        free terms ``reported`` selects."""
        cur = self.cur
        other = _law_of(new, effect)
        factor = self.cap_factor_for(cur)
        fm = self.nuisance_then_law(self.fit(new, cur.effects, starts, cap_factor=factor, extra=cur.shape),
                                    cap_factor=factor)
        held, bic = float("nan"), float("inf")
        if not fm.ok:
            ok, verdict = False, f"the fit failed: {fm.message}"
        else:
            bic = bic_change(cur, fm, self.n)
            if bic < 0.0 and fm.rms < cur.rms:
                held = self.heldout_of(fm)
            ok, verdict = _law_judged(cur.rms, fm.rms, bic, self.cur_held, held, 1.0, law)
            if not ok and effect == "hysteresis" and not self.budget_hit:
                fm, held, bic, ok, verdict = self.reseeded_rival(cur, fm, held, bic, verdict, law)
        ok = ok and not self.budget_hit
        terms = tuple(k for k in fm.free if reported(k)) if fm.ok else ()
        self.refinements.append(Refinement(effect, terms, cur.rms, fm.rms, self.cur_held, held, bic, ok, verdict,
                                           {k: float(fm.params[k]) for k in terms}, law=f"{law} -> {other}"))
        self.say(f"law of {effect}, {law} -> {other}: {'kept' if ok else 'not kept'}: {verdict}")
        if ok:
            self.adopt(fm, held)

    def on_whole_records(self) -> None:
        """A search on thinned records carried to the whole records (the one-record search's
        _on_whole_record): every model in turn evaluated on every sample of every record, the
        errors of the steps and removals with them; the final model fitted once more to the whole
        records from the search's values (WHOLE_RECORD_ITERATIONS, each record's nuisance refitted
        once with it), kept where it is no worse."""
        for r in self.records:
            r.trace = r.whole
            r.part, r.held = heldout_split(r.whole, CRITERIA.fit_part)
            r.sc, r.every = _scales(r.whole), 1
        self.n = sum(r.n for r in self.records)
        carried: dict = {}

        def whole(m: CampaignFit | None) -> CampaignFit | None:
            if m is None or not m.ok:
                return m
            if id(m) not in carried:
                carried[id(m)] = self.as_fitted(m)
            return carried[id(m)]

        self.fits = [whole(m) for m in self.fits]
        for st in self.steps:
            st.fit_before, st.fit_after = whole(st.fit_before), whole(st.fit_after)
            st.rms_before, st.records_before = st.fit_before.rms, list(st.fit_before.rms_records)
            if st.fit_after is not None:
                st.rms_after, st.records_after = st.fit_after.rms, list(st.fit_after.rms_records)
            for c in st.candidates:
                c.fit = carried.get(id(c.fit), c.fit)
        by_model = {}
        for m in self.fits:
            by_model.setdefault(m.model, m)
        for x in self.removals:
            x.rms_before, x.rms_after = by_model[x.model_before].rms, by_model[x.model_after].rms
        self.cur = self.fits[-1]
        if self.budget_hit:
            return
        self.say(f"fitting {self.cur.model} to the whole records")
        factor = self.cap_factor_for(self.cur)
        fitted = self.fit(self.cur.spec, self.cur.effects, [self.cur.params], nzs=self.cur.nz,
                          max_iterations=WHOLE_RECORD_ITERATIONS, cap_factor=factor, extra=self.cur.shape)
        fitted = self.nuisance_then_law(fitted, cap_factor=factor)
        if fitted.ok and fitted.rms <= self.cur.rms:
            self.fits[-1] = self.cur = fitted
        for r, nz in zip(self.records, self.cur.nz):
            r.nz = dict(nz)
        self.say(f"{self.cur.model} on the whole records: campaign RMS error {self.cur.rms:.2f} x noise")

    def fit_start(self) -> None:
        """Each record's start model alone (its nuisance values from the data, as the one-record
        search starts), then the shared law fitted to all records from each record's values, the
        best settled; the work cap of the search's fits: CAP_SIMULATIONS simulations of the campaign."""
        self.say(f"fitting the start model {self.spec.canonical} to each record alone")
        starts: list = [None]
        for r in self.records:
            nz0 = nuisance_start(r.trace, r.nuisance)
            alone = fit_model(r.trace, self.spec.for_experiment(r.trace.experiment), self.base_effects,
                              [nz0, None] if nz0 else [None], r.sc, nuisance=r.nuisance)
            if not alone.ok:
                raise DiscoveryError(f"{r.trace.csv_path}: the start model {self.spec.canonical} does not fit: "
                                     f"{alone.message}")
            r.nz = dict(alone.nuisance)
            r.alone = {"law": dict(alone.law_params), "nz": dict(alone.nuisance)}
            starts.append(alone.law_params)
            self.say(f"  {r.name} alone: RMS error {alone.rms / r.sigma:.2f} x noise")
        self.w_sim_start = self.simulation_work(self.spec, self.base_effects, starts[1], self.law_names(self.spec),
                                                [r.nz for r in self.records])
        self.cap = CAP_SIMULATIONS * self.w_sim_start
        self.say(f"fitting the start model {self.spec.canonical} to the {len(self.records)} records jointly")
        cur = self.fit(self.spec, self.base_effects, starts)
        if not cur.ok:
            raise DiscoveryError(f"the start model {self.spec.canonical} does not fit the campaign jointly: "
                                 f"{cur.message}")
        self.adopt(cur)
        self.n_free_start = self.cur.n_free
        self.say(f"{self.cur.model}: campaign RMS error {self.cur.rms:.2f} x noise (" + ", ".join(
            f"{r.name} {e / r.sigma:.2f}" for r, e in zip(self.records, self.cur.rms_records)) + ")")

    def retest_named(self, step: CampaignStep) -> None:
        """Does an effect named in an earlier step still earn its parameters on the campaign beside
        the one just added (the one-record search's re-test, Search.retest_named, by the one judge
        on the campaign's error in noise units)? The model without it is fitted to every record
        (each record's nuisance refitted once with it); the first that does not earn its place is
        removed and the model settled again. (A campaign of seed 1000 named a cubic law for the
        free vibration's misfit while the creep it lacked was still missing.)"""
        self.retest([x for x in self.cur.effects if x not in self.base_effects and x != step.effect], step,
                    step.effect)
        self.retested_at = len(self.refinements)

    def retest_after_refinements(self) -> None:
        """Every named effect tested again where a last stage put another law in (the rival or a
        wider law) after the last step's re-tests (the one-record search's
        Search.retest_after_refinements): an effect named to make up for a law's wrong form need
        not earn its place once the form is right. Not tested: an effect whose own law alone
        changed (judge.retested_beside_refinements); removed one at a time, the rest tested again
        after each removal."""
        changed = {r.effect for r in self.refinements[self.retested_at:] if r.accepted}
        if not changed or not self.steps:
            return
        beside = "the refined laws (" + ", ".join(sorted(changed)) + ")"
        while not self.budget_hit and self.retest(
                retested_beside_refinements(self.cur.effects, self.base_effects, changed),
                self.steps[-1], beside):
            pass
        self.retested_at = len(self.refinements)

    def retest(self, effects: Sequence[str], step: CampaignStep, beside: str) -> bool:
        """Each of ``effects`` tested again beside the current model (retest_named), on record in
        ``step``'s re-tests; the first that no longer earns its place is removed. True where one was."""
        cur = self.cur
        factor = self.cap_factor_for(cur)
        for e in effects:
            red = _without(cur.spec, e)
            effects = tuple(x for x in cur.effects if x != e)
            rf = self.fit(red, effects, _reduced_starts(cur, red, self.records[0].sc), cap_factor=factor,
                          extra=cur.shape)
            rf = self.nuisance_then_law(rf, cap_factor=factor)
            if not rf.ok or self.budget_hit:
                continue
            bic = bic_change(rf, cur, self.n)
            if self.within_noise(rf):          # judge.retest_verdict's rule, on every record
                w = self.worst_record(rf)
                keep, why = False, within_noise_without(rf.rms_records[w] / self.records[w].sigma)
            else:
                keep, why = self.effect_verdict(e, rf, cur, bic, cur.n_free - rf.n_free)
            step.retests.append(Retest(e, bic, keep, why, None if beside == step.effect else beside))
            self.say(f"  re-test of {e} beside {beside}: without it {rf.rms:.2f} x noise ({why}): "
                     + ("kept" if keep else "removed"))
            if keep:
                continue
            self.removals.append(Removal(e, cur.model, rf.model, cur.rms, rf.rms,
                                         f"next to {beside} it no longer earns its parameters: {why}"))
            self.adopt(rf)
            return True
        return False

