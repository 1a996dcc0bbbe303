"""Parameter sweeps: many runs of one trace, one row of summary outputs per run.

A sweep is a :class:`Plan`: the trace, the model, the base parameters and one set of varied values
per run, either a full-factorial grid (:func:`grid_plan`, from ``NAME=LO:HI:N`` specs) or draws
from a fit's uncertainty (:func:`sample_plan`, from the P.json that ``tether fit`` writes).

Varied names are the FMU's parameters, the trace's own values (``L0``, ``m``, ``g``, ``x0``,
``v0``: a varied one wins over the trace's) and ``force_scale`` / ``load_scale``, a factor on the
trace's input column.

One run (:func:`run_one`) gives the row :data:`OUTPUTS` (the measured column's name in place of
``MEASURED``): ``max_tension``, ``min_tension``, ``peak_MEASURED`` (largest magnitude),
``rms_MEASURED``, ``slack_time`` (seconds of the sample intervals that start slack, tension 0),
``final_elongation`` (the FMU's strain times L0 at the last sample) and ``rmse`` against the
measured column. Rows hold no timings or host names: a run's row is a function of its inputs only.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .models import TRACE_PARAMETERS, ModelSpec, ParamsError, check_parameters, parse_model
from .run import simulate
from .traces import Trace

#: the summary outputs of a run, in row order ("MEASURED": the trace's measured column)
OUTPUTS = ("max_tension", "min_tension", "peak_MEASURED", "rms_MEASURED", "slack_time", "final_elongation", "rmse")
#: trace attribute that a varied trace parameter replaces
_TRACE_FIELDS = {"L0": "length_m", "m": "payload_mass_kg", "g": "gravity_m_s2", "x0": "initial_displacement_m",
                 "v0": "initial_velocity_m_s", "line_density": "line_density_kg_m"}


class SweepError(ValueError):
    """A sweep that cannot run as asked; ``str(e)`` is one line naming the option or file and value."""


def output_names(trace: Trace) -> list[str]:
    return [n.replace("MEASURED", trace.measured_column) for n in OUTPUTS]


def scale_name(trace: Trace) -> str | None:
    """The varied name of the factor on the trace's input column (``force_scale``/``load_scale``)."""
    return f"{trace.input_column}_scale" if trace.input_column else None


# ---------------------------------------------------------------------------------------------
@dataclass
class Plan:
    trace: Trace
    model: str                        # canonical model string
    base: dict                        # parameters every run gets (a run's varied values win)
    names: list                       # varied names, in column order
    runs: list                        # per run: the varied values, in the order of `names`
    description: dict                 # what the sweep is, for the resume check (JSON-ready)

    @property
    def columns(self) -> list[str]:
        return ["run", *self.names, *output_names(self.trace)]

    def fingerprint(self) -> dict:
        """What a resumed sweep must share with the one it continues: key -> sha256 (or value)."""
        tr = self.trace
        return {
            "trace": _sha256(tr.csv_path.read_bytes() + b"\0" + tr.json_path.read_bytes()),
            "model": self.model,
            "parameters": _sha256(json.dumps(self.base, sort_keys=True).encode()),
            "columns": self.columns,
            "runs": _sha256(json.dumps([[repr(v) for v in r] for r in self.runs]).encode()),
            "sweep": self.description,
        }


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def check_varied_names(names: Sequence[str], trace: Trace, spec: ModelSpec, where: str) -> None:
    """Each name must be a parameter the model uses, a trace value or the input scale."""
    from .fmu import model_description

    desc = model_description()
    scale = scale_name(trace)
    for n in names:
        if n in TRACE_PARAMETERS or n == scale:
            if n in ("m", "x0", "v0", "line_density") and trace.rig != "payload":
                raise SweepError(f"{where} {n}: '{n}' belongs to the payload rig; {trace.name} is a "
                                 f"{trace.experiment} test (load rig)")
            continue
        if n.endswith("_scale") and n[:-len("_scale")] in ("force", "load"):
            raise SweepError(f"{where} {n}: {trace.name} has "
                             + (f"the input '{trace.input_column}': vary {scale}" if scale else "no input column"))
        if n not in desc.parameters:
            raise SweepError(f"{where} {n}: not a parameter of the FMU nor of the trace (L0, m, g, x0, v0, line_density"
                             f"{', ' + scale if scale else ''})")
        if n not in spec.parameters:
            raise SweepError(f"{where} {n}: not used by the model '{spec.canonical}'; its parameters are "
                             f"{', '.join(spec.parameters)}")


def parse_vary(text: str) -> tuple[str, np.ndarray]:
    """``NAME=LO:HI:N`` -> (NAME, N values from LO to HI, ends included; N = 1 gives LO)."""
    name, eq, rng = text.partition("=")
    parts = rng.split(":")
    if not eq or not name.strip() or len(parts) != 3:
        raise SweepError(f"--vary {text}: expected NAME=LO:HI:N, e.g. a1=900:1500:8")
    try:
        lo, hi = float(parts[0]), float(parts[1])
        n = int(parts[2])
    except ValueError:
        raise SweepError(f"--vary {text}: LO and HI must be numbers and N a whole number") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or n < 1:
        raise SweepError(f"--vary {text}: LO and HI must be finite and N >= 1")
    return name.strip(), np.linspace(lo, hi, n) if n > 1 else np.array([lo])


def grid_plan(trace: Trace, model: str | ModelSpec, base: Mapping[str, float], vary: Sequence[str]) -> Plan:
    """The full-factorial grid of the ``--vary`` specs (the first varies slowest)."""
    spec = (parse_model(model) if isinstance(model, str) else model).for_experiment(trace.experiment)
    axes = [parse_vary(v) for v in vary]
    names = [n for n, _ in axes]
    dup = [n for n in names if names.count(n) > 1]
    if dup:
        raise SweepError(f"--vary {dup[0]}: given twice")
    check_varied_names(names, trace, spec, "--vary")
    for n, values in axes:
        if n not in TRACE_PARAMETERS and n != scale_name(trace):
            for v in (values[0], values[-1]):
                try:
                    check_parameters({n: float(v)}, "--vary")
                except ParamsError as e:
                    raise SweepError(str(e)) from None
    runs = [list(map(float, combo)) for combo in itertools.product(*(values for _, values in axes))]
    return Plan(trace, spec.canonical, dict(base), names, runs, {"vary": list(vary)})


# ---------------------------------------------------------------------------------------------
# samples from a fit's uncertainty
def parameter_bounds(name: str) -> tuple[float, float]:
    """The range a fit keeps ``name`` in: the FMU's min/max and the fit's own ranges."""
    from .fit.parameters import FIT_RANGES
    from .fmu import model_description

    var = model_description().parameters.get(name)
    lo = -math.inf if var is None or var.min is None else float(var.min)
    hi = math.inf if var is None or var.max is None else float(var.max)
    if name in FIT_RANGES:
        lo, hi = max(lo, FIT_RANGES[name][0]), min(hi, FIT_RANGES[name][1])
    return lo, hi


def fit_uncertainty(extra: Mapping, parameters: Mapping[str, float], where: str):
    """(names, values, standard errors, correlation matrix) from a fit's P.json (its ``extra``)."""
    corr = extra.get("correlation")
    se = extra.get("std_error")
    if not isinstance(corr, dict) or not isinstance(se, dict):
        raise SweepError(f"{where}: no 'std_error' and 'correlation' keys; --samples needs the P.json that "
                         "`tether fit --out` writes")
    names = list(corr.get("parameters") or [])
    matrix = np.asarray(corr.get("matrix"), dtype=float)
    if not names or matrix.shape != (len(names), len(names)):
        raise SweepError(f"{where}: key 'correlation': expected 'parameters' and a square 'matrix' of that size")
    # a fit's nuisance parameters (docs/nuisance.md) belong to its record, not to the model: the
    # draws are of the law, from its marginal (the law's rows and columns of the correlation)
    from .nuisance import NUISANCE

    law = [i for i, n in enumerate(names) if n not in NUISANCE]
    names, matrix = [names[i] for i in law], matrix[np.ix_(law, law)]
    if not names:
        raise SweepError(f"{where}: the fit freed only nuisance parameters; --samples draws the law's")
    values, errors = [], []
    for n in names:
        if n not in parameters or n not in se:
            raise SweepError(f"{where}: fitted parameter '{n}' has no value or no std_error")
        s = float(se[n]) if isinstance(se[n], (int, float)) else float("nan")
        if not (math.isfinite(s) and s >= 0):
            raise SweepError(f"{where}: key 'std_error': '{n}' = {se[n]!r}; the fit did not determine it "
                             "(fit again with it held, --free)")
        values.append(float(parameters[n]))
        errors.append(s)
    return names, np.array(values), np.array(errors), matrix


def draw_samples(names: Sequence[str], values: np.ndarray, errors: np.ndarray, corr: np.ndarray, n: int,
                 seed: int, log_scaled: Sequence[str] = (), bounds: Mapping[str, tuple] | None = None,
                 where: str = "--params") -> np.ndarray:
    """``n`` draws (rows) of a multivariate normal in the scale the fit used: ``log_scaled`` names
    in log(value) with standard error se/value (the engine's covariance maps so: dp = p dtheta),
    the rest in the value itself; draws outside ``bounds`` are drawn again (a truncated normal).
    The same seed gives the same draws."""
    k = len(names)
    log = np.array([nm in log_scaled for nm in names])
    if np.any(log & (values <= 0)):
        bad = names[int(np.argmax(log & (values <= 0)))]
        raise SweepError(f"{where}: '{bad}' was fitted in log scale but its value is not positive")
    centre = np.where(log, np.log(np.where(log, values, 1.0)), values)
    sd = np.where(log, errors / np.where(log, values, 1.0), errors)
    w, v = np.linalg.eigh(0.5 * (corr + corr.T))
    root = v * np.sqrt(np.clip(w, 0.0, None))          # corr = root root^T, positive semi-definite part
    lo = np.array([(bounds or {}).get(nm, (-math.inf, math.inf))[0] for nm in names])
    hi = np.array([(bounds or {}).get(nm, (-math.inf, math.inf))[1] for nm in names])
    rng = np.random.default_rng(seed)
    out = np.empty((0, k))
    outside = np.zeros(k, dtype=int)
    drawn = 0
    while len(out) < n:
        z = rng.standard_normal((n, k)) @ root.T
        theta = centre + z * sd
        p = np.where(log, np.exp(np.where(log, theta, 0.0)), theta)
        ok = np.all((p >= lo) & (p <= hi), axis=1)
        outside += np.sum((p < lo) | (p > hi), axis=0)
        drawn += n
        out = np.vstack([out, p[ok]])
        if drawn >= 100 * n and len(out) < n:
            worst = names[int(np.argmax(outside))]
            raise SweepError(f"{where}: fewer than 1 % of the draws fall inside the bounds; '{worst}' "
                             f"(value {values[names.index(worst)]:g}, std error {errors[names.index(worst)]:g}) "
                             f"leaves its range {bounds.get(worst) if bounds else ''} most often")
    return out[:n]


def sample_plan(trace: Trace, model: str | ModelSpec, base: Mapping[str, float], extra: Mapping, n: int,
                seed: int, where: str) -> Plan:
    """``n`` parameter sets drawn from the fit in ``extra`` (a P.json's statistics) around ``base``."""
    from .fit.parameters import LOG_SCALED

    spec = (parse_model(model) if isinstance(model, str) else model).for_experiment(trace.experiment)
    if n < 1:
        raise SweepError(f"--samples {n}: expected a whole number >= 1")
    names, values, errors, corr = fit_uncertainty(extra, base, where)
    check_varied_names(names, trace, spec, f"{where}: fitted parameter")
    bounds = {nm: parameter_bounds(nm) for nm in names}
    draws = draw_samples(names, values, errors, corr, n, seed, LOG_SCALED, bounds, where)
    return Plan(trace, spec.canonical, dict(base), list(names), [list(map(float, r)) for r in draws],
                {"samples": n, "seed": seed})


# ---------------------------------------------------------------------------------------------
# one run
def _trace_for(trace: Trace, varied: Mapping[str, float]) -> Trace:
    """The trace with its own values replaced by the varied ones (L0, m, g, x0, v0, input scale)."""
    changes = {_TRACE_FIELDS[n]: float(v) for n, v in varied.items() if n in _TRACE_FIELDS}
    scale = scale_name(trace)
    if scale in varied:
        changes["input"] = trace.input * float(varied[scale])
    return dataclasses.replace(trace, **changes) if changes else trace


def run_one(trace: Trace, model: str, base: Mapping[str, float], varied: Mapping[str, float],
            series: bool = False):
    """(row outputs, (time, predicted, tension) or None) of one run."""
    tr = _trace_for(trace, varied)
    params = {**base, **{n: v for n, v in varied.items() if n not in _TRACE_FIELDS and n != scale_name(trace)}}
    r = simulate(tr, model, params)
    y, T, t = r.predicted, r.tension, r.time
    slack = float(np.sum(np.diff(t)[T[:-1] <= 0.0]))
    measured = getattr(tr, "measured", None)
    rmse = float(np.sqrt(np.mean((y - measured) ** 2))) if measured is not None else float("nan")
    row = [float(np.max(T)), float(np.min(T)), float(np.max(np.abs(y))), float(np.sqrt(np.mean(y ** 2))),
           slack, float(r.final_strain * tr.length_m), rmse]
    return row, ((t, y, T) if series else None)


def run_chunk(chunk: Sequence[tuple[int, Sequence[float]]], trace: Trace, model: str, base: Mapping[str, float],
              names: Sequence[str], shipped_fmu, series: bool):
    """A Dask task: the runs of ``chunk`` ((index, varied values) pairs) with the shipped FMU;
    per run (index, outputs, series or None, the simulation's error or None). A run the FMU
    refuses gives outputs of NaN and its one-line error: one such set of values does not end a
    campaign."""
    from .campaign import use_fmu
    from .run import SimulationError

    if shipped_fmu is not None:
        use_fmu(shipped_fmu)
    out = []
    for i, values in chunk:
        try:
            out.append((i, *run_one(trace, model, base, dict(zip(names, values)), series), None))
        except SimulationError as e:
            out.append((i, [math.nan] * len(OUTPUTS), None, str(e)))
    return out


def format_row(index: int, values: Sequence[float], outputs: Sequence[float]) -> str:
    """One CSV line; floats as repr (the shortest text that reads back to the same double)."""
    return ",".join([str(int(index)), *(repr(float(v)) for v in values), *(repr(float(v)) for v in outputs)]) + "\n"


# ---------------------------------------------------------------------------------------------
# a sweep on a Dask client
def chunk_size(n_runs: int, n_workers: int, seconds_per_run: float, task_seconds: float = 0.25) -> int:
    """Runs per task: about ``task_seconds`` of work (a task costs the scheduler milliseconds), and
    at least four tasks per worker so that the load evens out and rows come in steadily."""
    by_time = max(1, int(round(task_seconds / max(seconds_per_run, 1e-6))))
    by_balance = max(1, math.ceil(n_runs / (4 * max(n_workers, 1))))
    return min(by_time, by_balance)


def execute(plan: Plan, client, rows, todo: Sequence[int], series_dir: Path | None = None,
            seconds_per_run: float = 0.0, progress=None) -> dict[int, str]:
    """Run the runs ``todo`` of ``plan`` on ``client``; each row goes to ``rows`` (a
    :class:`tether.sweep_output.RowsFile`) as its task finishes, its series first (Parquet).
    Returns the runs the FMU refused: index -> error (their rows hold NaN outputs)."""
    from .campaign import run_tasks, ship_fmu
    from .sweep_output import write_series

    failed: dict[int, str] = {}
    if not todo:
        return failed
    n_workers = max(1, sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values()))
    size = chunk_size(len(todo), n_workers, seconds_per_run)
    chunks = [[(i, plan.runs[i]) for i in todo[k:k + size]] for k in range(0, len(todo), size)]
    if progress:
        progress(f"{len(todo)} runs in {len(chunks)} tasks of up to {size} on {n_workers} worker"
                 f"{'s' if n_workers > 1 else ''}")
    trace = client.scatter(plan.trace, hash=False, broadcast=True)
    fmu = ship_fmu(client)
    for _, results in run_tasks(client, run_chunk, chunks, trace, plan.model, plan.base, plan.names, fmu,
                                series_dir is not None, label="task", progress=progress):
        for index, outputs, ser, error in results:
            if error is not None:
                failed[index] = error
                if progress:
                    progress(f"  run {index} failed, its row holds NaN: {error}")
            if ser is not None:
                write_series(series_dir, index, plan.trace.measured_column, *ser)
            if index not in rows.rows:
                rows.append(index, format_row(index, plan.runs[index], outputs))
    return failed
