"""The elastic laws as the fit's starts use them: the cubic (with its power term) and the
exponential law, the tension at a strain, the strain at a tension, and the coefficients from the
Taylor coefficients about a balance or from a load-elongation curve."""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

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


def cubic_inverse(params: Mapping[str, float]):
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


def cubic_from_taylor(k1: float, k2: float, k3: float, L0: float, weight: float) -> dict | None:
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


def exponential_tension(params: Mapping[str, float], eps):
    """Tension of the FMU's exponential elastic law at strain ``eps``: exp_F (exp(eps/exp_eps) - 1)
    (physics/elastic.c)."""
    return float(params["exp_F"]) * np.expm1(np.asarray(eps, float) / float(params["exp_eps"]))


def elastic_inverse(stiffness: str, params: Mapping[str, float]):
    """The strain at tension T of the elastic law ``stiffness`` (linear, cubic or exponential) with
    ``params``, as a function of T (on the law's rising branch)."""
    if stiffness == "cubic":
        return cubic_inverse(params)
    if stiffness == "exponential":
        F, e = float(params["exp_F"]), float(params["exp_eps"])
        return lambda T: e * np.log1p(np.asarray(T, float) / F)
    EA = float(params.get("EA", 3500.0))
    return lambda T: np.asarray(T, float) / EA


def exponential_from_taylor(k1: float, k2: float, L0: float, weight: float) -> dict | None:
    """exp_F, exp_eps from the Taylor coefficients about the balance, F(eps_b + x/L0) - weight =
    k1 x + k2 x^2 + ...: the law's derivatives are (F + exp_F)/exp_eps and (F + exp_F)/exp_eps^2,
    so exp_eps = k1 L0 / (2 k2 L0^2) and exp_F = k1 L0 exp_eps - weight; None where they are not
    positive (a record that shows no stiffening)."""
    K1, K2 = k1 * L0, 2.0 * k2 * L0 ** 2
    if not (K1 > 0 and K2 > 0):
        return None
    e = K1 / K2
    F = K1 * e - weight
    return {"exp_F": F, "exp_eps": e} if F > 0 else None


def exponential_from_curve(eps: np.ndarray, T: np.ndarray) -> dict | None:
    """exp_F, exp_eps from a load-elongation curve (strain, tension samples) by least squares: for
    a strain scale exp_eps the tension is linear in exp_F; exp_eps is the best on a geometric grid
    from 1/100 to 10 times the largest strain, refined by golden-section search. None without
    two distinct positive strains."""
    eps = np.asarray(eps, float)
    T = np.asarray(T, float)
    ok = np.isfinite(eps) & np.isfinite(T)
    eps, T = eps[ok], T[ok]
    top = float(np.max(np.abs(eps))) if eps.size else 0.0
    if eps.size < 2 or not top > 0 or not np.ptp(eps) > 0:
        return None

    def fit(log_e: float) -> tuple[float, float]:
        g = np.expm1(np.clip(eps / math.exp(log_e), None, 700.0))
        F = float(g @ T / max(float(g @ g), 1e-300))
        return float(np.sum((F * g - T) ** 2)), F

    grid = np.linspace(math.log(0.01 * top), math.log(10.0 * top), 41)
    costs = [fit(x)[0] for x in grid]
    j = int(np.argmin(costs))
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    golden = 0.5 * (math.sqrt(5.0) - 1.0)
    for _ in range(40):
        c, d = b - golden * (b - a), a + golden * (b - a)
        if fit(c)[0] < fit(d)[0]:
            b = d
        else:
            a = c
    log_e = 0.5 * (a + b)
    F = fit(log_e)[1]
    return {"exp_F": F, "exp_eps": math.exp(log_e)} if F > 0 else None
