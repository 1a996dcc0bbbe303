"""Validation runs: simulate measured traces with the FMU and measure the disagreement.

For each trace: RMS error, normalized RMS error (RMS error / standard deviation of the
measurement), R^2, the largest error and when it happens, and, where the trace states its noise
level (the ``synthetic.noise.sigma_m`` of the project's reference traces), whether the error is
within that noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from .models import ModelSpec, parse_model
from .run import SimResult, simulate
from .traces import Trace, read_trace

#: an RMS error up to this multiple of the stated noise sigma counts as "within the noise"
WITHIN_NOISE_FACTOR = 1.2


@dataclass
class Validation:
    trace: Trace
    model: str
    parameters: dict
    result: SimResult
    rms: float
    nrmse: float
    r2: float
    max_error: float
    max_error_time: float
    noise_sigma: float | None
    within_noise: bool | None
    source: str                       # where the model came from: "command line" or "trace"
    residual: np.ndarray = field(repr=False, default=None)

    def as_dict(self) -> dict:
        return {
            "trace": str(self.trace.stem),
            "experiment": self.trace.experiment,
            "measured_column": self.trace.measured_column,
            "model": self.model,
            "model_source": self.source,
            "parameters": {k: v for k, v in sorted(self.parameters.items())},
            "samples": int(self.trace.n),
            "rms_error": self.rms,
            "normalized_rms_error": self.nrmse,
            "r2": self.r2,
            "max_error": self.max_error,
            "max_error_time": self.max_error_time,
            "noise_sigma": self.noise_sigma,
            "within_noise": self.within_noise,
            "warnings": list(self.result.warnings),
        }


def stated_noise(trace: Trace) -> float | None:
    """The noise sigma a trace states about itself (reference traces carry it), else None."""
    syn = trace.meta.get("synthetic") if isinstance(trace.meta, dict) else None
    try:
        return float(syn["noise"]["sigma_m"])
    except (TypeError, KeyError, ValueError):
        return None


def generating_model(trace: Trace) -> tuple[str, dict] | None:
    """(model, parameters) a synthetic trace was generated with, if it says so."""
    syn = trace.meta.get("synthetic") if isinstance(trace.meta, dict) else None
    if not isinstance(syn, dict) or "model" not in syn:
        return None
    params = dict(syn.get("parameters") or {})
    start = syn.get("fmu_start_values") or {}
    if isinstance(start.get("rtol"), (int, float)):
        params.setdefault("rtol", float(start["rtol"]))
    return str(syn["model"]), params


def metrics(measured: np.ndarray, predicted: np.ndarray, time: np.ndarray) -> dict:
    r = predicted - measured
    rms = float(np.sqrt(np.mean(r ** 2)))
    sd = float(np.std(measured))
    ss_tot = float(np.sum((measured - np.mean(measured)) ** 2))
    i = int(np.argmax(np.abs(r)))
    return {
        "rms": rms,
        "nrmse": rms / sd if sd > 0 else float("inf"),
        "r2": 1.0 - float(np.sum(r ** 2)) / ss_tot if ss_tot > 0 else float("nan"),
        "max_error": float(np.abs(r[i])),
        "max_error_time": float(time[i]),
        "residual": r,
    }


def validate_trace(trace: Trace | str | Path, model: str | ModelSpec | None = None,
                   params: Mapping[str, float] | None = None,
                   nuisance: Mapping[str, float] | None = None) -> Validation:
    """Validate one trace. Without ``model``, a synthetic trace is run with the model that
    generated it, any other trace with the linear baseline. ``nuisance``: the trace's nuisance
    parameters (a fit's FitResult.nuisance on it; tether.nuisance), applied as the fit applied them."""
    if not isinstance(trace, Trace):
        trace = read_trace(trace)
    source = "command line"
    if model is None:
        gen = generating_model(trace)
        if gen is not None:
            model, gen_params = gen
            params = {**gen_params, **dict(params or {})}
            source = "trace (synthetic: generating model)"
        else:
            model, source = "linear", "default (linear baseline)"
    spec = parse_model(model) if isinstance(model, str) else model
    result = simulate(trace, spec, params or {}, nuisance=nuisance)
    m = metrics(trace.measured, result.predicted, trace.time)
    sigma = stated_noise(trace)
    within = None if sigma is None else bool(m["rms"] <= WITHIN_NOISE_FACTOR * sigma)
    return Validation(trace=trace, model=spec.canonical, parameters=dict(params or {}), result=result,
                      rms=m["rms"], nrmse=m["nrmse"], r2=m["r2"], max_error=m["max_error"],
                      max_error_time=m["max_error_time"], noise_sigma=sigma, within_noise=within,
                      source=source, residual=m["residual"])


def find_traces(paths: Iterable[str | Path]) -> list[Path]:
    """Trace stems from files, stems or directories (a directory: every NAME.csv or NAME.csv.gz with a NAME.json)."""
    stems: list[Path] = []
    for p in paths:
        p = Path(p)
        if p.is_dir():
            found = [c.with_suffix("") for c in p.glob("*.csv")]
            found += [c.with_name(c.name[:-len(".csv.gz")]) for c in p.glob("*.csv.gz")]
            stems.extend(sorted({s for s in found if s.with_name(s.name + ".json").is_file()}))
        else:
            stems.append(p)
    return stems
