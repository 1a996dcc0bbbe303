"""The start of a creep test's creep terms: the Kelvin cells' compliances and the slip per loading
by non-negative least squares on the strain the elastic law leaves unexplained."""

from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np

from ..models import ModelSpec
from ..traces import Trace
from .elastic import elastic_inverse
from .equation_error import scaled_nnls


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
    coef, _ = scaled_nnls(A, b)
    return [max(float(c), 1e-12) for c in coef], max(slip, 1e-12)


def creep_estimate(traces: Sequence[Trace], spec: ModelSpec, values: Mapping[str, float]) -> dict:
    """creep_J1..3, slip_capacity0 and slip_rate (primary creep: primary_J, primary_tau, primary_n in
    the slip's place, primary_estimate) from the creep tests among ``traces``, the elastic
    law and the time constants at ``values`` (the estimates so far over the FMU's defaults); {}
    without creep tests."""
    creep_traces = [tr for tr in traces if tr.experiment == "creep"]
    if not creep_traces:
        return {}
    inv = elastic_inverse(spec.stiffness, values)
    taus = [values.get(f"creep_tau{k}", v) for k, v in ((1, 1800.0), (2, 5400.0), (3, 172800.0))]
    if spec.creep_law == "primary":
        est = primary_estimate(creep_traces, inv, taus)
        dc = est.pop("_compliance_change", 0.0)
        EA = values.get("EA")
        if spec.stiffness == "linear" and EA and 1.0 / EA + dc > 0:
            est["EA"] = 1.0 / (1.0 / EA + dc)
        return est
    slip_tau = values.get("slip_regen_tau", 3600.0)
    J, slip = _creep_compliances(creep_traces, inv, taus, slip_tau)
    floor = 1e-3 * max(J)
    # slip: what one loading uses up, at the rate that uses it within slip_tau
    return {"creep_J1": max(J[0], floor), "creep_J2": max(J[1], floor), "creep_J3": max(J[2], floor),
            "slip_capacity0": max(slip, 1e-9), "slip_rate": max(slip, 1e-9) / slip_tau}


#: the primary creep's start: onset times log-spaced from the sample interval to ten times the
#: longest hold, and these exponents of time (0: logarithmic)
PRIMARY_TAU_GRID, PRIMARY_N_GRID = 13, (0.0, 0.15, 0.3, 0.5)


def primary_response(t: np.ndarray, T: np.ndarray, tau: float, n: float) -> np.ndarray:
    """Primary creep strain of unit compliance (physics/creep.c, creep_law = primary) under the
    tension ``T`` sampled at ``t``: over each interval the tension at the mean of its ends, the law
    advanced exactly there from the time equivalent to the strain reached (strain hardening). The
    strain of compliance J is J times this (the law is homogeneous in J)."""
    w = np.zeros_like(T)
    for i in range(1, len(t)):
        h, Ti = t[i] - t[i - 1], 0.5 * (T[i] + T[i - 1])
        if not Ti > 0:
            w[i] = w[i - 1]
            continue
        x = w[i - 1] / Ti
        if n > 0:
            te = tau * ((1 + n * x) ** (1 / n) - 1)
            w[i] = Ti / n * ((1 + (te + h) / tau) ** n - 1)
        else:
            te = tau * math.expm1(min(x, 700.0))
            w[i] = Ti * math.log1p((te + h) / tau)
    return w


def primary_estimate(traces: Sequence[Trace], elastic: Callable[[np.ndarray], np.ndarray],
                     taus: Sequence[float]) -> dict:
    """primary_J, primary_tau, primary_n and the Kelvin compliances creep_J1..3 (time constants
    ``taus``) by non-negative least squares on the strain the elastic law leaves unexplained, for
    each onset time and exponent of a grid (PRIMARY_TAU_GRID x PRIMARY_N_GRID), the best kept, and
    the change of the elastic compliance beside them ('_compliance_change', 1/N); {} without a
    loaded sample."""
    ts = [np.asarray(tr.time, float) for tr in traces]
    Ts = [np.asarray(tr.input, float) for tr in traces]
    if not any(T.max() > 0 for T in Ts):
        return {}
    b = np.concatenate([np.asarray(tr.measured, float) / float(tr.length_m) - elastic(T) for tr, T in zip(traces, Ts)])
    kelvin = np.vstack([np.column_stack([kelvin_response(t, T, tau) for tau in taus]) for t, T in zip(ts, Ts)])
    dt = min(float(np.median(np.diff(t))) for t in ts)
    span = max(float(t[-1] - t[0]) for t in ts)
    # the elastic law's compliance corrected beside them (c T, c of either sign): its estimate from
    # the first sample after each load change holds the primary creep of that first interval
    T_all = np.concatenate(Ts)
    best = None
    for tau in np.geomspace(max(dt, 1.0), 10.0 * span, PRIMARY_TAU_GRID):
        for n in PRIMARY_N_GRID:
            w = np.concatenate([primary_response(t, T, float(tau), n) for t, T in zip(ts, Ts)])
            coef, res = scaled_nnls(np.column_stack([w, kelvin, T_all, -T_all]), b)
            if np.all(np.isfinite(coef)) and (best is None or res < best[0]):
                best = (res, float(tau), n, coef)
    if best is None or not best[3][0] > 0:
        return {}
    _, tau, n, coef = best
    J = [max(float(c), 1e-3 * float(coef[0])) for c in coef[1:1 + len(taus)]]
    return {"primary_J": float(coef[0]), "primary_tau": tau, "primary_n": n,
            **{f"creep_J{k + 1}": j for k, j in enumerate(J)}, "_compliance_change": float(coef[-2] - coef[-1])}
