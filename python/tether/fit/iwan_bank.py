"""The Iwan bank's start from the data: slip strains on a grid, the spring strains of its Jenkins
elements along the measured strain path, and the element stiffnesses by non-negative least squares
beside the other linear terms of the payload's equation error or the load rig's static law."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..models import IWAN_EPS, IWAN_EPS_FIT, IWAN_K, ModelSpec
from ..traces import Trace
from .elastic import cubic_tension

#: the Iwan bank of a fit: slip strains on a geometric grid, each IWAN_RATIO of the next, the
#: largest chosen by the equation error among IWAN_SPANS multiples of half the record's strain
#: range; the element stiffnesses then enter the equations linearly. An element that never slips
#: is a spring like the elastic law's: the largest stays within the range (with one at twice it,
#: a forced record with slack split its stiffness between the two, and the balance, where the
#: elastic law alone carries the weight, moved three times too low)
IWAN_RATIO = 0.55
IWAN_SPANS = (0.25, 0.5, 1.0)
#: the load rig's grids: these multiples of the largest strain of the records
IWAN_LOAD_SPANS = (0.1, 0.2, 0.4, 0.8)
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


def iwan_params(slip: Sequence[float], k: np.ndarray) -> dict:
    """The bank's parameters: element stiffnesses k and slip strains, by the FMU's names."""
    return {**{n: float(v) for n, v in zip(IWAN_K, k)}, **{n: float(v) for n, v in zip(IWAN_EPS, slip)}}


def _bounded_lstsq(A: np.ndarray, b: np.ndarray, lower: np.ndarray) -> tuple[np.ndarray, float]:
    """min |A c - b| over c >= lower, A's columns scaled to unit norm; (c, the residual sum of squares)."""
    from scipy.optimize import lsq_linear

    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    sol = lsq_linear(A / scale, b, bounds=(lower, np.full(len(lower), np.inf)))
    coef = sol.x / scale
    return coef, float(np.sum((A @ coef - b) ** 2))


def _floored(k: np.ndarray) -> np.ndarray:
    """Element stiffnesses kept above a thousandth of their sum: at zero, a log-scaled stiffness has no scale."""
    total = float(np.sum(k))
    return np.maximum(k, 1e-3 * total if total > 0 else 1e-6)


def payload_iwan_bank(A_rest: np.ndarray, lo_rest: Sequence[float], b: np.ndarray, d: np.ndarray,
                      rows: np.ndarray, span: float,
                      periodic: bool) -> tuple[np.ndarray, list[float], np.ndarray, np.ndarray] | None:
    """Equation error of the Iwan bank beside the other linear terms (columns A_rest, lower bounds
    lo_rest): for each grid of IWAN_SPANS, min |A_rest c + Q k - b| over the rows with k >= 0.
    Returns (c, slip strains, k, Q @ k over all samples) of the best grid, or None."""
    best = None
    for f in IWAN_SPANS:
        slip = iwan_slip_grid(f * span)
        Q = iwan_spring_strains(d, slip, periodic)
        A = np.column_stack([A_rest, Q])[rows]
        lo = np.r_[np.asarray(lo_rest, float), np.zeros(Q.shape[1])]
        try:
            coef, rss = _bounded_lstsq(A, b[rows], lo)
        except (ValueError, np.linalg.LinAlgError):
            continue
        if best is None or rss < best[0]:
            nr = A_rest.shape[1]
            best = (rss, coef[:nr], slip, coef[nr:], Q @ coef[nr:])
    if best is None:
        return None
    _, c, slip, k, h = best
    return c, slip, _floored(k), h


def load_iwan_estimate(traces: Sequence[Trace], spec: ModelSpec, defaults: Mapping[str, float]) -> dict:
    """The bank's start from the load-unload records among ``traces``, with the elastic law's
    (``EA``, or the cubic's a1..a3 and a given power term's ``pow_F``) where its first coefficient
    comes out positive: T = F(eps) + sum k_i q_i along each record's strain path from zero (a
    virgin tether). {} without such records or strain."""
    records = [tr for tr in traces if tr.experiment == "load_unload"]
    if not records:
        return {}
    ds = [np.asarray(tr.measured, float) / float(tr.length_m) for tr in records]
    d = np.concatenate(ds)
    T = np.concatenate([np.asarray(tr.input, float) for tr in records])
    cubic = spec.stiffness == "cubic"
    elastic = [d, d ** 2, d ** 3] if cubic else [d]
    lo = [0.0] + ([-np.inf, -np.inf] if cubic else [])
    # a power term given (fixed, e.g. the one a discovery kept): its exponent and reference
    # strain stay, its tension is estimated with the cubic's coefficients and the bank
    power = cubic and float(defaults.get("pow_F", 0.0)) > 0.0
    if power:
        elastic.append(cubic_tension({"pow_F": 1.0, "pow_eps": defaults["pow_eps"], "pow_n": defaults["pow_n"]},
                                     np.nan_to_num(d)))
        lo.append(0.0)
    ok = np.isfinite(d) & np.isfinite(T)
    span = float(np.max(np.abs(d[ok]))) if ok.any() else 0.0
    if not span > 0:
        return {}
    coef, slip = _best_load_grid(np.column_stack(elastic), lo, ds, T, ok, span)
    kb = _floored(coef[len(elastic):])
    est = {**iwan_params(slip, kb), "_iw_cap": IWAN_CAP * (abs(float(coef[0])) + float(np.sum(kb)))}
    if cubic:
        if coef[0] > 0:
            est.update(a1=float(coef[0]), a2=float(coef[1]), a3=float(coef[2]))
            if power:
                est["pow_F"] = float(coef[3])
    elif coef[0] > 0:
        est["EA"] = float(coef[0])
    return est


def _best_load_grid(elastic: np.ndarray, lo: Sequence[float], ds: Sequence[np.ndarray], T: np.ndarray,
                    ok: np.ndarray, span: float) -> tuple[np.ndarray, list[float]]:
    """The coefficients (elastic columns', then the bank's) and slip strains of the grid of
    IWAN_LOAD_SPANS that fits the tension T best; the spring strains along each record's path."""
    best = None
    for f in IWAN_LOAD_SPANS:
        slip = iwan_slip_grid(f * span)
        Q = np.vstack([iwan_spring_strains(np.nan_to_num(x), slip) for x in ds])
        A = np.column_stack([elastic, Q])[ok]
        coef, rss = _bounded_lstsq(A, T[ok], np.r_[lo, np.zeros(Q.shape[1])])
        if best is None or rss < best[0]:
            best = (rss, coef, slip)
    return best[1], best[2]
