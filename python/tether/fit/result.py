"""What a fit hands back: its result (FitResult, and the parameter file written from it), its
progress reports (FitProgress) and its one error (FitError)."""

from __future__ import annotations

import math

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..models import write_params


class FitError(ValueError):
    """A fit that cannot be set up (bad free names, no traces, ...); ``str(e)`` is one line."""


@dataclass
class FitResult:
    model: str                      # canonical model string
    parameters: dict                # every parameter that defines the fitted model (fixed + fitted), --params form
    free: list                      # names fitted
    values: dict                    # name -> fitted value
    std_error: dict                 # name -> standard error
    ci95: dict                      # name -> (low, high)
    correlation: np.ndarray         # k x k, order of `free`
    unidentifiable: list
    identifiability_report: str
    rms: float                      # overall RMS of (simulated - measured) over all traces
    rms_per_trace: list
    predictions: list               # simulated measured column on each trace's own time grid
    evaluations: int
    seconds: float
    status: int
    message: str
    # extras
    traces: list = field(default_factory=list)          # trace names
    noise: list = field(default_factory=list)           # noise level estimated per trace (measured unit)
    start: dict = field(default_factory=dict)           # the start values of the free parameters
    stages: list = field(default_factory=list)          # per stage: name, free, rms, evaluations, seconds, status
    condition: float = float("nan")
    singular_values: list = field(default_factory=list)
    # nuisance parameters (docs/nuisance.md): name -> value of every one fitted or given (fixed);
    # which of them were fitted is in `free`, their intervals in ci95 like the law's
    nuisance: dict = field(default_factory=dict)
    nuisance_moved: list = field(default_factory=list)   # one line each: start -> value, in interval widths

    @property
    def intervals(self) -> dict:
        """name -> (low, high): the 95 % intervals, under the name every JSON output uses."""
        return self.ci95

    def as_dict(self) -> dict:
        """JSON-ready summary (what ``tether fit --report`` writes to fit.json; schema
        docs/schemas/tether-fit-1.schema.json)."""
        return {
            "format": "tether-fit/1",
            "model": self.model,
            "traces": list(self.traces),
            "free": list(self.free),
            "parameters": dict(self.parameters),
            "values": dict(self.values),
            "start": dict(self.start),
            "std_error": dict(self.std_error),
            "intervals": {k: [float(a), float(b)] for k, (a, b) in self.ci95.items()},
            "correlation": np.asarray(self.correlation).tolist(),
            "unidentifiable": list(self.unidentifiable),
            "identifiability_report": self.identifiability_report,
            "rms": self.rms,
            "rms_per_trace": list(self.rms_per_trace),
            "noise_estimate": list(self.noise),
            "condition": self.condition,
            "singular_values": list(self.singular_values),
            "stages": list(self.stages),
            "evaluations": self.evaluations,
            "seconds": self.seconds,
            "status": self.status,
            "message": self.message,
            "nuisance": dict(self.nuisance),
            "nuisance_moved": list(self.nuisance_moved),
        }


@dataclass
class FitProgress:
    """One progress report: an LM iteration (iteration >= 0) or a stage starting (iteration -1)."""

    stage: str
    stage_index: int                # 0-based
    n_stages: int
    iteration: int
    rms: float                      # weighted RMS residual so far (measured unit)
    evaluations: int                # simulations of the data set in this stage
    seconds: float                  # since the fit began
    free: list = field(default_factory=list)
    start: int = 0                  # engine start (multistart)
    horizon: str = ""               # engine horizon stage, e.g. "1/3"

    def __str__(self) -> str:
        head = f"stage {self.stage_index + 1}/{self.n_stages} ({self.stage})"
        if self.iteration < 0:
            return f"{head}: fitting {', '.join(self.free)}"
        hz = f" horizon {self.horizon}" if self.horizon else ""
        st = f" start {self.start + 1}" if self.start else ""
        return (f"{head}{st}{hz} iteration {self.iteration + 1}: RMS {self.rms:.4g}, "
                f"{self.evaluations} simulations, {self.seconds:.1f} s")


def write_fit_params(path: str | Path, result: FitResult) -> Path:
    """The canonical parameter file (``tether simulate/validate --params`` read it) with the fit's
    statistics: {"model", "parameters", "intervals", "std_error", "correlation", "unidentifiable",
    "rms"}."""
    # a parameter the data do not determine has an infinite (or undefined) variance: null, so that
    # the file stays strict JSON
    extra = {
        "intervals": {n: [float(a), float(b)] if math.isfinite(a) and math.isfinite(b) else None
                      for n, (a, b) in result.ci95.items()},
        "std_error": {n: float(v) if math.isfinite(v) else None for n, v in result.std_error.items()},
        "correlation": {"parameters": list(result.free),
                        "matrix": [[float(v) if math.isfinite(v) else None for v in row]
                                   for row in np.asarray(result.correlation, float)]},
        "unidentifiable": list(result.unidentifiable),
        "rms": float(result.rms),
        "rms_per_trace": {n: float(v) for n, v in zip(result.traces, result.rms_per_trace)},
        "fitted": list(result.free),
        "traces": list(result.traces),
    }
    if result.nuisance:
        # the record's, not the model's: `tether validate --params` applies them to these traces only
        extra["nuisance"] = {n: float(v) for n, v in result.nuisance.items()}
    return write_params(path, result.model, result.parameters, extra)

