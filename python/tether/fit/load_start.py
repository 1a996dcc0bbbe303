"""The start of load-rig records (load-unload, creep tests): the static law inverted (a linear or
cubic fit of tension against strain), the Iwan bank beside it, Kawabata's LT, RT and residual strain
from a cycle's energies, and the creep terms (creep_start)."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..models import ModelSpec
from ..traces import Trace
from .creep_start import creep_estimate
from .elastic import bilinear_from_curve, bilinear_near_linear, exponential_from_curve
from .equation_error import scaled_lstsq
from .iwan_bank import load_iwan_estimate


def load_estimate(traces: Sequence[Trace], spec: ModelSpec, defaults: dict) -> dict:
    """Start values from the load-rig ``traces`` (``defaults``: the FMU's start values and the
    values given as fixed)."""
    est = _static_law(traces, spec)
    if spec.hysteresis == "iwan":
        est.update(load_iwan_estimate(traces, spec, defaults))
    if spec.hysteresis == "kawabata":
        est.update(_kawabata_estimate(traces, defaults))
    if spec.creep:
        est.update(creep_estimate(traces, spec, {**defaults, **est}))
    return est


#: a creep test whose load ramps over at least this many samples (a ramp sampled on its way, not a
#: step between two samples) traces the elastic curve there as a load test does
CURVE_SAMPLES = 8

#: the load steps between two samples where it changes by more than this share of its largest
#: value; a smaller change, above the digits a record keeps, is a ramp sampled on its way
STEP_SHARE = 0.05


def _load_moves(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of the load ``T``: did it step there from the sample before, did a ramp reach it
    (STEP_SHARE)."""
    change = np.r_[0.0, np.abs(np.diff(T))]
    top = max(float(np.max(np.abs(T))), 1e-300)
    return change > STEP_SHARE * top, (change > 1e-6 * top) & (change <= STEP_SHARE * top)


def _instantaneous(T: np.ndarray) -> np.ndarray:
    """The samples of a creep test where its elongation is the elastic law's (creep has had seconds
    at most): the first, the first after each step of the load, and those its ramps reach."""
    steps, ramps = _load_moves(T)
    sel = np.r_[False, steps[:-1]] & ~steps
    sel[0] = True
    return sel | ramps


def _static_law(traces: Sequence[Trace], spec: ModelSpec) -> dict:
    """EA (and the cubic's a1..a3, the exponential's exp_F, exp_eps or the bilinear's toe) by least squares of tension
    against strain over the load-unload tests' loaded samples and the creep tests' instantaneous
    ones (_instantaneous); a creep test whose load changes in steps informs only EA (two load
    levels), one whose load ramps over CURVE_SAMPLES or more samples the nonlinear laws too."""
    est: dict = {}
    eps_all, T_all = [], []
    static = [tr for tr in traces if tr.experiment == "load_unload"
              or (tr.experiment == "creep" and np.count_nonzero(_load_moves(np.asarray(tr.input, float))[1])
                  >= CURVE_SAMPLES)]
    if not static and spec.stiffness == "linear" and spec.hysteresis != "kawabata":
        static = list(traces)
    for tr in static:
        T = np.asarray(tr.input, float)
        eps = np.asarray(tr.measured, float) / float(tr.length_m)
        if tr.experiment == "creep":
            sel = _instantaneous(T)
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
            coef = scaled_lstsq(np.column_stack([eps, eps ** 2, eps ** 3]), T)
            if coef[0] > 0:
                est.update(a1=float(coef[0]), a2=float(coef[1]), a3=float(coef[2]))
        if spec.stiffness == "exponential" and static:
            est.update(exponential_from_curve(eps, T) or {})
        if spec.stiffness == "bilinear" and static:
            est.update(bilinear_from_curve(eps, T) or bilinear_near_linear(est.get("EA"), float(np.max(eps))))
    return est


def _kawabata_estimate(traces: Sequence[Trace], defaults: dict) -> dict:
    """kaw_LT, kaw_RT, kaw_residual and kaw_F_ref from the load-unload tests' cycles (kept within
    the law's ranges); {} without a usable cycle."""
    cycles = [c for c in (_kawabata_cycle(tr) for tr in traces if tr.experiment == "load_unload") if c]
    if not cycles:
        return {}
    LT = float(np.clip(np.mean([c["LT"] for c in cycles]), 0.06, 1.9))
    RT = float(np.clip(np.mean([c["RT"] for c in cycles]), 0.02, 0.99))
    res = float(np.clip(np.mean([c["residual"] for c in cycles]), 0.0, 0.9))
    p = 2.0 / LT - 1.0
    eps_ref = defaults.get("kaw_eps_ref", 0.02)
    F_ref = float(np.exp(np.mean([math.log(c["F_m"] * (eps_ref / c["eps_m"]) ** p) for c in cycles])))
    return {"kaw_LT": LT, "kaw_RT": RT, "kaw_residual": res, "kaw_F_ref": F_ref}


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
