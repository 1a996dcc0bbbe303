"""Fits of one model to one record, through tether.fit (the project's fitting layer): the start
cleaned, the work caps and the budget's deadline passed to the engine, several starts side by side."""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from .. import nuisance as NZ
from ..identify_native import FORWARD
from ..models import IWAN_EPS, IWAN_K, ModelSpec, parse_model
from ..traces import Trace
from .laws import _floor, _POSITIVE, free_parameters, HELD_AT_START, keeps_model_tolerance
from .scales import _Scales


def model_label(model: str, shape: Sequence[str]) -> str:
    """A model as OUT.json and the progress lines name it: with the shape terms freed beyond its law's."""
    return f"{model} (shape: {' '.join(shape)})" if shape else model


@dataclass
class ModelFit:
    """One model fitted to one record."""

    spec: ModelSpec
    effects: tuple                 # the discovery's effect names in this model, in the order added
    params: dict                   # every parameter of the model (fitted and fixed), --params form
    free: list
    rms: float
    predicted: np.ndarray = field(repr=False)
    evaluations: int = 0
    seconds: float = 0.0
    ok: bool = True
    message: str = ""
    std_error: dict = field(default_factory=dict)
    unidentifiable: list = field(default_factory=list)
    best_start: int = 0
    shape: tuple = ()              # shape terms freed beyond free_parameters (refine_shapes)
    intervals: dict = field(default_factory=dict)   # name -> (low, high), 95 %, of every free parameter

    @property
    def nuisance(self) -> dict:
        """The nuisance parameters this fit freed (discover.nuisance.nuisance_parameters), name ->
        fitted value; they are in ``params`` too, so every later fit starts from them."""
        return {k: float(v) for k, v in self.params.items() if k in NZ.NUISANCE}

    @property
    def law_params(self) -> dict:
        """``params`` without the nuisance parameters: the model's own (a --params file's)."""
        return {k: v for k, v in self.params.items() if k not in NZ.NUISANCE}

    @property
    def model(self) -> str:
        return self.spec.canonical

    @property
    def label(self) -> str:
        return model_label(self.model, self.shape)

    @property
    def n_free(self) -> int:
        return len(self.free)


def _clean_start(names: Sequence[str], start: dict, sc: _Scales) -> dict:
    """The start values of the free parameters ``names`` the engine accepts; a value it cannot start
    from is left to tether.fit's data-based estimate (a positive parameter at or below zero, and
    with an Iwan element's stiffness its slip strain of zero: valid only beside a stiffness of 0,
    which a log-scaled start cannot be; a fit that switched an element off hands back both at 0)."""
    out = {}
    for n in names:
        if n not in start:
            continue
        v = float(start[n])
        if not math.isfinite(v):
            continue
        fl = _floor(n, sc)
        if fl and abs(v) < fl:
            v = math.copysign(fl, v if v != 0 else 1.0)
        if n in _POSITIVE and not v > 0:
            continue                              # fit's data-based estimate instead
        if n == "kaw_LT":
            v = min(max(v, 0.06), 1.94)
        if n == "kaw_RT":
            v = min(max(v, 0.02), 1.0)
        if n == "kaw_residual":
            v = min(max(v, 0.0), 0.9)
        out[n] = v
    for k, e in zip(IWAN_K, IWAN_EPS):
        if k in names and k not in out and not out.get(e, 1.0) > 0:
            out.pop(e, None)
    return out


def predict(trace: Trace, spec: ModelSpec | str, params: dict) -> np.ndarray:
    """The model's prediction of the measured column on the trace's grid, driven exactly as
    tether.fit drives its fits (and tether.run the FMU)."""
    from ..fit.experiments import predict as predict_trace, trace_experiment

    spec = (parse_model(spec) if isinstance(spec, str) else spec).for_experiment(trace.experiment)
    from ..nuisance import NUISANCE

    x = trace_experiment(trace, spec, {})
    return predict_trace(x, {k: float(v) for k, v in params.items() if k in spec.parameters or k in NUISANCE})


#: the default bound of one discovery run [s]
DEFAULT_BUDGET = 900.0


#: the message of a fit stopped by the discovery's time budget
OUT_OF_BUDGET = "stopped: the discovery's time budget is spent"


def _held_nuisance(start: dict | None, names: Sequence[str]) -> dict:
    """The nuisance values ``start`` carries that a fit of ``names`` does not free: it holds them
    there (a held-out part fit, Search.fit), and its parameters keep them."""
    return {k: float(start[k]) for k in NZ.NUISANCE if start and k in start and k not in names}


def _fit_once(trace, spec, names, start, sc, work_cap: float | None = None, deadline: float | None = None,
              own_thread: bool = False, **options):
    """One fit through tether.fit.fit_traces; on a failure of its staging (a log-scaled parameter
    driven to 0 by the first stage) one direct engine fit of all free parameters instead. A fit
    whose simulations make more than ``work_cap`` evaluations of the model's equations (a start that
    wandered where the equations turn stiff and every simulation crawls; counted in work, not CPU
    time, so that the same fit stops at the same point however busy the machine is), or that runs
    past the discovery's ``deadline`` (a time.perf_counter() value, wall time: the user's budget), is
    abandoned: the engine checks both inside its simulations, so neither is overrun by more than a
    few samples' work. own_thread: the fit runs beside others, on this thread alone (n_threads 1)."""
    from .. import identify_native as idn
    from ..fit import fit_traces

    st = None if start is None else _clean_start(names, start, sc)
    held = {k: float(start[k]) for k in HELD_AT_START if start and k in start and k not in names
            and k in spec.parameters}
    held.update(_held_nuisance(start, names))
    options = {**ENGINE_OPTIONS, **options}
    options.setdefault("rtol", search_rtol(trace, spec))
    if deadline is not None and time.perf_counter() >= deadline:
        return None, OUT_OF_BUDGET
    if own_thread:
        options["n_threads"] = 1
    options.update(idn.deadlines(wall_seconds=None if deadline is None else deadline - time.perf_counter()))
    if work_cap is not None:
        options["max_rhs_evaluations"] = float(work_cap)

    def stopped(exc: idn.DeadlinePassed) -> str:
        return OUT_OF_BUDGET if exc.clock == "wall" else f"abandoned at its work cap ({work_cap:.3g} evaluations)"

    iterations = int(options.pop("max_iterations", 100))
    while True:
        try:
            return fit_traces([trace], spec, free=names, start=st, fixed=held or None,
                              max_iterations=iterations, **options), ""
        except idn.DeadlinePassed as exc:
            return None, stopped(exc)
        except (RuntimeError, ValueError) as exc:
            msg = " ".join(str(exc).split())
        # the engine drops a whole fit when a Jacobian column fails to simulate late in it (the
        # iterate wandered where the solver gives up): stop earlier, keeping the progress made
        if "failed to simulate" in msg and "start fails" not in msg and iterations > 2:
            iterations = max(2, iterations // 3)
            continue
        break
    if "log scaling" not in msg:
        return None, msg
    try:
        return _fit_direct(trace, spec, names, st, held, **options), ""
    except idn.DeadlinePassed as exc:
        return None, stopped(exc)
    except (RuntimeError, ValueError) as exc:
        return None, " ".join(str(exc).split())


@dataclass
class _DirectResult:
    """The parts of tether.fit.FitResult that discovery reads."""

    parameters: dict
    free: list
    values: dict
    std_error: dict
    unidentifiable: list
    rms: float
    predictions: list
    evaluations: int
    message: str
    ci95: dict = field(default_factory=dict)
    status: int = 1


#: CVODE's relative tolerance in the search's fits of a forced record (the FMU parameter rtol): there
#: the integrator's steps follow the tolerance, and at 1e-6 against the model's own 1e-8 a simulation
#: costs a half to a quarter and stays within a few thousandths of the noise
#: (bench/bench_integration_tolerance.py, docs/speed.md 2026-12-06). The final fit keeps the model's
#: own (MODEL_RTOL): the error reported of the final model is the one its --params rerun gets
SEARCH_RTOL = 1e-6
#: the engine's rtol option that keeps the model's own tolerance
MODEL_RTOL = 0.0


def search_rtol(trace: Trace, spec: ModelSpec) -> float:
    """The integration tolerance of a search's fit of ``spec`` to ``trace``: SEARCH_RTOL where a
    simulation's work follows the tolerance (the payload rig driven by an input), else the model's
    own: a free vibration is sampled between solver calls and the load rig is quasi-static (an
    evaluation every few to every twenty samples at either tolerance: nothing to gain, and the
    Jacobian's columns still move), and a law that keeps it (Law.model_tolerance) keeps it."""
    integration_bound = trace.input_column is not None and spec.for_experiment(trace.experiment).rig == "payload"
    return SEARCH_RTOL if integration_bound and not keeps_model_tolerance(spec) else MODEL_RTOL


#: engine options for every discovery fit (e.g. n_threads): the search compares candidates with
#: forward differences; its final fit polishes the optimum with central ones (Search.final_fit)
ENGINE_OPTIONS: dict = {"central_differences": FORWARD}


#: independent fits run this many side by side, each on one thread: the candidates of a step, or
#: (one candidate alone) the short fits from several starts. The engine's parallel Jacobian keeps
#: a second core only ~30 % busy (its trial steps are serial). The results are the same bit for
#: bit, and each fit's work cap counts its own simulations
PARALLEL_FITS = 2


def fit_cost(spec, experiment: str) -> int:
    """What _side_by_side orders fits by: the model's free parameters (each a Jacobian column, and the
    laws with most of them, the Iwan bank, simulate slowest)."""
    return len(free_parameters(spec, experiment))


def _side_by_side(fit_one: Callable, items: Sequence, nested: bool = False,
                  cost: Callable | None = None) -> list:
    """[fit_one(item, own_thread) for item in items], up to PARALLEL_FITS at a time, each on its own
    thread (own_thread True); one after the other (own_thread False) when there is one item or
    PARALLEL_FITS is 1. nested: the caller already runs beside others: one after the other, each
    still on its own thread alone (own_thread True). ``cost``: an estimate of each item's work; the
    costliest start first (a long fit started last would run alone at the end), the results still
    in the order of ``items``."""
    items = list(items)
    side = 1 if nested else min(PARALLEL_FITS, len(items))
    if side <= 1:
        return [fit_one(x, nested) for x in items]
    order = sorted(range(len(items)), key=lambda i: -cost(items[i])) if cost else list(range(len(items)))
    with ThreadPoolExecutor(side) as pool:
        done = list(pool.map(lambda i: fit_one(items[i], True), order))
    out = [None] * len(items)
    for i, r in zip(order, done):
        out[i] = r
    return out


def _fit_direct(trace, spec, names, start, held=None, **options):
    from .. import identify_native as idn
    from ..fit.experiments import predict as predict_trace, trace_experiment
    from ..fit.parameters import bounds_and_start, fmu_bounds, fmu_defaults
    from ..fit.start import initial_estimate

    spec = spec.for_experiment(trace.experiment)
    est = initial_estimate([trace], spec)
    defaults = fmu_defaults()
    bounds = fmu_bounds()
    values = {n: float(defaults[n]) for n in spec.parameters if n in defaults}
    values.update(held or {})
    free, scaling = {}, {}
    for n in names:
        if n in NZ.NUISANCE:
            lo, hi, s, how = NZ.nuisance_box(trace, n)
            s = float((start or {}).get(n, s))
            free[n], scaling[n] = (lo, hi, s), how
            continue
        s = float((start or {}).get(n, est.get(n, defaults[n])))
        lo, hi, s, how = bounds_and_start(n, s, bounds, {k: v for k, v in est.items() if k.startswith("_")})
        if how == "log" and not s > 0:
            s = max(abs(float(defaults[n])), 1e-6)
        free[n], scaling[n] = (lo, hi, s), how
    held = {n: v for n, v in values.items() if n not in names}
    x = trace_experiment(trace, spec, held)
    x.exp.weight = math.sqrt(x.periods)
    opts = dict(options)
    if trace.experiment == "free_vibration":
        opts.setdefault("horizon_stages", 3)
    r = idn.fit([x.exp], free, scaling=scaling, **opts)
    values.update(r.as_dict())
    values.update({k: float(v) for k, v in (held or {}).items() if k in NZ.NUISANCE})
    pred = predict_trace(x, values)
    rms = float(np.sqrt(np.mean((pred - np.asarray(trace.measured, float)) ** 2)))
    return _DirectResult(parameters={k: v for k, v in values.items() if k not in NZ.NUISANCE}, free=list(names),
                         values=r.as_dict(), std_error=dict(zip(r.names, map(float, r.std_error))),
                         unidentifiable=list(r.unidentifiable), rms=rms, predictions=[pred], evaluations=r.evaluations,
                         message=r.message, ci95={n: (float(a), float(b)) for n, a, b in
                                                   zip(r.names, r.ci_low, r.ci_high)}, status=int(r.status))


#: every fit of a discovery is capped at this many simulations of the start model (times the stage's
#: factors, and work_ratio where the model fitted simulates slower), counted in work: evaluations of
#: the equations, the same on a busy machine as on an idle one (docs/discovery.md, "Work caps")
CAP_SIMULATIONS = 2400.0


def work_ratio(own: float, current: float) -> float:
    """How many simulations of the current model one simulation of the model being fitted is worth,
    at least 1: a fit's cap, counted in simulations of the current model, is stretched by it, so
    that a candidate that simulates slower (an Iwan bank makes several times the evaluations of the
    linear model it extends) gets as many of its own simulations as the current model would."""
    return max(1.0, float(own) / max(float(current), 1.0))


#: the second search (from the refined model) caps its fits at this share of the first's: it starts
#: within a few sigma of the record, where a candidate that earns its place converges in a few
#: iterations, and the fits that run to the cap there crawl to nothing (a free vibration with
#: hysteresis and slack spent 10 s of its 60 s so, on two candidates that failed)
SECOND_SEARCH_CAP_SHARE = 0.5


#: a quick fit (quick_iterations from one of several starts) is abandoned at this share of the
#: work cap: twelve iterations that need half the cap crawl through equations turned stiff
QUICK_CAP_SHARE = 0.5


def fit_model(trace: Trace, spec: ModelSpec, effects: Sequence[str], starts: Sequence[dict | None], sc: _Scales,
              quick_iterations: int = 12, work_cap: float | None = None, extra: Sequence[str] = (),
              held: Sequence[str] = (), own_thread: bool = False, baseline_rms: float | None = None,
              nuisance: Sequence[str] = (), **options) -> ModelFit:
    """Fit ``spec`` from each start (a few iterations each when there are several; None = tether.fit's
    data-based estimate), then carry the best to convergence (where the best converged within those
    iterations, the best start still descending races it instead: _carried_on). ``best_start`` of
    the result is the index of the start that won. ``extra`` frees shape terms beyond free_parameters; ``held`` keeps
    terms at their start values. own_thread: this model is fitted beside others, every fit on the
    calling thread alone (see _fit_once). baseline_rms: the error of the model this one extends;
    where no quick fit gets 0.1 % below it, the best of them is returned as it is (a candidate with
    nothing to gain; carrying it to convergence cost 15-40 s a time on a 10 s record and always
    ended where the quick fits had). nuisance: the nuisance parameters freed beside the model's
    (discover.nuisance.nuisance_parameters); their fitted values join ``params``."""
    from .judge import CRITERIA      # (the judge reads fits: imported when a fit runs)

    t0 = time.perf_counter()
    spec = spec.for_experiment(trace.experiment)
    names = free_parameters(spec, trace.experiment)
    names += [e for e in extra if e not in names]
    names += [e for e in nuisance if e not in names and NZ.law_refusal(e, spec) is None]
    names = [e for e in names if e not in held]
    evaluations = 0
    best, best_i, msg = None, -1, ""
    if len(starts) > 1:
        quick_cap = None if work_cap is None else QUICK_CAP_SHARE * work_cap
        quick_fits = _side_by_side(
            lambda s, alone: _fit_once(trace, spec, names, s, sc, work_cap=quick_cap, max_iterations=quick_iterations,
                                       own_thread=alone, **options), starts, nested=own_thread)
        for i, (r, m) in enumerate(quick_fits):
            if r is None:
                msg = m
                continue
            evaluations += r.evaluations
            if best is None or r.rms < best.rms:
                best, best_i = r, i
        if best is not None:
            def fit_from(s, cap, iterations=None):
                more = {} if iterations is None else {"max_iterations": iterations}
                return _fit_once(trace, spec, names, s, sc, work_cap=cap, own_thread=own_thread, **more, **options)

            def gains(rms):
                return baseline_rms is None or rms < (1.0 - CRITERIA.least_gain) * baseline_rms

            best, best_i, more = _carried_on(fit_from, starts, quick_fits, best, best_i, gains, quick_iterations,
                                             work_cap)
            evaluations += more
    else:
        best, msg = _fit_once(trace, spec, names, starts[0], sc, work_cap=None if work_cap is None else 2 * work_cap,
                              own_thread=own_thread, **options)
        best_i = 0
        evaluations += best.evaluations if best is not None else 0
    if best is None or not math.isfinite(best.rms):
        return ModelFit(spec=spec, effects=tuple(effects), params={}, free=names, rms=float("inf"),
                        predicted=np.full(len(trace.time), np.nan), evaluations=evaluations,
                        seconds=time.perf_counter() - t0, ok=False, message=msg or "fit failed")
    params = dict(best.parameters)
    params.update(_held_nuisance(starts[best_i], names))
    params.update({n: float(best.values[n]) for n in best.free if n in NZ.NUISANCE})
    params = {k: v for k, v in params.items() if NZ.law_refusal(k, spec) is None}
    return ModelFit(spec=spec, effects=tuple(effects), params=params, free=list(best.free),
                    rms=float(best.rms), predicted=np.asarray(best.predictions[0]), evaluations=evaluations,
                    seconds=time.perf_counter() - t0, message=best.message, std_error=dict(best.std_error),
                    unidentifiable=list(best.unidentifiable), best_start=best_i, shape=tuple(extra),
                    intervals={k: (float(a), float(b)) for k, (a, b) in best.ci95.items()})


def _carried_on(fit_from: Callable, starts: Sequence, quick_fits: Sequence, best, best_i: int, gains: Callable,
                quick_iterations: int, work_cap: float | None):
    """After fit_model's quick round (``quick_fits``, won by ``best`` from start ``best_i``; ``gains(rms)``:
    an error that gains on the model this one extends): (best, its start, the evaluations spent here).
    ``fit_from(start, work_cap, iterations=None)`` is one fit (_fit_once's result and message). A fit is
    carried to convergence only where it gains, as the quick round's winner is."""
    cap2 = None if work_cap is None else 2 * work_cap
    evaluations = 0
    descending = _best_still_descending(quick_fits, best_i)
    if descending is not None:
        # the winner converged within the quick iterations (carried on, it would end where it is,
        # gain or none): the best start still descending there races it for as many iterations
        # again (from its start: a fit continued from where it stopped restarts its staging and
        # step control, and settles early), and is carried to convergence where it then leads
        r, _ = fit_from(starts[descending], work_cap, 2 * quick_iterations)
        evaluations += r.evaluations if r is not None else 0
        if r is not None and r.rms < best.rms:
            best, best_i = r, descending
            if _stopped_at_limit(r) and gains(r.rms):
                r, _ = fit_from(starts[descending], cap2)
                if r is not None:
                    evaluations += r.evaluations
                    best = r if r.rms < best.rms else best
    elif gains(best.rms):
        # carried to convergence along its own path: the winner's start again, with the full
        # iteration budget (restarting from the quick fit's end resets the staging and the step
        # control, and can settle elsewhere: a creep fit went 1.18 -> 1.76 x noise that way); the
        # restart from the quick fit's end (its values over the start's, which hold the terms
        # the fit keeps fixed) only where the full run fails or is worse
        for s in (starts[best_i], {**(starts[best_i] or {}), **best.values}):
            r, _ = fit_from(s, cap2)
            if r is not None:
                evaluations += r.evaluations
                if r.rms <= best.rms:
                    best = r
                    break
    return best, best_i, evaluations


def _best_still_descending(quick_fits: Sequence, best_i: int) -> int | None:
    """Where the quick fits' winner (index ``best_i``) converged within its iterations, the index of
    the best quick fit that stopped at its iteration limit instead (still descending, its optimum not
    yet seen); None otherwise. ``quick_fits``: (result or None, message)."""
    winner = quick_fits[best_i][0]
    if winner.status != 0 or _stopped_at_limit(winner):
        return None
    going = [(r.rms, i) for i, (r, _) in enumerate(quick_fits)
             if r is not None and i != best_i and _stopped_at_limit(r) and math.isfinite(r.rms)]
    return min(going)[1] if going else None


def _stopped_at_limit(r) -> bool:
    """A fit that stopped at its iteration limit in any of its stages (engine status 1, which covers
    the engine's horizon stages): run longer, it walks on from there, in a later stage too, so where
    it ended is not the optimum it would reach. A fit converged in its last stage after an earlier
    one was cut ends elsewhere than the same fit run longer."""
    # (tether.fit's results log their stages; the direct engine fit's have none)
    return r.status == 1 or any(s["status"] == 1 for s in getattr(r, "stages", ()))


def _heldout(trace: Trace, spec: ModelSpec, params: dict, held_out: np.ndarray) -> float:
    """The RMS error of the model with ``params`` on the held-out samples of the record (``held_out``:
    True per sample, samples.heldout_split); inf where it does not simulate."""
    try:
        y = predict(trace, spec, params)
    except RuntimeError:
        return float("inf")
    r = (y - np.asarray(trace.measured, float))[held_out]
    v = float(np.sqrt(np.mean(r ** 2)))
    return v if math.isfinite(v) else float("inf")
