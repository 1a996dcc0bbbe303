"""A fit through the identification engine: the problem set up (free names, starts, boxes, scales,
weighted experiments, engine options), the stages run, and the result with its statistics."""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from .. import identify_native as idn
from .. import nuisance as NZ
from ..blas import in_one_blas_thread
from ..models import IWAN_EPS, ModelSpec
from ..traces import Trace, read_trace
from .experiments import TraceExperiment, fitted_count, predict, trace_experiment
from .memory import GRIDS, SCANNED_AFTER_LAW, scan_memory
from .parameters import (FIRST_STAGE, bounds_and_start, check_names, default_free_parameters, fmu_bounds,
                         fmu_defaults, model_spec)
from .result import FitError, FitProgress, FitResult
from .start import initial_estimate


@dataclass
class _Problem:
    """A fit set up: the free parameters' starts, boxes and scalings, every other value of the
    model, the weighted experiments and the engine's options."""

    free: list                      # names fitted, in order
    x0: dict                        # name -> start
    box: dict                       # name -> (low, high)
    scaling: dict                   # name -> "log" | "linear"
    model_values: dict              # every parameter of the model: fixed ones at their values
    fixed_nuisance: dict            # nuisance parameters given as fixed
    exps: list                      # TraceExperiment per trace
    n_eff: float                    # samples, weighted
    options: dict                   # the engine's options


@in_one_blas_thread
def fit_traces(traces: Sequence[Trace | str | Path], model, free: Sequence[str] | None = None,
               start: Mapping[str, float] | None = None, fixed: Mapping[str, float] | None = None,
               progress: Callable[[FitProgress], object] | None = None, n_starts: int = 1,
               mass_band: float | None = None, **engine_options) -> FitResult:
    """Fit ``model`` to ``traces`` jointly (one shared parameter set).

    ``free``, ``start`` and ``fixed`` may name the nuisance parameters m, x0, v0, offset_measured,
    offset_input, input_gain (tether.nuisance, docs/nuisance.md); a free one a trace cannot
    determine is refused (FitError naming the trace, the parameter and why). A free ``m`` stays in
    payload_mass_kg * (1 +- mass_band) (default: the trace's mass_uncertainty_rel, else 0.3).

    free: names to fit (default: :func:`default_free_parameters` for each trace's experiment,
    united). start: start values (default: :func:`initial_estimate`). fixed: values of parameters
    that are not fitted (default: the FMU's start values; the Iwan slip strains: the estimate's
    grid, iwan_slip_grid). progress: called with a
    :class:`FitProgress` at every stage and LM iteration. n_starts: starts of the last stage (the
    estimate, then random ones around it). engine_options: kt_fit_options fields (max_iterations,
    fd_step, stat_tol, ...). Raises FitError for bad names and RuntimeError if the engine fails.
    """
    t_begin = _time.perf_counter()
    spec = model_spec(model)
    traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
    if not traces:
        raise FitError("no traces to fit")
    start = dict(start or {})
    fixed = dict(fixed or {})
    problem = _problem(traces, spec, free, start, fixed, mass_band, engine_options)
    current, evaluations, stage_log, r = _run_stages(problem, n_starts, progress, t_begin)
    params, predictions, total = _predictions(problem, current)
    message = r.message
    # a fit never hands back more error than its start: the stages (the elastic law alone first; in
    # free vibration the record's first quarter, then half) can lead a start that is already at an
    # optimum of the whole record elsewhere (a discovery's final model refitted from its own
    # values: 7.47 -> 15.2 x noise). Then the start is the result.
    if all(n in start for n in problem.free):
        params0, predictions0, total0 = _predictions(problem, problem.x0)
        if math.isfinite(total0) and not total <= total0:
            message = (f"the fit ended with more error than its start (RMS {total0:.6g} -> {total:.6g}): the "
                       f"start is returned ({r.message})")
            current.update(problem.x0)
            params, predictions, total = params0, predictions0, total0
    per = [math.sqrt(_squares(p, x.trace) / fitted_count(x.trace)) for p, x in zip(predictions, problem.exps)]
    return FitResult(
        model=spec.canonical, parameters=params, rms=total, rms_per_trace=per, predictions=predictions,
        evaluations=evaluations, seconds=_time.perf_counter() - t_begin, message=message,
        traces=[str(x.trace.stem.name) for x in problem.exps], noise=[float(x.noise) for x in problem.exps],
        start=dict(problem.x0), stages=stage_log,
        **_statistics(problem, r, current, float(engine_options.get("max_rel_std", 0.5))))


def _problem(traces: list[Trace], spec: ModelSpec, free: Sequence[str] | None, start: dict, fixed: dict,
             mass_band: float | None, engine_options: Mapping) -> _Problem:
    """The fit set up, its names and values checked (FitError), the starts from the data."""
    free_names = _free_names(traces, spec, free, start, fixed)
    try:
        if mass_band is not None:
            mass_band = NZ.check_mass_band(mass_band, "mass_band")
        NZ.check_free(traces, free_names)
    except ValueError as e:
        raise FitError(str(e)) from None
    fixed_nuisance = {n: float(v) for n, v in fixed.items() if n in NZ.NUISANCE}
    for n, v in list(start.items()) + list(fixed.items()):
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(float(v)):
            raise FitError(f"parameter '{n}': value {v!r} is not a finite number")

    est = initial_estimate(traces, spec, fixed)
    scales = {k: v for k, v in est.items() if k.startswith("_")}
    if traces[0].payload_mass_kg:
        scales["_m"] = float(traces[0].payload_mass_kg)
    defaults = fmu_defaults()
    # every parameter of the model: fixed ones at `fixed` or the FMU's start value; the Iwan slip
    # strains at the grid the estimate chose (its element stiffnesses are fitted on that grid)
    grid = {n: est[n] for n in IWAN_EPS if n in est}
    model_values = {n: float(fixed.get(n, grid.get(n, defaults[n]))) for n in spec.parameters if n in defaults}
    x0, box, scaling = _starts_and_boxes(traces[0], free_names, start, est, scales, defaults, mass_band)
    held = {n: v for n, v in model_values.items() if n not in free_names}
    held.update(fixed_nuisance)
    exps, n_eff = _weighted_experiments(traces, spec, held)
    return _Problem(free_names, x0, box, scaling, model_values, fixed_nuisance, exps, n_eff,
                    _engine_options(engine_options, exps, scales))


def _free_names(traces: list[Trace], spec: ModelSpec, free: Sequence[str] | None, start: Mapping,
                fixed: Mapping) -> list[str]:
    """The names to fit: ``free`` checked, or those the traces' experiments determine (not fixed)."""
    check_names(fixed, spec, "fixed parameter")
    check_names(start, spec, "start value for")
    if free is None:
        free_names: list[str] = []
        for tr in traces:
            for n in default_free_parameters(spec, tr.experiment):
                if n not in free_names and n not in fixed:
                    free_names.append(n)
    else:
        free_names = check_names(free, spec, "free parameter")
        both = [n for n in free_names if n in fixed]
        if both:
            raise FitError(f"parameter '{both[0]}' is both free and fixed")
    if not free_names:
        raise FitError(f"nothing to fit: every parameter of '{spec.canonical}' is fixed")
    return free_names


def _starts_and_boxes(trace: Trace, free_names: list[str], start: Mapping, est: Mapping, scales: Mapping,
                      defaults: Mapping, mass_band: float | None) -> tuple[dict, dict, dict]:
    """Each free parameter's start (``start``'s, else the estimate's), box and scaling; a given
    start outside its box is refused (FitError). The nuisance parameters' boxes from ``trace``."""
    limits = fmu_bounds()
    x0, box, scaling = {}, {}, {}
    for n in free_names:
        if n in NZ.NUISANCE:
            lo, hi, s, sc = NZ.nuisance_box(trace, n, mass_band)
            if n in start:
                if not lo <= float(start[n]) <= hi:
                    raise FitError(f"start value for '{n}': {start[n]!r} is outside its range [{lo:g}, {hi:g}]")
                s = float(start[n])
            x0[n], box[n], scaling[n] = s, (lo, hi), sc
            continue
        s = float(start[n]) if n in start else float(est.get(n, defaults[n]))
        lo, hi, s, sc = bounds_and_start(n, s, limits, scales)
        if n in start and s != float(start[n]):
            raise FitError(f"start value for '{n}': {start[n]!r} is outside the FMU's range [{lo:g}, {hi:g}]")
        x0[n], box[n], scaling[n] = s, (lo, hi), sc
    return x0, box, scaling


def _weighted_experiments(traces: list[Trace], spec: ModelSpec,
                          held: Mapping[str, float]) -> tuple[list[TraceExperiment], float]:
    """The experiments and their weights (inverse noise, normalized; periodic means: sqrt(K)), and
    the weighted number of samples."""
    exps = [trace_experiment(tr, spec, held) for tr in traces]
    noises = np.array([max(x.noise, 1e-300) for x in exps])
    ref = float(np.exp(np.mean(np.log(noises))))
    for x, s in zip(exps, noises):
        x.exp.weight = math.sqrt(x.periods) * (ref / s if len(exps) > 1 else 1.0)
    return exps, sum((len(x.exp.time) if x.trace.fitted_samples is None else fitted_count(x.trace))
                     * x.exp.weight ** 2 for x in exps)


def _engine_options(engine_options: Mapping, exps: list[TraceExperiment], scales: Mapping) -> dict:
    """The caller's engine options; free vibration adds horizon stages and a stride that keeps the
    Hermite interpolation between solver calls far below the noise (omega h <= 0.1)."""
    opts = dict(engine_options)
    free_vib = [x for x in exps if x.trace.experiment == "free_vibration"]
    if free_vib and "horizon_stages" not in opts:
        opts["horizon_stages"] = 3
    if free_vib and "output_stride" not in opts:
        omega = float(scales.get("_omega", 0.0)) or 0.0
        dt = min(float(np.median(np.diff(x.trace.time))) for x in free_vib)
        # the cubic stiffens: allow for twice the frequency at the balance
        stride = int(0.1 / (2.0 * omega * dt)) if omega > 0 else 1
        opts["output_stride"] = max(1, min(stride, 50))
    return opts


def _stages(free_names: list[str]) -> list[tuple[str, list[str]]]:
    """(name, free) per stage: the elastic law and viscous damping (with the nuisance parameters,
    which a wrong mass or an offset would otherwise push into the law); where a state of
    SCANNED_AFTER_LAW is free, everything but that state (held at its start; the scan follows);
    then everything."""
    base = [n for n in free_names if n in FIRST_STAGE]
    # a law's state (the Iwan bank's memory, a preload's creep) is fitted with the law: beside a bank
    # held at its start the memory runs off
    nuisance_free = [n for n in free_names if n in NZ.NUISANCE and n not in NZ.LAW_STATE]
    stages = []
    if base and len(base) + len(nuisance_free) < len(free_names):
        stages.append(("elastic law + viscous damping" + (" + nuisance" if nuisance_free else ""),
                       base + nuisance_free))
    held = [n for n in free_names if n in SCANNED_AFTER_LAW]
    if held and len(held) < len(free_names):
        stages.append((f"all but {', '.join(held)}", [n for n in free_names if n not in held]))
    stages.append(("all free parameters", list(free_names)))
    return stages


def _run_stages(problem: _Problem, n_starts: int, progress: Callable[[FitProgress], object] | None,
                t_begin: float) -> tuple[dict, int, list, idn.FitResult]:
    """The stages through the engine, each from the last one's values; (values, simulations, one
    record per stage, the last stage's engine result)."""
    stages = _stages(problem.free)
    current = dict(problem.x0)
    evaluations = 0
    stage_log = []
    r = None
    for si, (sname, names) in enumerate(stages):
        if progress:
            progress(FitProgress(sname, si, len(stages), -1, float("nan"), 0, _time.perf_counter() - t_begin,
                                 free=list(names)))
        for state in (GRIDS if si == len(stages) - 1 else ()):
            if state in names:
                current = scan_memory(current, problem.free, problem.exps[0].trace, problem.box,
                                      lambda v: _residuals(problem, v), state)
        hold = {n: current[n] for n in problem.free if n not in names}
        for x in problem.exps:
            x.exp.settings = {**x.exp.settings, **hold}
        fr = {n: (*problem.box[n], _stage_start(current[n], problem.x0[n], problem.box[n], problem.scaling[n]))
              for n in names}
        cb = _engine_progress(progress, problem.exps, sname, si, len(stages), names, t_begin)
        o = _stage_options(problem.options, si == len(stages) - 1, n_starts)
        t_stage = _time.perf_counter()
        r = idn.fit([x.exp for x in problem.exps], fr, scaling={n: problem.scaling[n] for n in names}, progress=cb,
                    **o)
        evaluations += r.evaluations
        # inside the box it was given: a value the engine's scaling maps back from the bound can
        # round past it (creep_tau1 = 1.0000000000000006e7 against 1e7), and the next fit started
        # from it would be refused
        current.update({n: min(max(v, problem.box[n][0]), problem.box[n][1]) for n, v in r.as_dict().items()})
        stage_log.append({"stage": sname, "free": list(names), "rms": math.sqrt(2 * r.cost / problem.n_eff),
                          "evaluations": r.evaluations, "iterations": r.iterations,
                          "seconds": _time.perf_counter() - t_stage, "message": r.message,
                          "status": int(r.status)})
    assert r is not None
    for x in problem.exps:   # leave the experiments as built (held values of the first stage undone)
        x.exp.settings = {**x.exp.settings, **{n: current[n] for n in problem.free}}
    return current, evaluations, stage_log, r


def _stage_start(value: float, start: float, box: tuple[float, float], scaling: str) -> float:
    """A stage's start of a parameter from the last stage's ``value``: inside its box; where it is
    log-scaled and the last stage drove it to zero (a parameter the records hardly see, such as a
    damping beside a hysteresis), the fit's own ``start`` again, for the engine refuses a
    log-scaled start of 0 and a parameter at the smallest double would never move again."""
    v = min(max(value, box[0]), box[1])
    return start if scaling == "log" and not v > 0 else v


def _stage_options(options: Mapping, last: bool, n_starts: int) -> dict:
    """The engine's options of a stage: an intermediate stage only brings the start near the
    optimum (a looser stop, forward differences); the last one runs the starts asked for."""
    o = dict(options)
    if not last:
        o.setdefault("max_iterations", 20)
        o["ftol"] = max(float(o.get("ftol", 1e-10)), 1e-4)
        o.setdefault("central_differences", idn.FORWARD)
    if last and n_starts > 1:
        o["n_starts"] = int(n_starts)
        o.setdefault("start_spread", 0.3)
    return o


def _engine_progress(progress: Callable[[FitProgress], object] | None, exps: list[TraceExperiment], sname: str,
                     si: int, n_stages: int, names: list[str], t_begin: float) -> Callable:
    """The engine's progress callback of a stage: a FitProgress per LM iteration, its RMS over the
    part of the records the engine's horizon stage fits."""
    def cb(st, hstage, n_h, it, cost, ev):
        if progress:
            # a horizon stage fits the first 1/2^(n_h - 1 - hstage) of each non-periodic record
            frac = 2.0 ** -(n_h - 1 - hstage)
            n_h_eff = sum((len(x.exp.time) if x.exp.periodic_samples else
                           max(min(len(x.exp.time), len(names) + 2), math.ceil(len(x.exp.time) * frac)))
                          * x.exp.weight ** 2 for x in exps)
            progress(FitProgress(sname, si, n_stages, it, math.sqrt(2 * cost / n_h_eff), int(ev),
                                 _time.perf_counter() - t_begin, free=list(names), start=st,
                                 horizon=f"{hstage + 1}/{n_h}" if n_h > 1 else ""))
        return 0
    return cb


def _predictions(problem: _Problem, values: Mapping[str, float]) -> tuple[dict, list, float]:
    """The model's parameters with the free ones at ``values`` (nuisance ones aside), its
    predictions per trace, and the overall RMS error."""
    ps = dict(problem.model_values)
    ps.update(problem.fixed_nuisance)
    ps.update({n: float(values[n]) for n in problem.free})
    pred = [predict(x, ps) for x in problem.exps]
    tot = float(np.sqrt(sum(_squares(p, x.trace) for p, x in zip(pred, problem.exps))
                        / sum(fitted_count(x.trace) for x in problem.exps)))
    return {n: v for n, v in ps.items() if n not in NZ.NUISANCE}, pred, tot


def _squares(predicted: np.ndarray, trace: Trace) -> float:
    """The sum of squared errors over the samples a fit sees (Trace.fitted_samples)."""
    e = predicted - np.asarray(trace.measured, float)
    return float(np.sum(e ** 2 if trace.fitted_samples is None else e[trace.fitted_samples] ** 2))


def _residuals(problem: _Problem, values: Mapping[str, float]) -> np.ndarray:
    """The model's misfit of every trace's measured column, one vector."""
    _, pred, _ = _predictions(problem, values)
    return np.concatenate([(p - np.asarray(x.trace.measured, float)) * (1.0 if x.exp.sample_weight is None
                                                                        else x.exp.sample_weight)
                           for p, x in zip(pred, problem.exps)])


def _statistics(problem: _Problem, r: idn.FitResult, current: Mapping[str, float], max_rel: float) -> dict:
    """FitResult's fields of the values ``current``: standard errors, intervals, correlations,
    identifiability (``max_rel``: the largest standard error of a determined value, relative to
    it), the engine's status and the nuisance parameters."""
    free_names = problem.free
    idx = {n: i for i, n in enumerate(r.names)}
    values = {n: float(current[n]) for n in free_names}
    std = {n: float(r.std_error[idx[n]]) for n in free_names}
    ci = {n: (float(r.ci_low[idx[n]]), float(r.ci_high[idx[n]])) for n in free_names}
    order = [idx[n] for n in free_names]
    corr = np.asarray(r.correlation)[np.ix_(order, order)]
    # the engine flags parameters in near-null directions of the Jacobian and those whose standard
    # error, in its scaled coordinates, exceeds max_rel_std (log scale: relative to the value; linear
    # scale: relative to the start). Judge linear-scaled ones against their fitted value as well:
    # a value the data cannot tell from zero is not determined either.
    # (not the nuisance parameters: an offset or initial state near zero is determined when its
    # interval is narrow, whatever its size)
    loose = [n for n in free_names if problem.scaling[n] == "linear" and n not in r.unidentifiable
             and n not in NZ.NUISANCE and not std[n] <= max_rel * abs(values[n])]
    nuisance_free = {n: values[n] for n in free_names if n in NZ.NUISANCE}
    unid = [n for n in free_names if n in r.unidentifiable or n in loose]
    return dict(
        free=list(free_names), values=values, std_error=std, ci95=ci, correlation=corr, unidentifiable=unid,
        identifiability_report=_identifiability_text(r, free_names, unid, loose, values, std, max_rel),
        status=int(r.status), condition=float(r.condition), singular_values=[float(v) for v in r.singular_values],
        nuisance={**problem.fixed_nuisance, **nuisance_free},
        nuisance_moved=NZ.moved_statement(nuisance_free, problem.x0, ci))


def _identifiability_text(r: idn.FitResult, names: Sequence[str], unid: Sequence[str], loose: Sequence[str],
                          values: Mapping[str, float], std: Mapping[str, float], max_rel: float) -> str:
    """The identifiability report: every parameter determined, or which are not and why."""
    if not unid:
        return (f"Every fitted parameter is determined by the data: standard errors below {max_rel:g} of "
                f"the value, no near-null direction (condition number of the scaled Jacobian {r.condition:.3g}).")
    lines = [f"Not determined by the data: {', '.join(unid)}."]
    if r.report.strip():
        lines.append("Directions of the scaled parameters (log-scaled: relative) the data hardly see, with "
                     "their relative size sigma/sigma_max and standard deviation:")
        lines += ["  " + ln for ln in r.report.strip().splitlines()]
    for n in loose:
        lines.append(f"  {n} = {values[n]:.6g} +- {std[n]:.3g}: the standard error exceeds {max_rel:g} of the "
                     f"value (the data cannot tell it from zero)")
    lines.append("Fix some of them (or add data that excites them) to determine the rest.")
    return "\n".join(lines)
