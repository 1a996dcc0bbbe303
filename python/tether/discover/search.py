"""The search: discover() and its loop (add effects, re-test them, refine the shapes, swap the
rival laws, carry a thinned search to the whole record)."""

from __future__ import annotations

import copy
import math
import time
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from ..blas import in_one_blas_thread
from ..models import HYSTERESIS_PARAMETERS, parse_model
from ..traces import Trace
from .document import _evidence, _slack_seen_by, ordinal
from .evidence import disagreement, regime_table, regimes, signatures
from .fitting import (_heldout, _side_by_side, CAP_SIMULATIONS, DEFAULT_BUDGET, fit_cost, fit_model, MODEL_RTOL,
                      ModelFit, predict, SECOND_SEARCH_CAP_SHARE, work_ratio)
from .judge import (CRITERIA, _gap, _not_kept_for_budget, _partial_damping_gain, _slack_acts, acts_as_itself,
                    bic_change, full_data_verdict, heldout_verdict, leaves_unexplained, retested_beside_refinements,
                    refuse_tied_effects, retest_verdict, slack_heldout_unasked, table_to_try,
                    tie_stop_reason)
from .laws import (_law_of, _models_for, _replaced, _without, candidates, DAMPING_TABLE, EFFECT, LAW_FIELD,
                   RIVAL_LAWS)
from .plan import PLAN
from ..noise import estimate_noise
from .nuisance import data_start, nuisance_parameters, nuisance_start
from .. import nuisance as NZ
from .records import CandidateResult, Discovery, DiscoveryError, Refinement, Removal, Retest, Step
from .refine import _knots_unseen, _shape_groups, refine_shapes
from . import rival
from .branch import RivalBranch
from .pairs import PairStep
from .runner_up import RunnerUpSwap
from .stand_in import StandIn
from .rival import IWAN_STAGE_CAP_FACTOR
from .samples import held_out_spans, heldout_split, search_thinning, thinned, WHOLE_RECORD_ITERATIONS
from .scales import _scales
from .starts import _damping_table_starts, _reduced_starts, candidate_starts, kept_shape


def _refit_without_slack(trace: Trace, cur: ModelFit, results: Sequence, sigma: float) -> ModelFit | None:
    """A slack candidate that never goes slack is the current model with other values (slack adds no
    parameter); where the search stops and such a fit is lower than the current one, it is the
    current model better fitted: returned with slack off (its prediction the same to 0.01 x noise),
    else None. The generator's free vibration with Iwan friction and Gaussian damping stopped at
    50.4 x noise where the slack candidate's refit of the same model reached 24.7 x."""
    for c in results:
        fm = c.fit
        if (c.effect != "slack" or fm is None or not fm.ok or not fm.rms < (1.0 - CRITERIA.least_gain) * cur.rms
                or _slack_acts(trace, cur.spec, fm, sigma, "")[0]):
            continue
        params = {k: fm.params[k] for k in cur.params if k in fm.params}
        y = predict(trace, cur.spec, params)
        rms = float(np.sqrt(np.mean((y - np.asarray(trace.measured, float)) ** 2)))
        if rms < cur.rms:
            return replace(cur, params=params, rms=rms, predicted=y, evaluations=fm.evaluations,
                           seconds=fm.seconds, message=fm.message, std_error=dict(fm.std_error),
                           unidentifiable=list(fm.unidentifiable), best_start=fm.best_start)
    return None


def _outranked(results: Sequence, win: CandidateResult) -> None:
    """One effect is added per step: every other candidate that passed is not accepted, and its
    verdict says it passed and which one won (the step's record must not mark it added); those
    and the ones the held-out test set aside for a better candidate name the winner."""
    for c in results:
        if c is win or not (c.accepted or c.outranked_by):
            continue
        if c.accepted:
            c.accepted = False
            c.verdict += (f"; passes, but {win.effect} lowers the BIC more ({win.bic_change:+.0f} against "
                          f"{c.bic_change:+.0f}) and is added in its place")
        c.outranked_by = win.effect


@in_one_blas_thread
def discover(trace: Trace, start: str = "linear", progress: Callable[[str], None] | None = None,
             max_steps: int = 4, heldout_candidates: int = 2, budget: float | None = DEFAULT_BUDGET,
             mass_band: float | None = None, free_nuisance: bool = True) -> Discovery:
    """Run the discovery loop on one trace (see the package docstring). ``progress`` receives one
    line per stage. ``budget`` [s] bounds the run: a step whose fits are not all done when it is
    spent adds nothing, and the discovery stops with the model it has, saying so. Every fit frees
    the record's nuisance parameters (discover.nuisance.nuisance_parameters) unless
    ``free_nuisance`` is false; ``mass_band``: the effective mass's band, relative to
    payload_mass_kg (default: the trace's mass_uncertainty_rel, else
    tether.nuisance.DEFAULT_MASS_BAND; 0 = the mass is exact)."""
    trace = copy.copy(trace)
    trace.mass_uncertainty_rel = NZ.mass_band_rel(trace, mass_band) if trace.rig == "payload" else None
    nuisance = tuple(nuisance_parameters(trace)) if free_nuisance else ()
    return Search(trace, start, progress, max_steps, heldout_candidates, budget, nuisance).run()


class Search(PairStep, RunnerUpSwap, StandIn, RivalBranch):
    """One discovery run: the record (searched, and whole where the search thins it), its noise and
    held-out split, the current fit and its held-out error, the steps, removals and refinements so
    far, the work caps and the budget. run() takes the stages in turn: the search for effects
    (step by step, each named effect re-tested once a later one is in), the shapes of the named
    laws, a second search from a refined model, the Iwan bank's last stages and the rival law, and
    the fit to the whole record."""

    def __init__(self, trace: Trace, start: str, progress: Callable[[str], None] | None, max_steps: int,
                 heldout_candidates: int, budget: float | None, nuisance: Sequence[str] = ()):
        self.t_begin = time.perf_counter()
        self.nuisance = tuple(nuisance)  # freed in every fit from the start model on
        self.budget = budget
        self.deadline = None if budget is None else self.t_begin + float(budget)
        self.budget_hit = False          # a fit ran past the deadline: what it judged cannot be taken
        self.cur_work: dict = {}         # one simulation's work of the current model, by (model, record): own_work_ratio
        self.say = progress or (lambda s: None)
        self.max_steps, self.heldout_candidates = max_steps, heldout_candidates
        self.noise = estimate_noise(trace)
        self.sigma = self.noise.sigma
        if not self.sigma > 0:
            raise DiscoveryError(f"{trace.name}: the measured column shows no noise (a noise-free record): there "
                                 "is no scale to judge a gap against")
        self.say(f"noise {self.sigma:.3g} m ({self.noise.method})")
        self.whole = trace
        self.every = search_thinning(self.whole, self.sigma)
        if self.every > 1:
            trace = thinned(self.whole, self.every)
            self.say(f"searching on every {ordinal(self.every)} sample ({len(trace.time)} of {len(self.whole.time)}); "
                     f"the final model is fitted to the whole record")
        self.trace = trace
        self.sc = _scales(trace)
        self.n = len(trace.time)
        self.part, self.held_out = heldout_split(trace, CRITERIA.fit_part)
        self.sc_part = _scales(self.part)
        self.spec = parse_model(start, trace.experiment)
        self.base_effects = tuple(self.spec.effects)
        self.shape_free: tuple = ()      # shape terms a refinement freed, kept free in every later fit
        self.shape_held: tuple = ()      # and the terms they replace, held (at 0) in every later fit
        self.steps: list[Step] = []
        self.removals: list[Removal] = []
        self.refinements: list[Refinement] = []
        self.rivals: dict = {}           # effect -> {law: parameters of its candidate's fit}
        self.retested_at = 0             # len(refinements) when the named effects were last re-tested
        self.search_again = False        # the plan's second search for effects is due (refine_shapes_first)
        self.effects_before_again = ()   # the named effects when the second search began
        self.rival_kept = False          # the rival law was kept (swap_rival)
        self.law_candidates: dict = {}   # effect -> the candidates of each of its laws in this step
        self.branch = None               # the search with a tied law in the winner's place (branch.py)
        self.branched = False            # this search is such a branch: it sets none aside
        self.stages: list[str] = []      # the plan's stages run so far, in order
        self.no_winner = False           # the last search for effects stopped with no candidate earning its place
        self.pairs_on = False            # a step without a winner tries pairs (the plan's stage "pairs")
        self.stop = ""
        self.fit_start_model()

    #: the record's own starts of its nuisance parameters (set by fit_start_model)
    nz_start: dict | None = None

    def fit_start_model(self) -> None:
        """The start model, fitted; the work cap of the search's fits, CAP_SIMULATIONS of its simulations
        (counted in evaluations of the model's equations, as the caps are); its held-out error."""
        spec, trace = self.spec, self.trace
        own = [n for n in self.nuisance if NZ.law_refusal(n, spec) is None]
        self.say(f"fitting the start model {spec.canonical}"
                 + (f" with the nuisance parameters {', '.join(own)}" if own else ""))
        nz_start = self.nz_start = nuisance_start(trace, self.nuisance)
        starts = [data_start(trace, spec, nz_start), None] if nz_start else [None]
        cur = fit_model(trace, spec, self.base_effects, starts, self.sc, nuisance=self.nuisance)
        if not cur.ok:
            raise DiscoveryError(f"{trace.name}: the start model {spec.canonical} does not fit: {cur.message}")
        w_sim = _simulation_work(trace, cur.spec, cur.params)
        self.w_sim_start, self.n_free_start = w_sim, cur.n_free
        self.cap = CAP_SIMULATIONS * w_sim
        self.fit_cap = self.cap          # the cap of the current stage (the second search's: SECOND_SEARCH_CAP_SHARE)
        self.cur = cur
        part_fit = self.fit(self.part, spec, self.base_effects, [cur.params], self.sc_part, cap_factor=1.0)
        self.cur_held = _heldout(trace, spec, part_fit.params, self.held_out)
        self.say(f"{cur.model}: RMS error {cur.rms:.3g} m = {cur.rms / self.sigma:.2f} x noise ({cur.seconds:.1f} s)")
        self.fits = [cur]

    # ---- fits, as every stage asks for them
    def fit(self, tr, sp, eff, starts, scales, extra=(), held=(), own_thread=False, baseline_rms=None,
            cap_factor: float | None = None, **engine) -> ModelFit:
        """fit_model with the search's shape terms free (and those they replace held), the unseen
        knots of the damping table held in a fit of the first part, the stage's work cap and the
        budget's deadline; a fit that ends past the deadline marks the budget spent. The nuisance
        parameters are constants of the whole record: a fit of its first part holds them at the
        values its start carries (the whole record's fit of the same model), so that the held-out
        test judges the law, not a mass or an offset refitted to bend the first part. The work cap:
        ``cap_factor`` of the stage's, by default a step candidate's (candidate_cap_factor), counted in
        simulations of the model being fitted where it simulates slower than the current model
        (own_work_ratio). ``engine``: options of the engine for this fit (fit_model's)."""
        if cap_factor is None:
            cap_factor = self.candidate_cap_factor()
        extra = tuple(extra) + tuple(k for k in self.shape_free if k not in extra and k in sp.parameters)
        held = tuple(held) + self.shape_held
        if tr is self.part:
            held += _knots_unseen(self.part, extra, starts)
        else:
            starts = self._data_starts(tr, sp, starts)
        work_cap = cap_factor * self.fit_cap * self.own_work_ratio(tr, sp, starts[0])
        r = fit_model(tr, sp, eff, starts, scales, work_cap=work_cap, extra=extra, held=held,
                      deadline=self.deadline, own_thread=own_thread, baseline_rms=baseline_rms,
                      nuisance=() if tr is self.part else self.nuisance, **engine)
        if self.deadline is not None and time.perf_counter() > self.deadline:
            self.budget_hit = True           # this fit may have been cut short: it cannot judge
        return r

    def _data_starts(self, tr, sp, starts) -> list:
        """``starts`` with tether.fit's data-based estimate (None) read off the record as the current
        model's nuisance values describe it, and as the record's own nuisance starts do where those
        differ: a law the model lacks can bend its nuisance values (a linear law under Bouc-Wen
        shifted a toe-linear load test's offset by -0.12 m, and the toe read off the record so
        shifted came out a thirtieth of its stiffness)."""
        readings = [self.cur.nuisance] + ([self.nz_start] if self.nz_start and self.nz_start != self.cur.nuisance else [])
        out = []
        for s in starts:
            out += [data_start(tr, sp, nz) for nz in readings] if s is None else [s]
        return out

    def shape_fit(self, tr, sp, eff, starts, extra, own_thread=False, cap_factor=1.0, **engine) -> ModelFit:
        """A fit with the shape terms ``extra`` free and the terms they replace held."""
        return self.fit(tr, sp, eff, starts, self.sc_part if tr is self.part else self.sc, extra,
                        held=_replaced(extra), own_thread=own_thread, cap_factor=cap_factor, **engine)

    def own_work_ratio(self, tr: Trace, sp, start: dict | None) -> float:
        """The work of one simulation of ``sp`` from ``start`` over ``tr`` against the current model's
        (at least 1): the caps, which count simulations of the current model, count simulations of the
        model being fitted where it simulates slower. An Iwan bank makes several times the evaluations
        of the linear model it extends, and a step-1 candidate capped in the linear model's work was
        abandoned where the CPU-second caps had let it finish (docs/discovery.md, "Work caps")."""
        if start is None:
            return 1.0
        key = (id(self.cur), id(tr))
        if key not in self.cur_work:
            self.cur_work[key] = _simulation_work(tr, self.cur.spec, self.cur.params)
        try:
            own = _simulation_work(tr, sp, start)
        except (RuntimeError, ValueError):
            return 1.0
        return work_ratio(own, self.cur_work[key])

    def heldout_of(self, m: ModelFit) -> float:
        """The held-out error of ``m``: its prediction of the held-out part by its fit to the first."""
        pf = self.fit(self.part, m.spec, m.effects, [m.params], self.sc_part)
        return _heldout(self.trace, m.spec, pf.params, self.held_out) if pf.ok else float("inf")

    def model_cap_factor(self, m: ModelFit) -> float:
        """The work cap for fits of ``m``'s kind, as a multiple of the search's: the cap is CAP_SIMULATIONS
        simulations of the start model, and a model with an Iwan bank and a table of c(x) may take
        more integrator steps per simulation; at least IWAN_STAGE_CAP_FACTOR, for a restarted bank's
        start simulates slower than the bank it comes from (docs/discovery.md, "Time")."""
        return max(IWAN_STAGE_CAP_FACTOR, CAP_SIMULATIONS * _simulation_work(self.trace, m.spec, m.params) / self.cap)

    def extension_cap_factor(self, m: ModelFit) -> float:
        """The work cap for fits that extend ``m``, as a multiple of the search's (which is counted
        in simulations of the start model): each simulation costs what one of ``m`` costs, and each
        Jacobian needs one per free parameter, so both ratios to the start model's, at least 1."""
        per_simulation = _simulation_work(self.trace, m.spec, m.params) / max(self.w_sim_start, 1)
        return max(1.0, per_simulation) * max(1.0, (m.n_free + 1) / (self.n_free_start + 1))

    def out_of_budget(self, where: str) -> str:
        return (f"the time budget of {self.budget:.0f} s was spent {where}; the model is the last one that was "
                f"fully judged (rerun with a larger --budget to go on)")

    def adopt_model(self, m: ModelFit, held: float) -> None:
        """``m`` becomes the current model, with its held-out error."""
        self.cur, self.cur_held = m, held
        self.fits.append(m)

    # ---- the run: the plan's stages in turn (plan.PLAN)
    def run(self) -> Discovery:
        """Each stage of the plan whose condition holds, in the plan's order: its proposer proposes,
        has each proposal judged, adopts or refuses it and records it."""
        for stage in PLAN:
            if stage.when(self):
                getattr(self, stage.proposer)()
                self.stages.append(stage.name)
        return Discovery(trace=self.whole, noise=self.noise, start_model=self.spec.canonical, fits=self.fits,
                         steps=self.steps, stop_reason=self.stop, seconds=time.perf_counter() - self.t_begin,
                         heldout_start=float(self.trace.time[np.argmax(self.held_out)]),
                         heldout_spans=held_out_spans(self.trace, self.held_out), removals=self.removals,
                         refinements=self.refinements, searched_every=self.every,
                         nuisance_freed=bool(self.nuisance), stages=self.stages)

    def search_effects(self, cap_share: float = 1.0) -> None:
        """The search for effects, step by step until it stops, its fits capped at ``cap_share`` of
        the search's cap."""
        self.fit_cap = cap_share * self.cap
        while self.step():
            pass
        self.fit_cap = self.cap

    def refine_shapes_first(self) -> None:
        """The shapes of the named laws; where one is kept and the refined model still misses the
        record by the noise or more (CRITERIA.unexplained_gap), the search runs once more
        (search_again): a law of the wrong shape can hide a further effect behind its own misfit (a
        drag-damped record with slack was named nonlinear damping alone at 3-12 x noise), and below
        the noise too little is left to hide one (a further effect must halve the gap)."""
        before = len(self.refinements)
        held = self.reshape(self.refined_effects(), where="while the shapes of the laws were refined")
        if held is None or not leaves_unexplained(self.cur.rms, self.sigma):
            return
        self.free_shapes(tuple(k for r in self.refinements[before:] if r.accepted for k in r.parameters))
        if not math.isfinite(held):
            # (where refine_shapes asked, its fit of the first part was this one: same terms, same start)
            self.cur_held = self.heldout_of(self.cur)
        self.say(f"searching again from the refined model ({' '.join(self.shape_free)} free): RMS error "
                 f"{self.cur.rms / self.sigma:.2f} x noise")
        self.search_again = True

    def search_effects_again(self) -> None:
        """The second search for effects, from the refined model, its shape terms free and its fits
        capped at SECOND_SEARCH_CAP_SHARE of the search's cap."""
        self.effects_before_again = self.cur.effects
        self.search_effects(SECOND_SEARCH_CAP_SHARE)

    def refine_shapes_again(self) -> None:
        """The shapes of the laws not refined yet, from the model of the second search."""
        self.reshape(self.refined_effects(), where="while the shapes of the laws were refined")

    def refined_effects(self) -> set:
        """The effects whose law's shape a kept refinement changed."""
        return {r.effect for r in self.refinements if r.accepted}

    def named_again(self) -> bool:
        """The second search changed the named effects."""
        return self.cur.effects != self.effects_before_again

    def shapes_left(self) -> bool:
        """A named law has shape groups, and its effect no kept refinement yet."""
        return bool(_shape_groups(self.cur, skip=self.refined_effects()))

    def free_shapes(self, terms: tuple) -> None:
        """Shape terms kept free in every later fit, the terms they replace held."""
        self.shape_free = tuple(dict.fromkeys(self.shape_free + tuple(terms)))
        self.shape_held = _replaced(self.shape_free)

    # ---- one step of the search for effects: propose, judge, adopt, re-test
    def step(self) -> bool:
        """One step: where the model disagrees, each candidate effect fitted and judged, the winner
        added and the effects named before it re-tested beside it. False where the search stops."""
        cur, sigma, trace = self.cur, self.sigma, self.trace
        masks = regimes(trace, cur)
        windows = disagreement(trace, cur, sigma, masks)
        step = Step(model_before=cur.model, rms_before=cur.rms, heldout_before=self.cur_held, windows=windows,
                    regimes=regime_table(trace, cur, sigma, masks), candidates=[])
        self.steps.append(step)
        if cur.rms <= CRITERIA.within_noise * sigma:
            self.stop = f"the model reproduces the record within the noise (RMS error {cur.rms / sigma:.2f} x noise)"
            return False
        if len([s for s in self.steps if s.effect]) >= self.max_steps:
            self.stop = f"stopped after {self.max_steps} added effects"
            return False
        if self.deadline is not None and time.perf_counter() > self.deadline:
            self.budget_hit = True
            self.stop = self.out_of_budget(f"before step {len(self.steps)}")
            return False
        sig = signatures(trace, cur, sigma, masks)
        todo = [(e, m) for e in candidates(trace) if e not in cur.effects for m in _models_for(cur.spec, e, trace)]
        if not todo:
            self.stop = "every effect the experiment can reveal is in the model"
            return False
        results = self.judged_candidates(todo, sig)
        step.candidates = results
        if self.budget_hit:
            step.cut_short = True
            for c in results:
                c.accepted = False
                c.verdict += "; not judged to the end: the time budget ran out during this step"
                c.forget_curves()
            self.stop = self.out_of_budget(f"while the candidates of step {len(self.steps)} were fitted")
            return False
        win = results[0]
        if win.accepted and not refuse_tied_effects(results):
            _outranked(results, win)
        for c in results:
            self.say(f"  {c.effect}: {'earns' if c.accepted else 'does not earn'} its parameters: {c.verdict}")
        if not win.accepted:
            pair = self.pair_of_refused(results) if self.pairs_on and self.pair_worth_trying(results) else None
            if pair is not None:
                self.add_pair(pair, results, step, windows)
                return True
            self.stop_without_winner(results)
            if self.budget_hit:
                self.stop = self.out_of_budget(f"while pairs of effects were fitted in step {len(self.steps)}")
            return False
        self.fork_at_tie(win, step, windows)
        self.add(win, results, step, windows)
        self.retest_named(win.effect)
        return True

    def judged_candidates(self, todo: list, sig: dict) -> list:
        """The candidates (effect, model) fitted and judged, best first: on the whole record, the
        damping table where the polynomial closes part of the gap, the best law of each effect, then
        the held-out test for the best few that pass."""
        cur, sigma = self.cur, self.sigma
        results = self.fit_candidates(todo, sig)
        # a damping the polynomial c(x) follows only in part: the table of c(x)
        for cr in [c for c in results if _partial_damping_gain(c, sigma, cur.rms)]:
            results.append(self.table_candidate(cr))
        # the rival laws' fits of the effect, for rival_law at the end
        for effect in RIVAL_LAWS:
            laws = {_law_of(c.fit.spec, effect): dict(c.fit.params) for c in results
                    if c.effect == effect and c.fit is not None and c.fit.ok}
            if laws:
                self.rivals[effect] = laws
        self.law_candidates = {e: [c for c in results if c.effect == e] for e in RIVAL_LAWS}
        # an effect with several laws (hysteresis: Bouc-Wen or Iwan, in a load test Kawabata too)
        # competes with the best of them
        best_of: dict[str, CandidateResult] = {}
        for c in results:
            b = best_of.get(c.effect)
            if b is None or (c.fit.ok and (not b.fit.ok or c.bic_change < b.bic_change)):
                best_of[c.effect] = c
        results = list(best_of.values())
        self.heldout_tests(sorted([c for c in results if c.accepted], key=lambda c: c.bic_change))
        # a polynomial c(x) that earns its place on the whole record and loses it on the held-out
        # part (its x^2 term runs on beyond the displacements the first part reaches): the table of
        # c(x), whose knots beyond that reach are held (_knots_unseen), is fitted and tested in its place
        refused = None if any(c.accepted for c in results) else next(
            (c for c in results if c.effect == "nonlinear_damping" and c.fit is not None and c.fit.ok
             and table_to_try(c.fit) and math.isfinite(c.heldout_rms)
             and full_data_verdict(sigma, cur.rms, c.rms, c.bic_change, c.added_parameters)[0]), None)
        if refused is not None:
            ct = self.table_candidate(refused)
            if ct.accepted:
                self.heldout_test(ct, " (table of c(x))")
            results.append(ct)
        results.sort(key=lambda c: (not c.accepted, c.bic_change))
        return results

    def fit_candidates(self, todo: list, sig: dict) -> list:
        """Each candidate model fitted (side by side: they are independent) and judged on the whole
        record."""
        cur, sigma = self.cur, self.sigma
        jobs = [(eff, new, candidate_starts(cur, new, self.sc, self.trace)) for eff, new in todo]
        factor = self.candidate_cap_factor()
        candidate_fits = _side_by_side(
            lambda job, alone, _effects=cur.effects, _rms=cur.rms: self.fit(
                self.trace, job[1], _effects + (job[0],), job[2], self.sc, own_thread=alone, baseline_rms=_rms,
                cap_factor=factor), jobs, cost=lambda job: fit_cost(job[1], self.trace.experiment))
        results = []
        for (eff, new, _), fm in zip(jobs, candidate_fits):
            dk = fm.n_free - cur.n_free
            cr = CandidateResult(effect=eff, model=fm.model, added_parameters=dk, rms=fm.rms,
                                 heldout_rms=float("nan"), bic_change=bic_change(cur, fm, self.n),
                                 signature=float(sig.get(eff, {}).get("score", 0.0)),
                                 signature_text=sig.get(eff, {}).get("text", ""), fit=fm)
            if fm.ok:
                cr.accepted, cr.verdict = full_data_verdict(sigma, cur.rms, fm.rms, cr.bic_change, dk)
                if cr.accepted:
                    cr.accepted, cr.verdict = acts_as_itself(self.trace, cur.spec, fm, sigma, eff, cr.verdict)
            else:
                cr.accepted, cr.verdict = False, f"the fit failed: {fm.message}"
            self.say(f"  + {eff}: RMS error {fm.rms / sigma:.2f} x noise with {dk} more parameter"
                     f"{'s' if dk != 1 else ''} ({fm.seconds:.1f} s)")
            results.append(cr)
        return results

    def table_candidate(self, cr: CandidateResult) -> CandidateResult:
        """The damping candidate again with its second law, the table of c(x), judged on the whole record."""
        cur, sigma, poly = self.cur, self.sigma, cr.fit
        tf = self.fit(self.trace, poly.spec, poly.effects, _damping_table_starts(self.trace, poly, self.sc), self.sc,
                      extra=DAMPING_TABLE, held=_replaced(DAMPING_TABLE))
        dk = tf.n_free - cur.n_free
        ct = CandidateResult(effect=cr.effect, model=tf.model, shape=tf.shape, added_parameters=dk, rms=tf.rms,
                             heldout_rms=float("nan"), bic_change=bic_change(cur, tf, self.n), signature=cr.signature,
                             signature_text=cr.signature_text, fit=tf)
        if tf.ok:
            ct.accepted, ct.verdict = full_data_verdict(sigma, cur.rms, tf.rms, ct.bic_change, dk)
        else:
            ct.accepted, ct.verdict = False, f"the fit failed: {tf.message}"
        self.say(f"  + {cr.effect} (table of c(x)): RMS error {tf.rms / sigma:.2f} x noise with {dk} more "
                 f"parameters ({tf.seconds:.1f} s)")
        return ct

    def part_fit(self, c: CandidateResult, own_thread: bool = False) -> ModelFit:
        """The first part of the record, fitted from the whole record's optimum (as the current
        model's part fit is: both sides start alike, and each converges to its own optimum), with
        the work cap the candidate's fit had."""
        return self.fit(self.part, c.fit.spec, c.fit.effects, [c.fit.params], self.sc_part, extra=c.fit.shape,
                        held=_replaced(c.fit.shape), own_thread=own_thread)

    def candidate_cap_factor(self) -> float:
        """The work cap of a step's candidates and of their held-out fits, as a multiple of the
        search's: that of a fit extending the current model, but the start model's own."""
        return 1.0 if self.cur is self.fits[0] else self.extension_cap_factor(self.cur)

    def heldout_tests(self, passing: list) -> None:
        """The held-out test, best first, for up to ``heldout_candidates`` of the candidates that pass
        on the whole record (more while none of those passes it); the rest are not tested."""
        ahead = passing[:self.heldout_candidates]
        for c, pf in zip(ahead, _side_by_side(self.part_fit, ahead)):   # needed in any case: side by side
            c.part_fit = pf
        tested = 0
        for c in passing:
            if tested >= self.heldout_candidates and any(x.accepted for x in passing[:tested]):
                break
            tested += 1
            self.heldout_test(c)
        for c in passing[tested:]:
            c.accepted = False
            c.outranked_by = "a better candidate"    # named in step() once the winner is known
            c.verdict += "; not tested on the held-out part (a better candidate was)"

    def heldout_test(self, c: CandidateResult, label: str = "") -> None:
        """The candidate's prediction of the held-out part by its fit to the first part, judged."""
        if c.part_fit is None:
            c.part_fit = self.part_fit(c)
        pf, sigma = c.part_fit, self.sigma
        c.heldout_rms = _heldout(self.trace, c.fit.spec, pf.params, self.held_out) if pf.ok else float("inf")
        self.say(f"  {c.effect}{label}: held-out RMS error {c.heldout_rms / sigma:.2f} x noise (was "
                 f"{self.cur_held / sigma:.2f})")
        unasked = c.effect == "slack" and slack_heldout_unasked(
            c.added_parameters, bool(regimes(self.trace, c.fit)["slack"][self.held_out].any()))
        if unasked:
            c.verdict += f"; {unasked}"
            return
        ok, why = heldout_verdict(sigma, self.cur_held, c.heldout_rms, self.cur.rms, c.rms)
        c.accepted = ok
        c.verdict = f"{c.verdict}; {why}"

    def stop_without_winner(self, results: list) -> None:
        """No candidate earned its place: the search stops; a slack candidate's refit that never goes
        slack and fits lower is kept as the current model, better fitted."""
        cur, sigma = self.cur, self.sigma
        tied = [c.effect for c in results if c.tied_with]
        self.stop = tie_stop_reason(tied) if tied else "no candidate earns its parameters"
        self.no_winner = True
        refit = _refit_without_slack(self.trace, cur, results, sigma)
        for c in results:
            c.forget_curves()
        if refit is None:
            return
        # the same model, better fitted: the last stages start from it
        self.say(f"kept the refit of the slack candidate, which never goes slack: the same model "
                 f"{cur.model}, RMS error {cur.rms / sigma:.2f} -> {refit.rms / sigma:.2f} x noise")
        self.stop += (f"; the slack candidate never went slack, and its fit, the same model with other "
                      f"values, is kept: RMS error {cur.rms / sigma:.2f} -> {refit.rms / sigma:.2f} x noise")
        self.adopt_model(refit, self.heldout_of(refit))

    def add(self, win: CandidateResult, results: list, step: Step, windows: list) -> None:
        """The winner's effect added, with its evidence; the other candidates' curves dropped."""
        step.effect = win.effect
        if win.effect == "slack":
            win.signature_text = _slack_seen_by(self.trace, win)
        step.evidence = _evidence(win, windows)
        step.rms_after = win.rms
        step.model_after = win.label
        self.say(f"added {win.effect}: RMS error {self.cur.rms / self.sigma:.2f} -> {win.rms / self.sigma:.2f} x noise")
        self.cur, self.cur_held = win.fit, win.heldout_rms
        if self.cur.shape:                           # a law with its shape terms (the table of c(x))
            self.free_shapes(self.cur.shape)
        self.fits.append(self.cur)
        for c in results:                            # fitted curves of the winner only
            if c is not win:
                c.forget_curves()

    def retest_named(self, *added: str) -> None:
        """Does an effect added earlier still earn its parameters next to the ones just ``added`` (the
        step's winner, or a pair's two effects), by the whole record's rule? The first that does not
        is removed."""
        self.retest([x for x in self.cur.effects if x not in self.base_effects and x not in added], " and ".join(added))
        self.retested_at = len(self.refinements)

    def retest(self, effects: Sequence[str], beside: str, record_beside: str | None = None) -> bool:
        """Each of ``effects`` tested again beside the current model (refitted without it, judged by
        judge.retest_verdict); the first that no longer earns its parameters is removed. True where
        one was."""
        cur, sigma = self.cur, self.sigma
        for e in effects:
            red = _without(cur.spec, e).for_experiment(self.trace.experiment)
            rf = self.fit(self.trace, red, tuple(x for x in cur.effects if x != e), _reduced_starts(cur, red, self.sc),
                          self.sc, **kept_shape(cur, red))
            if not rf.ok:
                continue
            bic = bic_change(rf, cur, self.n)
            keep, why = retest_verdict(sigma, rf.rms, cur.rms, bic, cur.n_free - rf.n_free)
            self.steps[-1].retests.append(Retest(e, bic, keep, why, record_beside))
            if keep:
                continue
            self.say(f"removed {e}: without it the RMS error is {rf.rms / sigma:.2f} x noise ({why})")
            self.removals.append(Removal(e, cur.model, rf.model, cur.rms, rf.rms,
                                         f"next to {beside} it no longer earns its parameters: {why}"))
            self.adopt_model(rf, self.heldout_of(rf))
            return True
        return False

    def retest_after_refinements(self) -> None:
        """Every named effect tested again where a last stage changed a law after the last step's
        re-tests (a shape refined, an Iwan bank restarted or made finer, a rival or wider law put in
        its place): an effect named to make up for a law's wrong shape need not earn its place once
        the shape is right (the generator's Iwan friction with slack: a cubic named beside a bank on
        its grid of slip strains, whose strains were freed and idle elements restarted after it).
        Not tested: an effect whose own law alone changed (judge.retested_beside_refinements).
        Removed one at a time, the rest tested again after each removal."""
        changed = self.laws_changed()
        beside = "the refined laws (" + ", ".join(sorted(changed)) + ")"
        while changed and not self.budget_hit and self.retest(
                retested_beside_refinements(self.cur.effects, self.base_effects, changed),
                beside, beside):
            pass

    def laws_changed(self) -> set:
        """The effects whose law a kept refinement changed after the last step's re-tests."""
        return {r.effect for r in self.refinements[self.retested_at:] if r.accepted}

    # ---- the last stages: the laws' reseeding moves, the rival law, the wider laws, the whole record
    def adopt(self, result, where: str) -> bool:
        """A last stage's (model, held-out error, record or list of records): kept on record, and the
        model taken unless the time budget ran out during the stage."""
        new, held, recs = result
        recs = [r for r in (recs if isinstance(recs, list) else [recs]) if r is not None]
        if self.budget_hit and any(r.accepted for r in recs):
            _not_kept_for_budget(recs)
            new = self.cur
            self.stop += "; " + self.out_of_budget(where)
        self.refinements.extend(recs)
        if new is self.cur:
            return False
        self.adopt_model(new, held)
        return True

    def reshape(self, skip, cap_factor: float | None = None, where: str | None = None) -> float | None:
        """The shape groups of refine_shapes from the current model, the effects in ``skip`` left out;
        the result taken unless the time budget ran out during the stage (then, with ``where``, the
        stop reason says so). The fits' work cap: ``cap_factor`` of the search's, by default a step
        candidate's (candidate_cap_factor). Returns the refined model's held-out error (NaN where
        refine_shapes did not ask for it) where one was taken, else None."""
        if cap_factor is None:
            cap_factor = self.candidate_cap_factor()
        refined, refined_held, refs = refine_shapes(
            self.trace, self.part, self.held_out, self.cur, self.cur_held, self.sigma,
            lambda tr, sp, eff, starts, extra, own_thread=False: self.shape_fit(tr, sp, eff, starts, extra, own_thread,
                                                                                cap_factor),
            self.sc, self.say, skip=skip)
        self.refinements.extend(refs)
        if self.budget_hit:
            _not_kept_for_budget(refs)
            if where:
                self.stop += "; " + self.out_of_budget(where)
            return None
        if refined is self.cur:
            return None
        self.fits.append(refined)
        self.cur = refined
        if math.isfinite(refined_held):
            self.cur_held = refined_held
        return refined_held

    def reseeded_laws(self) -> list:
        """(effect, Law) of the named laws that have reseeding moves (Law.reseed)."""
        laws = [(e, EFFECT[e].law(_law_of(self.cur.spec, e))) for e in self.cur.effects if e in LAW_FIELD]
        return [(e, law) for e, law in laws if law is not None and law.reseed]

    def reseedable(self) -> bool:
        """A named law has reseeding moves, the model misses the record by CRITERIA.iwan_stages_gap or
        more, and the budget is not spent."""
        return (not self.budget_hit and bool(self.reseeded_laws())
                and _gap(self.cur.rms, self.sigma) >= CRITERIA.iwan_stages_gap * self.sigma)

    def reseed(self) -> None:
        """Each named law's reseeding moves in turn (for the Iwan bank: its idle elements restarted,
        then a finer bank), each kept on the judge's terms. Where one is kept and the model still
        misses the record by CRITERIA.iwan_stages_gap or more, the other laws' shape groups are tried
        again beside the reseeded law, its terms free (docs/discovery.md, "The search")."""
        for effect, law in self.reseeded_laws():
            kept = False
            for move, what in law.reseed:
                if not self.budget_hit:
                    kept |= self.adopt(self.reseed_move(move, self.cur, self.cur_held), f"while {what}")
            if not kept or self.budget_hit or _gap(self.cur.rms, self.sigma) < CRITERIA.iwan_stages_gap * self.sigma:
                continue
            self.free_shapes(tuple(self.cur.shape))
            self.reshape(self.refined_effects() | {effect}, rival.reseeded_cap_factor(self.cur))

    def reseed_move(self, move: str, m: ModelFit, held: float):
        """One reseeding move of the registry (a function of rival.py) on ``m``: (model, held-out
        error, Refinement or None)."""
        mf = self.model_cap_factor(m)
        return getattr(rival, move)(
            self.trace, self.part, self.held_out, m, held, self.sigma,
            lambda tr, sp, eff, starts, extra=(), cap_factor=1.0, **kw:
            self.shape_fit(tr, sp, eff, starts, extra, cap_factor=cap_factor * mf, **kw), self.say)

    def reseeded(self, m: ModelFit, held: float) -> tuple[ModelFit, float]:
        """``m`` after its hysteresis law's reseeding moves (Law.reseed), each kept where it is
        judged better, as the reseed stage does; for the rival law's verdict (rival_law)."""
        law = EFFECT["hysteresis"].law(m.spec.hysteresis)
        for move, _ in (law.reseed if law else ()):
            if not self.budget_hit:
                m, held, _ = self.reseed_move(move, m, held)
        return m, held

    def has_rival(self) -> bool:
        """The hysteresis step fitted the rival law (its fits kept for rival_law)."""
        return "hysteresis" in self.rivals

    def swap_rival(self) -> None:
        """The hysteresis law fitted again with its rival in its place (rival_law), and the new law's
        own shape terms (the Iwan bank's slip strains, Bouc-Wen's exponent) where it is kept. Its
        fits' work caps are a step candidate's (candidate_cap_factor), times rival_law's."""
        added = [s.effect for s in self.steps if s.effect and s.effect in self.cur.effects]
        law = self.cur.spec.hysteresis
        shaped = any(k in HYSTERESIS_PARAMETERS.get(law, ()) for k in self.shape_free)
        base = self.candidate_cap_factor()
        self.rival_kept = self.adopt(rival.rival_law(
            self.trace, self.part, self.held_out, self.cur, self.cur_held, self.sigma,
            lambda tr, sp, eff, starts, baseline_rms=None, cap_factor=1.0, extra=(): self.fit(
                tr, sp, eff, starts, self.sc_part if tr is self.part else self.sc, extra, baseline_rms=baseline_rms,
                cap_factor=base * cap_factor),
            self.rivals["hysteresis"], added, self.say,
            elastic_reshaped=any(r.accepted and r.effect == "nonlinear_stiffness" for r in self.refinements),
            incumbent_shaped=shaped, reseed=self.reseeded, sc=self.sc),
            "while the rival law was fitted")
        if self.rival_kept:
            self.reshape(set(self.cur.effects) - {"hysteresis"})

    def swap_other_rival_laws(self) -> None:
        """The other named effects fitted again with their laws' rivals in place (other_rival_laws),
        where the model still misses the record."""
        self.swap_laws(rival.other_rival_laws, "while a rival law was fitted", self.rivals, self.say, sc=self.sc)

    def swap_wider_laws(self) -> None:
        """The elastic law and creep fitted again with their wider laws in their place (wider_law),
        where the model still misses the record."""
        self.swap_laws(rival.wider_law, "while a wider law was fitted", self.say, sc=self.sc)

    def swap_laws(self, stage: Callable, where: str, *args, **options) -> None:
        """A last stage that puts other laws in place (rival.py's ``stage``), its fits with a step
        candidate's work caps (``extra``: shape terms free, those they replace held), its result
        adopted (``where``: for the stop reason)."""
        base = self.candidate_cap_factor()
        self.adopt(stage(
            self.trace, self.part, self.held_out, self.cur, self.cur_held, self.sigma,
            lambda tr, sp, eff, starts, baseline_rms=None, extra=(): self.fit(
                tr, sp, eff, starts, self.sc_part if tr is self.part else self.sc, extra, held=_replaced(extra),
                baseline_rms=baseline_rms, cap_factor=base),
            *args, **options), where)

    def final_fit(self) -> None:
        """The final model fitted once more from the searched optimum (WHOLE_RECORD_ITERATIONS), with
        central differences, which reach the least-squares point and its intervals where the
        search's forward differences stop short along a weakly determined direction (a mass against
        a stiffness); on the whole record where the search used every k-th sample, every error then
        carried to the whole record."""
        from ..identify_native import POLISH_CENTRAL
        cur, fitted = self.cur, None
        if not self.budget_hit:
            self.say(f"fitting {cur.label} to the whole record" if self.every > 1 else f"polishing the fit of {cur.label}")
            fitted = fit_model(self.whole, cur.spec, cur.effects, [cur.params], _scales(self.whole),
                               work_cap=self.every * self.cap, extra=cur.shape,
                               held=self.shape_held + _replaced(cur.shape), deadline=self.deadline,
                               max_iterations=WHOLE_RECORD_ITERATIONS, nuisance=self.nuisance,
                               central_differences=POLISH_CENTRAL, rtol=MODEL_RTOL)
            if not fitted.ok:
                self.stop += (f"; the final fit failed ({fitted.message}): the searched values are kept")
                fitted = None
        self.fits = _on_whole_record(self.whole, self.fits, self.steps, self.removals, fitted)
        self.say(f"{self.fits[-1].model} on the whole record: RMS error {self.fits[-1].rms / self.sigma:.2f} x noise")


def _simulation_work(trace: Trace, spec, params: dict) -> int:
    """The work of one simulation of ``spec`` at ``params`` over ``trace``, in evaluations of the
    model's equations (the unit of the search's work caps: the same on a busy machine as on an idle one)."""
    from .. import identify_native as idn

    before = idn.simulation_work()
    predict(trace, spec, params)
    return idn.simulation_work() - before


def _on_whole_record(whole: Trace, fits: list, steps: list, removals: list, fitted: ModelFit | None) -> list:
    """A search on a thinned record carried to the whole record: each model in turn with its values
    of the search, its prediction and RMS error now those of the whole record, the errors of the
    steps and removals with them; the last model is ``fitted`` (its final fit, from the search's
    values) where there is one and it is no worse: tether.fit's staging (the elastic law and the
    nuisance parameters first, the rest held) can lead a fit that starts at an optimum elsewhere."""
    carried = {}
    for m in fits:
        if id(m) not in carried:
            pred = predict(whole, m.spec, m.params)
            carried[id(m)] = replace(m, predicted=pred, rms=float(np.sqrt(np.mean((pred - whole.measured) ** 2))))
    # every error a step or removal records is that of one of the models in turn
    rms_of = {m.rms: carried[id(m)].rms for m in fits}
    for st in steps:
        st.rms_before = rms_of[st.rms_before]
        if st.rms_after is not None:
            st.rms_after = rms_of[st.rms_after]
    for r in removals:
        r.rms_before, r.rms_after = rms_of[r.rms_before], rms_of[r.rms_after]
    out = [carried[id(m)] for m in fits]
    if fitted is not None and fitted.rms <= out[-1].rms:
        out[-1] = fitted
    return out
