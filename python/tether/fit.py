"""Fit model parameters to measured traces: data-based starts, staged Levenberg-Marquardt through
the identification engine (the FMU's own physics), intervals and an identifiability report.

    from tether.fit import fit_traces, write_fit_params
    r = fit_traces([read_trace("train_multisine")], "linear+boucwen", progress=print)
    write_fit_params("P.json", r)          # tether simulate/validate --params P.json read it

How a fit runs
==============
1. **Experiments.** Each trace becomes one engine experiment exactly as :func:`tether.run.simulate`
   drives the FMU: the rig of its experiment, ``L0``, ``m``, ``g``, ``x0``, ``v0`` from its metadata
   (fixed, never fitted; a periodic record starts from rest), its input reconstructed by run.py's
   own helpers (``force`` a cubic spline, periodic for a periodic record; ``load`` PCHIP; the trace's
   ``input_interpolation`` key wins), one solver step sequence per sample like the FMU's.
   A periodic record of K periods is fitted as the mean of its periods with weight sqrt(K): the
   model's output repeats every period, so sum_k |y - m_k|^2 = K |y - mean(m)|^2 + const and the
   optimum, the covariance and the intervals are those of the whole record, at 1/K of the cost.
   Several traces share one parameter set; each trace's residuals are weighted by the inverse of
   its noise level estimated from the data (equal noise: weight 1).
2. **Starts from the data** (:func:`initial_estimate`, no hand-picked values):
   payload traces: equation error ``m x'' + c(x) x' + R(x) + z = f`` with derivatives from a
   Savitzky-Golay filter (periodic records: exact spectral derivatives below the highest excited
   frequency), linear in the stiffness and damping coefficients; with Bouc-Wen, ``z`` is integrated
   along the measured path for (A, beta, gamma) found by a small nonlinear least-squares (several
   data-scaled starts: A a fraction of the stiffness, beta and gamma from the amplitude). The
   cubic's a1, a2, a3 follow from the Taylor coefficients about the balance. Load tests: the static
   law inverted (linear or cubic fit of load against strain); Kawabata's LT, RT and residual strain
   from the cycle's energies; creep compliances by linear least squares on the Kelvin responses.
3. **Stages**: the elastic law and viscous damping first (other effects held at their starts),
   then every free parameter. Free-vibration records use the engine's horizon stages (first part
   of the record, then all of it) against the multimodality of an oscillation in its frequency.
4. **Statistics** at the optimum: standard errors, 95 % intervals (linearized, Student t),
   correlations, and the directions the data do not determine (SVD of the Jacobian), named.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import hashlib
import json
import math
import threading
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from . import identify_native as idn
from . import nuisance as NZ
from .blas import in_one_blas_thread
from .models import (IWAN_EPS, IWAN_EPS_FIT, IWAN_K, IWAN_K_FIT, ModelSpec, TRACE_PARAMETERS, SWITCHES, parse_model,
                     write_params)
from .run import _input_pieces, input_interpolation, record_period
from .traces import Trace, read_trace

__all__ = ["FitResult", "FitProgress", "FitError", "default_free_parameters", "initial_estimate", "fit_traces",
           "write_fit_params", "noise_level"]


class FitError(ValueError):
    """A fit that cannot be set up (bad free names, no traces, ...); ``str(e)`` is one line."""


# ---------------------------------------------------------------------------------------------
# results
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
    stages: list = field(default_factory=list)          # per stage: name, free, rms, evaluations, seconds
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


# ---------------------------------------------------------------------------------------------
# parameters
#: fitted on a log scale (one sign; the engine's steps are relative)
_LOG = {"EA", "a1", "c0", "bw_A", "kaw_F_ref", "kaw_eps_ref", "creep_J1", "creep_J2", "creep_J3", "creep_tau1",
        "creep_tau2", "creep_tau3", "slip_capacity0", "slip_rate", "slip_knee", "slip_load_half",
        "slip_load_exponent", "slip_regen_tau", "slip_limit", *IWAN_K}
#: the elastic law and viscous damping: the first stage
_BASE = {"EA", "a1", "a2", "a3", "c0", "kaw_LT", "kaw_RT", "kaw_F_ref", "kaw_residual", "kaw_eps_ref"}
#: the creep terms a fit frees by default: the Kelvin compliances and the slip
CREEP_FREE = ("creep_J1", "creep_J2", "creep_J3", "slip_capacity0", "slip_rate")


def _spec(model) -> ModelSpec:
    return parse_model(model) if isinstance(model, str) else model


def default_free_parameters(spec, experiment: str) -> list[str]:
    """The parameters the data of ``experiment`` can determine for ``spec``.

    Elastic law: ``EA``; cubic ``a1 a2 a3``; Kawabata ``kaw_LT kaw_RT kaw_F_ref`` plus the residual
    strain ``kaw_residual`` where the load returns to zero (load tests; ``kaw_eps_ref`` stays fixed:
    the virgin curve through (eps_ref, F_ref) is one curve, a point on it is one number).
    Damping (payload rig only; quasi-static load tests do not see it): ``c0``, plus ``c1 c2`` for
    displacement-dependent damping. Bouc-Wen: ``bw_A bw_beta bw_gamma`` (the force scale is fixed by
    the law; ``bw_n`` stays at its value and the shape terms ``bw_b2..b6`` at 0). Iwan: the element
    stiffnesses ``iw_k1..8`` (their slip strains stay on the grid the estimate chose, see
    iwan_slip_grid; elements 9..16 stay absent). Creep (creep tests
    only; seconds of vibration do not see it): the Kelvin compliances ``creep_J1..3`` (time
    constants fixed at their values, spanning minutes to days) and the slip ``slip_capacity0``,
    ``slip_rate``; a creep test holds two load levels, which determine ``EA`` but not a cubic or
    Kawabata law (held at its values: fit it on a load test and pass it with ``fixed``).
    """
    spec = _spec(spec).for_experiment(experiment)
    # two load levels cannot determine a three-coefficient law: fit it on a load test
    many = experiment == "creep" and (spec.stiffness == "cubic" or spec.hysteresis == "kawabata")
    names = law_free_parameters(spec, elastic=not many)
    if spec.creep and experiment == "creep":
        names += CREEP_FREE
    return names


def law_free_parameters(spec: ModelSpec, elastic: bool = True) -> list[str]:
    """The elastic law's (unless ``elastic`` is false), the damping's and Bouc-Wen's free
    parameters of ``spec`` (already set to its experiment's rig), as default_free_parameters
    describes them; creep is left to the caller."""
    payload = spec.rig == "payload"
    names: list[str] = []
    if not elastic:
        pass
    elif spec.hysteresis == "kawabata":
        names += ["kaw_LT", "kaw_RT", "kaw_F_ref"] + ([] if payload else ["kaw_residual"])
    elif spec.stiffness == "cubic":
        names += ["a1", "a2", "a3"]
    else:
        names += ["EA"]
    if payload:
        names += ["c0"] + (["c1", "c2"] if spec.damping == "displacement" else [])
    if spec.hysteresis == "boucwen":
        names += ["bw_A", "bw_beta", "bw_gamma"]
    if spec.hysteresis == "iwan":
        names += list(IWAN_K_FIT)
    return names


def _fmu_defaults() -> dict:
    return {n: idn.parameter_start(n) for n in idn.parameter_names(kind=0)}


def _fmu_bounds() -> dict:
    """name -> (min, max) of the FMU's parameters (None where unbounded)."""
    try:
        from .fmu import model_description
        d = model_description()
        return {n: (v.min, v.max) for n, v in d.parameters.items()}
    except Exception:  # noqa: BLE001 - without the FMU: no bounds beyond the engine's
        return {}


# ---------------------------------------------------------------------------------------------
# noise and derivatives from the data
def _robust_std(d: np.ndarray) -> float:
    d = np.asarray(d, float)
    d = d[np.isfinite(d)]
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))))


def noise_level(trace: Trace) -> float:
    """The measurement noise (standard deviation, measured unit) estimated from the data alone:
    from the differences between periods of a periodic record, else from the 4th differences of
    the measured column (robust scale; white noise gives 70 sigma^2)."""
    y = np.asarray(trace.measured, float)
    P = int(trace.periodic_samples or 0)
    if P and len(y) >= 2 * P:
        per = y.reshape(-1, P)
        dev = per - per.mean(axis=0)
        K = per.shape[0]
        return float(np.sqrt(np.sum(dev ** 2) / (P * (K - 1))))
    if len(y) < 8:
        return float(np.std(y)) or 1.0
    d4 = y[4:] - 4 * y[3:-1] + 6 * y[2:-2] - 4 * y[1:-3] + y[:-4]
    s = _robust_std(d4) / math.sqrt(70.0)
    if not s > 0:
        s = float(np.std(np.diff(y))) / math.sqrt(2.0)
    return s if s > 0 else max(1e-12, 1e-9 * float(np.max(np.abs(y))))


def _dominant_frequency(t: np.ndarray, y: np.ndarray) -> float:
    dt = float(np.median(np.diff(t)))
    yy = (y - np.mean(y)) * np.hanning(len(y))
    spec = np.abs(np.fft.rfft(yy))
    f = np.fft.rfftfreq(len(y), dt)
    spec[0] = 0.0
    return float(f[int(np.argmax(spec))]) or 1.0 / (t[-1] - t[0])


@dataclass
class _Kinematics:
    x: np.ndarray      # smoothed displacement
    v: np.ndarray
    a: np.ndarray
    f: np.ndarray      # force on the payload (0 for free vibration)
    use: np.ndarray    # samples the equation error may use (edges of a filter window dropped)
    periodic: bool


def _kinematics(trace: Trace, f_dom: float) -> _Kinematics:
    """Displacement, velocity and acceleration of a payload trace (one period for periodic records)."""
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    f = np.zeros_like(y) if trace.input is None else np.asarray(trace.input, float)
    P = int(trace.periodic_samples or 0)
    if P:
        # exact derivatives of the mean period's Fourier series, below the highest excited frequency
        x = y.reshape(-1, P).mean(axis=0)
        fp = f[:P]
        Tp = record_period(t, P)
        X = np.fft.rfft(x)
        w = 2 * np.pi * np.fft.rfftfreq(P, Tp / P)
        F = np.abs(np.fft.rfft(fp))
        if F.max() > 0:
            excited = F > 1e-3 * F.max()
            cut = 1.2 * w[excited].max() if excited.any() else w[-1]
            X[w > cut] = 0.0
        xs = np.fft.irfft(X, P)
        v = np.fft.irfft(1j * w * X, P)
        a = np.fft.irfft(-(w ** 2) * X, P)
        return _Kinematics(xs, v, a, fp.copy(), np.ones(P, bool), True)
    from .savgol import savgol

    dt = float(np.median(np.diff(t)))
    win = int(round(1.0 / (f_dom * dt) / 6.0)) | 1           # about a sixth of the dominant period
    win = max(7, min(win, 101, (len(y) // 4) | 1 if len(y) >= 28 else 7))
    if len(y) <= win:
        win = max(5, (len(y) - 1) | 1 if (len(y) - 1) % 2 else len(y) - 2)
    order = 4 if win >= 9 else 3
    xs = savgol(y, win, order, deriv=0)
    v = savgol(y, win, order, deriv=1, delta=dt)
    a = savgol(y, win, order, deriv=2, delta=dt)
    use = np.zeros(len(y), bool)
    use[win:len(y) - win] = True
    if use.sum() < 10:
        use[:] = True
    return _Kinematics(xs, v, a, f, use, False)


# ---------------------------------------------------------------------------------------------
# initial estimates
def _scaled_lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares A coef = b with A's columns scaled to unit norm (a column of zeros as it is):
    columns of displacement, velocity and their powers differ by many orders of magnitude."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(A / scale, b, rcond=None)
    return coef / scale


def _scaled_nnls(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative least squares A coef = b, coef >= 0, with A's columns scaled to unit norm as in
    _scaled_lstsq; returns coef and the residual norm |A coef - b| (which the scaling leaves as is)."""
    from scipy.optimize import nnls

    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    coef, res = nnls(A / scale, b)
    return coef / scale, float(res)


def _taut_for_sure(x: np.ndarray, m: float, g: float, k: float) -> np.ndarray:
    """Samples of a payload record whose displacement x stays above 90 % of the balance stretch
    m g / k below balance: taut whatever the law's details (a slack record's other samples may not be)."""
    return x > -0.9 * m * g / k


def _restoring_columns(x: np.ndarray, cubic: bool) -> list[np.ndarray]:
    return [x, x ** 2, x ** 3] if cubic else [x]


def _damping_columns(x: np.ndarray, v: np.ndarray, displacement: bool) -> list[np.ndarray]:
    return [v, np.abs(x) * v, x ** 2 * v] if displacement else [v]


def _cubic_from_taylor(k1: float, k2: float, k3: float, L0: float, weight: float) -> dict | None:
    """a1, a2, a3 from the Taylor coefficients about the balance: F(eps_b + x/L0) - F(eps_b) =
    k1 x + k2 x^2 + k3 x^3 and F(eps_b) = weight: eps_b solves K1 e - K2 e^2 + a3 e^3 = weight
    (K1 = k1 L0, K2 = k2 L0^2, a3 = k3 L0^3)."""
    K1, K2, a3 = k1 * L0, k2 * L0 ** 2, k3 * L0 ** 3
    if weight > 0:
        roots = np.roots([a3, -K2, K1, -weight])
        real = sorted(float(r.real) for r in roots if abs(r.imag) <= 1e-9 * max(1.0, abs(r)) and r.real > 0)
        if not real:
            return None
        eb = real[0]
    else:
        eb = 0.0
    a2 = K2 - 3 * a3 * eb
    a1 = K1 - 2 * K2 * eb + 3 * a3 * eb ** 2
    return {"a1": a1, "a2": a2, "a3": a3}


#: the Iwan bank of a fit: slip strains on a geometric grid, each IWAN_RATIO of the next, the
#: largest chosen by the equation error among IWAN_SPANS multiples of half the record's strain
#: range; the element stiffnesses then enter the equations linearly. An element that never slips
#: is a spring like the elastic law's: the largest stays within the range (with one at twice it,
#: a forced record with slack split its stiffness between the two, and the balance, where the
#: elastic law alone carries the weight, moved three times too low)
IWAN_RATIO = 0.55
IWAN_SPANS = (0.25, 0.5, 1.0)
#: a fit keeps each element's stiffness below this multiple of the tether's estimated stiffness
IWAN_CAP = 10.0


def iwan_slip_grid(e_max: float) -> list[float]:
    """Slip strains of the IWAN_FIT_ELEMENTS elements a fit frees, the largest e_max."""
    n = len(IWAN_EPS_FIT)
    return [float(e_max * IWAN_RATIO ** (n - 1 - i)) for i in range(n)]


def iwan_spring_strains(d: np.ndarray, slip: Sequence[float], periodic: bool = False) -> np.ndarray:
    """Spring strains of Jenkins elements slipping at ``slip`` along the strain path d (measured from
    where the springs are unloaded; the first sample reached monotonically from there), the path
    taken as straight between samples (physics/iwan.c). periodic: the path is one period of a
    steady cycle, run twice and the second pass kept. Shape (len(d), len(slip))."""
    d = np.asarray(d, float)
    e = np.asarray(slip, float)
    out = np.empty((len(d), len(e)))
    q = np.clip(d[0], -e, e)
    for lap in range(2 if periodic else 1):
        if lap:
            q = np.clip(q + (d[0] - d[-1]), -e, e)      # the period closes: from its end to its start
        out[0] = q
        for j in range(1, len(d)):
            q = np.minimum(np.maximum(q + (d[j] - d[j - 1]), -e), e)
            out[j] = q
    return out


def _iwan_bank(A_rest: np.ndarray, lo_rest: Sequence[float], b: np.ndarray, d: np.ndarray, rows: np.ndarray,
               span: float, periodic: bool) -> tuple[np.ndarray, list[float], np.ndarray] | None:
    """Equation error of the Iwan bank beside the other linear terms (columns A_rest, lower bounds
    lo_rest): for each grid of IWAN_SPANS, min |A_rest c + Q k - b| over the rows with k >= 0.
    Returns (c, k, Q @ k over all samples) of the best grid, or None."""
    from scipy.optimize import lsq_linear

    best = None
    for f in IWAN_SPANS:
        slip = iwan_slip_grid(f * span)
        Q = iwan_spring_strains(d, slip, periodic)
        A = np.column_stack([A_rest, Q])[rows]
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        lo = np.r_[np.asarray(lo_rest, float), np.zeros(Q.shape[1])]
        try:
            sol = lsq_linear(A / scale, b[rows], bounds=(lo, np.full(len(lo), np.inf)))
        except (ValueError, np.linalg.LinAlgError):
            continue
        coef = sol.x / scale
        rss = float(np.sum((A @ coef - b[rows]) ** 2))
        if best is None or rss < best[0]:
            nr = A_rest.shape[1]
            best = (rss, coef[:nr], slip, coef[nr:], Q @ coef[nr:])
    if best is None:
        return None
    _, c, slip, k, h = best
    total = float(np.sum(k))
    floor = 1e-3 * total if total > 0 else 1e-6
    return c, slip, np.maximum(k, floor), h


def _iwan_params(slip: Sequence[float], k: np.ndarray) -> dict:
    return {**{n: float(v) for n, v in zip(IWAN_K, k)}, **{n: float(v) for n, v in zip(IWAN_EPS, slip)}}


def _payload_estimate(trace: Trace, spec: ModelSpec) -> dict:
    """Equation-error estimates for one payload trace."""
    t = np.asarray(trace.time, float)
    m_w, m = idn.payload_masses(trace)    # the weight's mass and the inertia's (line density)
    g = float(trace.gravity_m_s2)
    L0 = float(trace.length_m)
    f_dom = _dominant_frequency(t, np.asarray(trace.measured, float))
    K = _kinematics(trace, f_dom)
    cubic = spec.stiffness == "cubic" or spec.hysteresis == "kawabata"
    disp = spec.damping == "displacement"
    bw = spec.hysteresis == "boucwen"
    rhs_all = K.f - m * K.a
    keep = K.use.copy()
    amp = float(np.max(np.abs(K.x[keep]))) or 1e-9

    def solve(z, sel, cub=cubic, dsp=disp):
        cols = _damping_columns(K.x[sel], K.v[sel], dsp) + _restoring_columns(K.x[sel], cub)
        A = np.column_stack(cols)
        b = rhs_all[sel] - (0.0 if z is None else z[sel])
        coef = _scaled_lstsq(A, b)
        res = b - A @ coef
        return coef, res

    # linear first: the stiffness scale; drop samples that may be slack (below the balance stretch)
    coef, _ = solve(None, keep, cub=False, dsp=False)
    k_lin = float(coef[1]) if coef[1] > 0 else m * (2 * math.pi * f_dom) ** 2
    c_lin = float(coef[0])
    if spec.slack and g > 0:
        slack_free = _taut_for_sure(K.x, m_w, g, k_lin)
        if slack_free[keep].sum() > 20:
            keep &= slack_free
    est: dict = {"_k_lin": k_lin, "_c_lin": c_lin, "_amp": amp, "_omega": math.sqrt(max(k_lin, 1e-300) / m)}

    z = None
    if bw:
        # (A, beta, gamma) by nonlinear least squares; the rest is linear (variable projection)
        from scipy.optimize import least_squares

        xs = K.x
        sA, sb = k_lin, 1.0 / amp

        def residual(p):
            # z along the measured path, the law integrated exactly sample to sample (physics/boucwen.c)
            zz = idn.bouc_wen_path(xs, p[0] * sA, p[1] * sb, p[2] * sb, K.periodic)
            _, r = solve(zz, keep)
            return r

        best = None
        for p0 in ([0.3, 1.5, 0.5], [0.5, 1.0, -0.5], [0.15, 3.0, 1.0], [0.6, 0.5, -1.0]):
            try:
                sol = least_squares(residual, p0, bounds=([1e-6, -1e3, -1e3], [10.0, 1e3, 1e3]), x_scale=1.0,
                                    diff_step=1e-4, max_nfev=60)
            except (ValueError, FloatingPointError):
                continue
            if best is None or sol.cost < best.cost:
                best = sol
        if best is not None:
            pA, pb, pg = best.x
            est.update(bw_A=float(pA * sA), bw_beta=float(pb * sb), bw_gamma=float(pg * sb))
            z = idn.bouc_wen_path(xs, est["bw_A"], est["bw_beta"], est["bw_gamma"], K.periodic)
    if spec.hysteresis == "iwan":
        # the bank's spring strains along the measured strain path from the balance, where its
        # springs are unloaded (held at zero strain where a slack tether is shortened): the element
        # stiffnesses enter linearly, >= 0
        eps_b = m_w * g / (k_lin * L0) if k_lin > 0 and g > 0 else 0.0
        d = K.x / L0
        if spec.slack:
            d = np.maximum(d + eps_b, 0.0) - eps_b
        cols = _damping_columns(K.x, K.v, disp) + _restoring_columns(K.x, cubic)
        span = 0.5 * float(np.ptp(d[keep])) or 1e-9
        bank = _iwan_bank(np.column_stack(cols), [-np.inf] * len(cols), rhs_all, d, keep, span, K.periodic)
        if bank is not None:
            _, slip, kb, z = bank
            est.update(_iwan_params(slip, kb))
            est["_iw_cap"] = IWAN_CAP * (k_lin * L0 + float(np.sum(kb)))
    coef, res = solve(z, keep)
    nd = 3 if disp else 1
    c = [float(v) for v in coef[:nd]]
    k = [float(v) for v in coef[nd:]]
    est["c0"] = c[0]
    if disp:
        # c(x) = c0 + c1 |x| + c2 x^2 >= 0: a term the equation error puts below zero starts small
        # (5 % of the record's linear damping at its amplitude), not at 0, where it has no scale
        c_ref = abs(c_lin) or 2 * 0.01 * math.sqrt(k_lin * m)
        est["c1"] = c[1] if c[1] > 0 else 0.05 * c_ref / amp
        est["c2"] = c[2] if c[2] > 0 else 0.05 * c_ref / amp ** 2
    weight = m_w * g
    if spec.hysteresis == "kawabata":
        est["_k_taylor"] = k
    elif cubic:
        a = _cubic_from_taylor(k[0], k[1], k[2], L0, weight)
        if a is None or not a["a1"] > 0:
            a = {"a1": k_lin * L0}            # no consistent balance: the linear part only
        est.update(a)
    else:
        est["EA"] = k[0] * L0
    est["_ee_rms"] = float(np.sqrt(np.mean(res ** 2)))
    return est


def _trapezoid(y: np.ndarray, x: np.ndarray) -> float:
    y = np.asarray(y, float)
    x = np.asarray(x, float)
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def _kawabata_cycle(trace: Trace) -> dict | None:
    """Kawabata's LT, RT and residual strain from one loading-unloading cycle of a load test."""
    T = np.asarray(trace.input, float)
    u = np.asarray(trace.measured, float)
    L0 = float(trace.length_m)
    Fm = float(T.max())
    if not Fm > 0:
        return None
    im = int(np.argmax(T))
    top = T >= Fm * (1 - 1e-9)
    last_top = int(np.flatnonzero(top)[-1])
    eps_m = float(np.mean(u[top])) / L0
    load = slice(0, im + 1)
    unload = slice(last_top, len(T))
    Tl, ul = T[load], u[load] / L0
    Tu, uu = T[unload], u[unload] / L0
    if len(Tl) < 3 or len(Tu) < 3 or not eps_m > 0:
        return None
    # energies by parts: int F d(eps) = F_m eps_m - int eps dF (the noisy strain is integrated over the load)
    WT = Fm * eps_m - float(_trapezoid(ul, Tl))
    zero = Tu <= 1e-9 * Fm
    eps_1 = max(0.0, float(np.mean(uu[zero]))) if zero.any() else 0.0
    # unloading from (eps_m, F_m) to (eps_1, 0): int F d(eps) = F_m eps_m - int eps dF (dF < 0 here)
    WTp = Fm * eps_m + float(_trapezoid(uu, Tu))
    if not (WT > 0 and WTp > 0):
        return None
    LT = WT / (Fm * eps_m / 2.0)
    RT = WTp / WT
    return {"LT": LT, "RT": RT, "residual": eps_1 / eps_m, "eps_m": eps_m, "F_m": Fm}


def kelvin_response(t: np.ndarray, T: np.ndarray, tau: float) -> np.ndarray:
    """Strain of a Kelvin cell of unit compliance and retardation time ``tau`` under the tension
    ``T`` sampled at ``t`` (over each interval the tension taken at the mean of its ends)."""
    w = np.zeros_like(T)
    for i in range(1, len(t)):
        h = t[i] - t[i - 1]
        e = math.exp(-h / tau)
        w[i] = w[i - 1] * e + (1 - e) * 0.5 * (T[i] + T[i - 1])
    return w


def slip_response(t: np.ndarray, T: np.ndarray, slip_tau: float) -> np.ndarray:
    """A saturating slip of unit size per loading (above half the largest tension), 1 -
    exp(-t_loaded / slip_tau), that stays after unloading and adds up over the loadings."""
    loaded = T > 0.5 * T.max()
    slip = np.zeros_like(T)
    done, since = 0.0, None
    for i in range(len(t)):
        if loaded[i]:
            since = t[i] if since is None else since
            slip[i] = done + 1.0 - math.exp(-(t[i] - since) / slip_tau)
        else:
            if since is not None:
                done += 1.0 - math.exp(-(t[i] - since) / slip_tau)
                since = None
            slip[i] = done
    return slip


def _creep_compliances(traces: Sequence[Trace], elastic: Callable[[np.ndarray], np.ndarray], taus: Sequence[float],
                       slip_tau: float):
    """Kelvin compliances J_k and the slip per loading by non-negative least squares:
    eps - eps_elastic(T) = sum_k J_k (T through 1/(1 + tau_k s)) + S (slip: for every loading, a
    saturating 1 - exp(-t_loaded / slip_tau) that stays after unloading)."""

    rows, rhs = [], []
    for tr in traces:
        t = np.asarray(tr.time, float)
        T = np.asarray(tr.input, float)
        eps = np.asarray(tr.measured, float) / float(tr.length_m)
        cols = [kelvin_response(t, T, tau) for tau in taus]
        cols.append(slip_response(t, T, slip_tau))
        rows.append(np.column_stack(cols))
        rhs.append(eps - elastic(T))
    A = np.vstack(rows)
    b = np.concatenate(rhs)
    # the slip per loading: what stays at the end of the first unloaded hold (the Kelvin cells of
    # minutes to hours have recovered by then); the long Kelvin cell would otherwise take it all
    persistent = []
    for tr, r in zip(traces, rhs):
        T = np.asarray(tr.input, float)
        loaded = T > 0.5 * T.max()
        off = np.flatnonzero(~loaded & (np.cumsum(loaded) > 0))
        if off.size:
            ends = off[np.r_[np.diff(off) > 1, True]]
            persistent.append(float(r[ends[0]]))
    slip = max(float(np.mean(persistent)), 0.0) if persistent else 0.0
    b = b - slip * A[:, -1]
    A = A[:, :-1]
    coef, _ = _scaled_nnls(A, b)
    return [max(float(c), 1e-12) for c in coef], max(slip, 1e-12)


def _load_estimate(traces: Sequence[Trace], spec: ModelSpec, defaults: dict) -> dict:
    est: dict = {}
    eps_all, T_all = [], []
    # the static law from load-unload tests; a creep test alone informs only EA (two load levels)
    static = [tr for tr in traces if tr.experiment == "load_unload"]
    if not static and spec.stiffness == "linear" and spec.hysteresis != "kawabata":
        static = list(traces)
    for tr in static:
        T = np.asarray(tr.input, float)
        eps = np.asarray(tr.measured, float) / float(tr.length_m)
        if tr.experiment == "creep":
            # the instantaneous (elastic) response: the first sample after each load change
            jump = np.r_[False, np.abs(np.diff(T)) > 0.05 * max(T.max(), 1e-300)]
            sel = np.r_[False, jump[:-1]] & ~jump
            sel |= np.r_[True, np.zeros(len(T) - 1, bool)]
        else:
            sel = T > 0.02 * max(T.max(), 1e-300)
        eps_all.append(eps[sel])
        T_all.append(T[sel])
    eps = np.concatenate(eps_all) if eps_all else np.zeros(0)
    T = np.concatenate(T_all) if T_all else np.zeros(0)
    ok = np.isfinite(eps) & np.isfinite(T)
    eps, T = eps[ok], T[ok]
    if eps.size >= 2 and np.ptp(eps) > 0:
        EA = float(np.sum(T * eps) / max(np.sum(eps ** 2), 1e-300))
        if EA > 0:
            est["EA"] = EA
        if spec.stiffness == "cubic" and eps.size >= 4:
            coef = _scaled_lstsq(np.column_stack([eps, eps ** 2, eps ** 3]), T)
            if coef[0] > 0:
                est.update(a1=float(coef[0]), a2=float(coef[1]), a3=float(coef[2]))
    iwan_traces = [tr for tr in traces if tr.experiment == "load_unload"]
    if spec.hysteresis == "iwan" and iwan_traces:
        # T = F(eps) + sum k_i q_i along each record's strain path from zero (a virgin tether)
        rows, cols, Ts, ds, starts = [], [], [], [], [0]
        for tr in iwan_traces:
            e = np.asarray(tr.measured, float) / float(tr.length_m)
            ds.append(e)
            Ts.append(np.asarray(tr.input, float))
            starts.append(starts[-1] + len(e))
        d, Tl = np.concatenate(ds), np.concatenate(Ts)
        elastic = [d, d ** 2, d ** 3] if spec.stiffness == "cubic" else [d]
        lo = [0.0] + ([-np.inf, -np.inf] if spec.stiffness == "cubic" else [])
        # a power term given (fixed, e.g. the one a discovery kept): its exponent and reference
        # strain stay, its tension is estimated with the cubic's coefficients and the bank
        power = spec.stiffness == "cubic" and float(defaults.get("pow_F", 0.0)) > 0.0
        if power:
            elastic.append(cubic_tension({"pow_F": 1.0, "pow_eps": defaults["pow_eps"], "pow_n": defaults["pow_n"]},
                                         np.nan_to_num(d)))
            lo.append(0.0)
        ok = np.isfinite(d) & np.isfinite(Tl)
        span = float(np.max(np.abs(d[ok]))) if ok.any() else 0.0
        best = None
        if span > 0:
            # one path per record: the grid's spring strains record by record
            def bank_for(f):
                slip = iwan_slip_grid(f * span)
                Q = np.vstack([iwan_spring_strains(np.nan_to_num(x), slip) for x in ds])
                return slip, Q
            from scipy.optimize import lsq_linear
            for f in (0.1, 0.2, 0.4, 0.8):
                slip, Q = bank_for(f)
                A = np.column_stack(elastic + [Q])[ok]
                scale = np.linalg.norm(A, axis=0)
                scale[scale == 0] = 1.0
                lower = np.r_[lo, np.zeros(Q.shape[1])]
                sol = lsq_linear(A / scale, Tl[ok], bounds=(lower, np.full(len(lower), np.inf)))
                coef = sol.x / scale
                rss = float(np.sum((A @ coef - Tl[ok]) ** 2))
                if best is None or rss < best[0]:
                    best = (rss, coef, slip)
        if best is not None:
            _, coef, slip = best
            ne = len(elastic)
            kb = coef[ne:]
            total = float(np.sum(kb))
            kb = np.maximum(kb, 1e-3 * total if total > 0 else 1e-6)
            est.update(_iwan_params(slip, kb))
            est["_iw_cap"] = IWAN_CAP * (abs(float(coef[0])) + float(np.sum(kb)))
            if spec.stiffness == "cubic":
                if coef[0] > 0:
                    est.update(a1=float(coef[0]), a2=float(coef[1]), a3=float(coef[2]))
                    if power:
                        est["pow_F"] = float(coef[3])
            elif coef[0] > 0:
                est["EA"] = float(coef[0])
    if spec.hysteresis == "kawabata":
        cycles = [c for c in (_kawabata_cycle(tr) for tr in traces if tr.experiment == "load_unload") if c]
        if cycles:
            LT = float(np.clip(np.mean([c["LT"] for c in cycles]), 0.06, 1.9))
            RT = float(np.clip(np.mean([c["RT"] for c in cycles]), 0.02, 0.99))
            res = float(np.clip(np.mean([c["residual"] for c in cycles]), 0.0, 0.9))
            p = 2.0 / LT - 1.0
            eps_ref = defaults.get("kaw_eps_ref", 0.02)
            F_ref = float(np.exp(np.mean([math.log(c["F_m"] * (eps_ref / c["eps_m"]) ** p) for c in cycles])))
            est.update(kaw_LT=LT, kaw_RT=RT, kaw_residual=res, kaw_F_ref=F_ref)
    if spec.creep:
        creep_traces = [tr for tr in traces if tr.experiment == "creep"]
        if creep_traces:
            if spec.stiffness == "cubic":
                inv = _cubic_inverse({n: est.get(n, defaults[n])
                                      for n in ("a1", "a2", "a3", "pow_F", "pow_eps", "pow_n")})
            else:
                EA = est.get("EA", defaults.get("EA", 3500.0))
                inv = lambda T: np.asarray(T) / EA  # noqa: E731
            taus = [defaults.get(f"creep_tau{k}", v) for k, v in ((1, 1800.0), (2, 5400.0), (3, 172800.0))]
            slip_tau = defaults.get("slip_regen_tau", 3600.0)
            J, slip = _creep_compliances(creep_traces, inv, taus, slip_tau)
            floor = 1e-3 * max(J)
            est.update(creep_J1=max(J[0], floor), creep_J2=max(J[1], floor), creep_J3=max(J[2], floor))
            # slip: what one loading uses up, at the rate that uses it within slip_tau
            est["slip_capacity0"] = max(slip, 1e-9)
            est["slip_rate"] = max(slip, 1e-9) / slip_tau
    return est


#: the power term's smoothing at zero strain (physics/elastic.c)
POWER_SMOOTHING = 1e-3


def cubic_tension(params: Mapping[str, float], eps):
    """Tension of the FMU's cubic elastic law at strain ``eps``: a1 eps + a2 eps^2 + a3 eps^3 plus,
    where pow_F > 0, the power term pow_F y (y^2 + d^2)^((pow_n - 1)/2), y = eps/pow_eps,
    d = POWER_SMOOTHING: sgn(eps) |y|^pow_n made smooth through 0 (as physics/elastic.c)."""
    e = np.asarray(eps, float)
    a1, a2, a3 = (float(params.get(n, 0.0)) for n in ("a1", "a2", "a3"))
    F = e * (a1 + e * (a2 + e * a3))
    pf = float(params.get("pow_F", 0.0))
    if pf > 0.0:
        y = e / float(params["pow_eps"])
        F = F + pf * y * (y * y + POWER_SMOOTHING ** 2) ** (0.5 * (float(params.get("pow_n", 1.0)) - 1.0))
    return F


def _cubic_inverse(params: Mapping[str, float]):
    """Strain of the cubic law (with its power term, cubic_tension) at tension T, on its rising
    branch: bisection on [0, eps_rise], eps_rise the cubic's first root of dF/deps (the power
    term's stiffness is never negative: the law rises at least that far)."""
    a1, a2, a3 = (float(params.get(n, 0.0)) for n in ("a1", "a2", "a3"))
    roots = np.roots([3 * a3, 2 * a2, a1]) if a3 != 0 else np.array([-a1 / (2 * a2)] if a2 else [])
    rising = [float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
    hi0 = min(rising) if rising else 1.0

    def inv(T):
        T = np.asarray(T, float)
        lo = np.zeros_like(T)
        hi = np.full_like(T, hi0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            below = cubic_tension(params, mid) < T
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        return 0.5 * (lo + hi)
    return inv


#: Trace fields that say where a trace was read from or describe it, not what it holds
_NOT_DATA = ("stem", "csv_path", "json_path", "description")


def _trace_digest(trace: Trace) -> bytes:
    """A digest of everything a trace holds (every field's value, arrays by their bytes), not of
    where it was read from."""
    h = hashlib.blake2b(digest_size=20)
    for f in dataclasses.fields(trace):
        if f.name in _NOT_DATA:
            continue
        v = getattr(trace, f.name)
        h.update(f.name.encode() + b"=")
        if isinstance(v, np.ndarray):
            h.update(str(v.dtype).encode() + np.ascontiguousarray(v).tobytes())
        elif isinstance(v, dict):
            h.update(json.dumps(v, sort_keys=True, default=repr).encode())
        else:
            h.update(repr(v).encode())
        h.update(b"|")
    return h.digest()


#: the start values last computed (key: the traces' digests, the model, the fixed values): a
#: discovery asks for the same record's and model's starts again and again (a free vibration with
#: hysteresis: 46 estimates, 21 distinct, 12 s of Bouc-Wen searches repeated)
_ESTIMATES: dict = {}
_ESTIMATES_KEPT = 32
_ESTIMATES_LOCK = threading.Lock()


def _remembered(estimate: Callable[..., dict]) -> Callable[..., dict]:
    """initial_estimate computed once per (traces' data, model, fixed values); callers get a copy."""
    @functools.wraps(estimate)
    def wrapper(traces, spec, fixed=None, **options):
        traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
        if options:
            return estimate(traces, spec, fixed, **options)
        key = (tuple(_trace_digest(t) for t in traces), repr(_spec(spec)),
               tuple(sorted((k, float(v)) for k, v in (fixed or {}).items())))
        with _ESTIMATES_LOCK:
            hit = _ESTIMATES.get(key)
        if hit is None:
            hit = estimate(traces, spec, fixed)
            with _ESTIMATES_LOCK:
                _ESTIMATES[key] = hit
                while len(_ESTIMATES) > _ESTIMATES_KEPT:
                    _ESTIMATES.pop(next(iter(_ESTIMATES)))
        return copy.deepcopy(hit)
    return wrapper


@_remembered
def initial_estimate(traces: Sequence[Trace], spec, fixed: Mapping[str, float] | None = None) -> dict:
    """Start values for every parameter of ``spec`` from the data (see the module docstring);
    parameters the data cannot inform keep the FMU's start values (or ``fixed``, values known
    otherwise, e.g. the elastic law under a creep test). Keys starting with '_' are scales for the
    fit (stiffness, amplitude, frequency), not parameters."""
    spec = _spec(spec)
    traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
    defaults = {**_fmu_defaults(), **{k: float(v) for k, v in (fixed or {}).items()}}
    est = {n: defaults[n] for n in spec.parameters if n in defaults}
    load = [t for t in traces if t.rig == "load"]
    payload = [t for t in traces if t.rig == "payload"]
    if load:
        est.update(_load_estimate(load, spec, defaults))
    if payload:
        per = [_payload_estimate(t, spec) for t in payload]
        keys = set().union(*per)
        for k in keys:
            vals = [p[k] for p in per if k in p and np.all(np.isfinite(p[k]))]
            if not vals:
                continue
            if k.startswith("_k_taylor"):
                continue
            if load and k in ("EA", "a1", "a2", "a3"):
                continue                      # the static law from the load tests wins
            est[k] = float(np.mean(vals))
        if spec.hysteresis == "kawabata" and not load:
            # payload only: the virgin curve's tangent at the balance gives the scale of F_ref
            k_lin = float(np.mean([p["_k_lin"] for p in per]))
            tr = payload[0]
            L0, w = float(tr.length_m), idn.payload_masses(tr)[0] * float(tr.gravity_m_s2)
            LT = est.get("kaw_LT", defaults["kaw_LT"])
            pexp = 2.0 / LT - 1.0
            if w > 0 and k_lin > 0:
                eps_b = pexp * w / (k_lin * L0)           # F = C eps^p: dF/deps = p F / eps at the balance
                est["kaw_F_ref"] = w * (defaults["kaw_eps_ref"] / eps_b) ** pexp
    return {k: v for k, v in est.items() if k in spec.parameters or k.startswith("_")}


# ---------------------------------------------------------------------------------------------
# experiments
@dataclass
class _Exp:
    trace: Trace
    exp: idn.Experiment
    periods: int          # K (periodic records are fitted as their mean period)
    noise: float


def _experiment(trace: Trace, spec: ModelSpec, settings_extra: Mapping[str, float]) -> _Exp:
    sp = spec.for_experiment(trace.experiment)
    settings = {k: float(v) for k, v in sp.switches.items()}
    settings.update({k: float(v) for k, v in settings_extra.items()})
    settings["L0"] = float(trace.length_m)
    P = int(trace.periodic_samples or 0)
    if sp.rig == "payload":
        settings.update(m=float(trace.payload_mass_kg), g=float(trace.gravity_m_s2),
                        x0=0.0 if P else float(trace.initial_displacement_m),
                        v0=0.0 if P else float(trace.initial_velocity_m_s),
                        line_density=float(trace.line_density_kg_m))
        # nuisance values given (fixed, or held between stages) win over the trace's metadata
        settings.update({k: float(v) for k, v in settings_extra.items() if k in NZ.NUISANCE})
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    kind = {None: idn.INPUT_NONE, "force": idn.INPUT_FORCE, "load": idn.INPUT_LOAD}[trace.input_column]
    inp = der = None
    if P:
        K = len(t) // P
        Tp = record_period(t, P)
        tt = t[:P]
        meas = y.reshape(K, P).mean(axis=0)
        if kind != idn.INPUT_NONE:
            inp, der = _input_pieces(tt, np.asarray(trace.input, float)[:P], Tp, input_interpolation(trace))
        # the engine closes a period with (t[P-1] - t[0]) P / (P - 1): exact for uniform sampling
        uniform = abs(float(t[P - 1] - t[0]) * P / (P - 1) - Tp) <= 1e-9 * Tp
        if not uniform:
            tt = np.concatenate([tt, tt + Tp])
            meas = np.tile(meas, 2)
            if inp is not None:
                inp, der = np.tile(inp, 2), np.tile(der, (2, 1))
            e = idn.Experiment(tt, settings=settings, input_kind=kind, input=inp, input_der=der,
                               output=trace.measured_column, measured=meas, periodic_samples=P)
            return _Exp(trace, e, K / 2.0, noise_level(trace))
        e = idn.Experiment(tt, settings=settings, input_kind=kind, input=inp, input_der=der,
                           output=trace.measured_column, measured=meas, periodic_samples=P)
        return _Exp(trace, e, K, noise_level(trace))
    if kind != idn.INPUT_NONE:
        vals, ders = _input_pieces(t, np.asarray(trace.input, float), None, input_interpolation(trace))
        inp = np.append(vals, float(trace.input[-1]))
        der = np.vstack([ders, np.zeros((1, 3))])
    e = idn.Experiment(t, settings=settings, input_kind=kind, input=inp, input_der=der,
                       output=trace.measured_column, measured=y)
    return _Exp(trace, e, 1, noise_level(trace))


def _predict(x: _Exp, params: Mapping[str, float]) -> np.ndarray:
    y = idn.simulate(x.exp, params)
    P = int(x.trace.periodic_samples or 0)
    if P:
        return np.tile(y[:P], len(x.trace.time) // P)
    return y


# ---------------------------------------------------------------------------------------------
def _check_names(names: Iterable[str], spec: ModelSpec, what: str) -> list[str]:
    known = set(idn.parameter_names(kind=0))
    out = []
    for n in names:
        if n in NZ.NUISANCE:
            if n in out:
                raise FitError(f"{what} '{n}' given twice")
            out.append(n)
            continue
        if n in SWITCHES:
            raise FitError(f"{what} '{n}': a structural switch, chosen by the model string, not a parameter")
        if n in TRACE_PARAMETERS:
            raise FitError(f"{what} '{n}': set by each trace's metadata (L0 and g are not fitted; m, x0, v0 are "
                           "nuisance parameters, docs/nuisance.md)")
        if n not in known:
            raise FitError(f"{what} '{n}': not a parameter of the FMU; the model '{spec.canonical}' has "
                           f"{', '.join(spec.parameters)}")
        if n not in spec.parameters:
            raise FitError(f"{what} '{n}': not used by the model '{spec.canonical}'; its parameters are "
                           f"{', '.join(spec.parameters)}")
        if n in out:
            raise FitError(f"{what} '{n}' given twice")
        out.append(n)
    return out


#: physical ranges a fit keeps to beyond the FMU's own limits: a creep cell of compliance 1e40 1/N
#: and time constant 1e160 s is a limit of the law, not a tether (fits of long creep records
#: wander there when two cells trade off)
FIT_RANGES = {"creep_tau1": (1.0, 1e7), "creep_tau2": (1.0, 1e7), "creep_tau3": (1.0, 1e7),
              "creep_J1": (0.0, 1e-3), "creep_J2": (0.0, 1e-3), "creep_J3": (0.0, 1e-3),
              "slip_regen_tau": (1.0, 1e7)}


def _bounds_and_start(name: str, start: float, fmu_bounds: dict, scales: dict) -> tuple[float, float, float, str]:
    lo, hi = fmu_bounds.get(name, (None, None))
    lo = -math.inf if lo is None else float(lo)
    hi = math.inf if hi is None else float(hi)
    if name in FIT_RANGES:
        lo, hi = max(lo, FIT_RANGES[name][0]), min(hi, FIT_RANGES[name][1])
    if name in IWAN_K and scales.get("_iw_cap"):
        # an element the estimate left near zero has a tiny log-sensitivity: a trial step may
        # throw it far out, where the tether turns stiff and the simulation crawls (a free
        # vibration fit spent 25 s on one iteration so)
        hi = min(hi, float(scales["_iw_cap"]))
    if name in _LOG:
        lo = max(lo, 0.0)
        if not start > 0:
            start = _positive_floor(name, scales)
        return lo, hi, min(max(start, lo), hi), "log"
    s = min(max(start, lo), hi)
    return lo, hi, s, "linear"


def _positive_floor(name: str, scales: dict) -> float:
    """A small positive start for a log-scaled parameter the estimate put at or below zero."""
    k = scales.get("_k_lin")
    m = scales.get("_m")
    if name == "c0" and k and m:
        return 2 * 0.002 * math.sqrt(k * m)       # damping ratio 0.2 %
    if name == "bw_A" and k:
        return 0.05 * k
    d = idn.parameter_start(name)
    return d if d > 0 else 1e-6


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
    spec = _spec(model)
    traces = [t if isinstance(t, Trace) else read_trace(t) for t in traces]
    if not traces:
        raise FitError("no traces to fit")
    start = dict(start or {})
    fixed = dict(fixed or {})
    _check_names(fixed, spec, "fixed parameter")
    _check_names(start, spec, "start value for")
    if free is None:
        free_names: list[str] = []
        for tr in traces:
            for n in default_free_parameters(spec, tr.experiment):
                if n not in free_names and n not in fixed:
                    free_names.append(n)
    else:
        free_names = _check_names(free, spec, "free parameter")
        both = [n for n in free_names if n in fixed]
        if both:
            raise FitError(f"parameter '{both[0]}' is both free and fixed")
    if not free_names:
        raise FitError(f"nothing to fit: every parameter of '{spec.canonical}' is fixed")
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
    defaults = _fmu_defaults()
    fmu_bounds = _fmu_bounds()
    # every parameter of the model: fixed ones at `fixed` or the FMU's start value; the Iwan slip
    # strains at the grid the estimate chose (its element stiffnesses are fitted on that grid)
    grid = {n: est[n] for n in IWAN_EPS if n in est}
    model_values = {n: float(fixed.get(n, grid.get(n, defaults[n]))) for n in spec.parameters if n in defaults}
    x0 = {}
    box = {}
    scaling = {}
    for n in free_names:
        if n in NZ.NUISANCE:
            lo, hi, s, sc = NZ.nuisance_box(traces[0], n, mass_band)
            if n in start:
                if not lo <= float(start[n]) <= hi:
                    raise FitError(f"start value for '{n}': {start[n]!r} is outside its range [{lo:g}, {hi:g}]")
                s = float(start[n])
            x0[n], box[n], scaling[n] = s, (lo, hi), sc
            continue
        s = float(start[n]) if n in start else float(est.get(n, defaults[n]))
        lo, hi, s, sc = _bounds_and_start(n, s, fmu_bounds, scales)
        if n in start and s != float(start[n]):
            raise FitError(f"start value for '{n}': {start[n]!r} is outside the FMU's range [{lo:g}, {hi:g}]")
        x0[n], box[n], scaling[n] = s, (lo, hi), sc
    held = {n: v for n, v in model_values.items() if n not in free_names}
    held.update(fixed_nuisance)

    # experiments and weights (inverse noise, normalized; periodic means: sqrt(K))
    exps = [_experiment(tr, spec, held) for tr in traces]
    noises = np.array([max(x.noise, 1e-300) for x in exps])
    ref = float(np.exp(np.mean(np.log(noises))))
    for x, s in zip(exps, noises):
        x.exp.weight = math.sqrt(x.periods) * (ref / s if len(exps) > 1 else 1.0)
    n_eff = sum(len(x.exp.time) * x.exp.weight ** 2 for x in exps)

    # engine options: free vibration uses horizon stages and a stride that keeps the Hermite
    # interpolation between solver calls far below the noise (omega h <= 0.1)
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

    # stages: the elastic law and viscous damping (with the nuisance parameters, which a wrong mass
    # or an offset would otherwise push into the law), then everything
    base = [n for n in free_names if n in _BASE]
    nuisance_free = [n for n in free_names if n in NZ.NUISANCE]
    stages = []
    if base and len(base) + len(nuisance_free) < len(free_names):
        stages.append(("elastic law + viscous damping" + (" + nuisance" if nuisance_free else ""),
                       base + nuisance_free))
    stages.append(("all free parameters", list(free_names)))

    current = dict(x0)
    evaluations = 0
    stage_log = []
    r = None
    for si, (sname, names) in enumerate(stages):
        if progress:
            progress(FitProgress(sname, si, len(stages), -1, float("nan"), 0, _time.perf_counter() - t_begin,
                                 free=list(names)))
        hold = {n: current[n] for n in free_names if n not in names}
        for x in exps:
            x.exp.settings = {**x.exp.settings, **hold}
        fr = {}
        for n in names:
            lo, hi = box[n]
            fr[n] = (lo, hi, min(max(current[n], lo), hi))

        def cb(st, hstage, n_h, it, cost, ev, _si=si, _sname=sname, _names=names):
            if progress:
                # a horizon stage fits the first 1/2^(n_h - 1 - hstage) of each non-periodic record
                frac = 2.0 ** -(n_h - 1 - hstage)
                n_h_eff = sum((len(x.exp.time) if x.exp.periodic_samples else
                               max(min(len(x.exp.time), len(_names) + 2), math.ceil(len(x.exp.time) * frac)))
                              * x.exp.weight ** 2 for x in exps)
                progress(FitProgress(_sname, _si, len(stages), it, math.sqrt(2 * cost / n_h_eff), int(ev),
                                     _time.perf_counter() - t_begin, free=list(_names), start=st,
                                     horizon=f"{hstage + 1}/{n_h}" if n_h > 1 else ""))
            return 0

        o = dict(opts)
        if si < len(stages) - 1:
            # an intermediate stage only brings the start near the optimum: a looser stop
            o.setdefault("max_iterations", 20)
            o["ftol"] = max(float(o.get("ftol", 1e-10)), 1e-4)
            o.setdefault("central_differences", idn.FORWARD)
        if si == len(stages) - 1 and n_starts > 1:
            o["n_starts"] = int(n_starts)
            o.setdefault("start_spread", 0.3)
        t_stage = _time.perf_counter()
        r = idn.fit([x.exp for x in exps], fr, scaling={n: scaling[n] for n in names}, progress=cb, **o)
        evaluations += r.evaluations
        # inside the box it was given: a value the engine's scaling maps back from the bound can
        # round past it (creep_tau1 = 1.0000000000000006e7 against 1e7), and the next fit started
        # from it would be refused
        current.update({n: min(max(v, box[n][0]), box[n][1]) for n, v in r.as_dict().items()})
        stage_log.append({"stage": sname, "free": list(names), "rms": math.sqrt(2 * r.cost / n_eff),
                          "evaluations": r.evaluations, "iterations": r.iterations,
                          "seconds": _time.perf_counter() - t_stage, "message": r.message})
    assert r is not None
    for x in exps:   # leave the experiments as built (held values of the first stage undone)
        x.exp.settings = {**x.exp.settings, **{n: current[n] for n in free_names}}

    def rms_of(values: Mapping[str, float]):
        ps = dict(model_values)
        ps.update(fixed_nuisance)
        ps.update({n: float(values[n]) for n in free_names})
        pred = [_predict(x, ps) for x in exps]
        tot = float(np.sqrt(sum(np.sum((p - np.asarray(x.trace.measured, float)) ** 2) for p, x in zip(pred, exps))
                            / sum(len(x.trace.time) for x in exps)))
        return {n: v for n, v in ps.items() if n not in NZ.NUISANCE}, pred, tot

    params, predictions, total = rms_of(current)
    message = r.message
    # a fit never hands back more error than its start: the stages (the elastic law alone first; in
    # free vibration the record's first quarter, then half) can lead a start that is already at an
    # optimum of the whole record elsewhere (a discovery's final model refitted from its own
    # values: 7.47 -> 15.2 x noise). Then the start is the result.
    if all(n in start for n in free_names):
        params0, predictions0, total0 = rms_of(x0)
        if math.isfinite(total0) and not total <= total0:
            message = (f"the fit ended with more error than its start (RMS {total0:.6g} -> {total:.6g}): the "
                       f"start is returned ({r.message})")
            current.update(x0)
            params, predictions, total = params0, predictions0, total0
    per = [float(np.sqrt(np.mean((p - np.asarray(x.trace.measured, float)) ** 2))) for p, x in zip(predictions, exps)]
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
    max_rel = float(engine_options.get("max_rel_std", 0.5))
    # (not the nuisance parameters: an offset or initial state near zero is determined when its
    # interval is narrow, whatever its size)
    loose = [n for n in free_names if scaling[n] == "linear" and n not in r.unidentifiable
             and n not in NZ.NUISANCE and not std[n] <= max_rel * abs(values[n])]
    nuisance = {**fixed_nuisance, **{n: values[n] for n in nuisance_free}}
    unid = [n for n in free_names if n in r.unidentifiable or n in loose]
    return FitResult(
        model=spec.canonical, parameters=params, free=list(free_names), values=values, std_error=std, ci95=ci,
        correlation=corr, unidentifiable=unid,
        identifiability_report=_identifiability_text(r, free_names, unid, loose, values, std, max_rel),
        rms=total, rms_per_trace=per,
        predictions=predictions, evaluations=evaluations, seconds=_time.perf_counter() - t_begin,
        status=int(r.status), message=message, traces=[str(x.trace.stem.name) for x in exps],
        noise=[float(x.noise) for x in exps], start=dict(x0), stages=stage_log,
        condition=float(r.condition), singular_values=[float(v) for v in r.singular_values],
        nuisance=nuisance,
        nuisance_moved=NZ.moved_statement({n: values[n] for n in nuisance_free}, x0, ci))


def _identifiability_text(r: idn.FitResult, names: Sequence[str], unid: Sequence[str], loose: Sequence[str],
                          values: Mapping[str, float], std: Mapping[str, float], max_rel: float) -> str:
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


def write_fit_params(path: str | Path, result: FitResult) -> Path:
    """The canonical parameter file (``tether simulate/validate --params`` read it) with the fit's
    statistics: {"model", "parameters", "intervals", "std_error", "correlation", "unidentifiable",
    "rms"}."""
    extra = {
        "intervals": {n: [float(a), float(b)] for n, (a, b) in result.ci95.items()},
        "std_error": {n: float(v) for n, v in result.std_error.items()},
        "correlation": {"parameters": list(result.free),
                        "matrix": [[float(v) for v in row] for row in np.asarray(result.correlation)]},
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


# `tether.fit(...)` calls tether.api.fit (docs/api.md); the module stays a module
import sys as _sys  # noqa: E402

from . import _CallableModule  # noqa: E402

_sys.modules[__name__].__class__ = _CallableModule
