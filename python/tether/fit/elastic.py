"""The elastic laws as the fit's starts use them: the cubic (with its power term), the
exponential and the bilinear law, the tension at a strain, the strain at a tension, and the coefficients from the
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
        return _bisect(cubic_tension, params, T, np.zeros_like(T), np.full_like(T, hi0), 60)
    return inv


def _bisect(tension, params: Mapping[str, float], T: np.ndarray, lo: np.ndarray, hi: np.ndarray, steps: int):
    """The strain between ``lo`` and ``hi`` at which the rising law ``tension`` carries T:
    ``steps`` halvings of the bracket, vectorised over T."""
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        below = tension(params, mid) < T
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


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


def _softplus(y):
    return np.logaddexp(0.0, y)


def toe_bend(eps, toe_eps: float, toe_width: float):
    """The bilinear law's bend, toe_width (softplus((eps - toe_eps)/toe_width) - softplus(-toe_eps/
    toe_width)): 0 in the toe, eps - toe_eps + its value at 0 beyond (F = toe_EA (eps - bend) +
    EA bend)."""
    e = np.asarray(eps, float)
    return toe_width * (_softplus((e - toe_eps) / toe_width) - _softplus(-toe_eps / toe_width))


def bilinear_tension(params: Mapping[str, float], eps):
    """Tension of the FMU's bilinear elastic law at strain ``eps``: a toe of stiffness toe_EA up to
    toe_eps, then EA, the corner rounded over toe_width (physics/elastic.c)."""
    e = np.asarray(eps, float)
    b = toe_bend(e, float(params["toe_eps"]), float(params["toe_width"]))
    return float(params["toe_EA"]) * (e - b) + float(params["EA"]) * b


def _bisection_inverse(tension, params: Mapping[str, float], span: float):
    """The strain at tension T of a law that rises everywhere with a slope of at least T / span per
    unit T (|eps| <= |T| span): bisection, vectorised."""
    def inv(T):
        T = np.asarray(T, float)
        return _bisect(tension, params, T, np.minimum(T * span, 0.0), np.maximum(T * span, 0.0), 80)
    return inv


def elastic_inverse(stiffness: str, params: Mapping[str, float]):
    """The strain at tension T of the elastic law ``stiffness`` (linear, cubic, exponential or
    bilinear) with ``params``, as a function of T (on the law's rising branch)."""
    if stiffness == "cubic":
        return cubic_inverse(params)
    if stiffness == "bilinear":
        return _bisection_inverse(bilinear_tension, params, 1.0 / min(float(params["toe_EA"]), float(params["EA"])))
    if stiffness == "exponential":
        F, e = float(params["exp_F"]), float(params["exp_eps"])
        return lambda T: e * np.log1p(np.asarray(T, float) / F)
    EA = float(params.get("EA", 3500.0))
    return lambda T: np.asarray(T, float) / EA


def elastic_tension(stiffness: str, params: Mapping[str, float], eps):
    """Tension of the elastic law ``stiffness`` (linear, cubic, exponential or bilinear) with
    ``params`` at strain ``eps``."""
    if stiffness == "cubic":
        return cubic_tension(params, eps)
    if stiffness == "bilinear":
        return bilinear_tension(params, eps)
    if stiffness == "exponential":
        return exponential_tension(params, eps)
    return float(params.get("EA", 3500.0)) * np.asarray(eps, float)


def cubic_from_curve(eps: np.ndarray, T: np.ndarray) -> dict | None:
    """a1, a2, a3 (no power term) from tension samples ``T`` along the strain ``eps`` by least
    squares; None without three distinct strains or where the law does not rise at the samples."""
    e, F = np.asarray(eps, float), np.asarray(T, float)
    if np.unique(e).size < 3:
        return None
    a = np.linalg.lstsq(np.column_stack([e, e ** 2, e ** 3]), F, rcond=None)[0]
    slope = a[0] + e * (2 * a[1] + 3 * a[2] * e)
    return {"a1": float(a[0]), "a2": float(a[1]), "a3": float(a[2]), "pow_F": 0.0} if np.all(slope > 0) else None


def elastic_from_curve(stiffness: str, eps: np.ndarray, T: np.ndarray) -> dict | None:
    """The terms of the elastic law ``stiffness`` (cubic, exponential or bilinear) that follow the
    tension samples ``T`` along the strain ``eps`` best (least squares); None where that law cannot."""
    fitted = {"cubic": cubic_from_curve, "exponential": exponential_from_curve, "bilinear": bilinear_from_curve}
    return fitted[stiffness](eps, T) if stiffness in fitted else None


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


#: the bilinear law's corner from a curve: toe_width on a geometric grid of these fractions of the
#: strain range, toe_eps on BILINEAR_CORNERS points across it
BILINEAR_WIDTHS = (0.02, 0.05, 0.1, 0.2, 0.4)
BILINEAR_CORNERS = 41


def _toe_slopes(u: np.ndarray, R: np.ndarray, corner: float, width: float, intercept: bool):
    """Least squares of R = toe_EA (u - b) + EA b (+ r0 with ``intercept``), b the bend of a corner
    at ``corner``: (cost, toe_EA, EA, r0), None unless both slopes are positive."""
    b = toe_bend(u, corner, width)
    A = np.column_stack([u - b, b] + ([np.ones_like(u)] if intercept else []))
    coef = np.linalg.lstsq(A, R, rcond=None)[0]
    if not (coef[0] > 0 and coef[1] > 0):
        return None
    return float(np.sum((A @ coef - R) ** 2)), float(coef[0]), float(coef[1]), float(coef[2]) if intercept else 0.0


def bilinear_from_curve(eps: np.ndarray, T: np.ndarray, balance: float | None = None) -> dict | None:
    """EA, toe_EA, toe_eps, toe_width from tension samples ``T`` along the strain ``eps`` by least
    squares: for a corner (toe_eps, toe_width) the tension is linear in the two slopes; the corner
    is the best on a grid (BILINEAR_CORNERS strains across the samples' range, BILINEAR_WIDTHS of
    it). ``balance``: the strain is known only from a balance that carries the tension
    ``balance`` (a payload record: eps is the displacement over L0 and T the restoring force, with
    an intercept), and the law's zero is where the fitted curve carries -balance. None without six
    samples over two strains, or where no corner gives two positive slopes and a toe that ends
    above zero strain."""
    u = np.asarray(eps, float)
    R = np.asarray(T, float)
    ok = np.isfinite(u) & np.isfinite(R)
    u, R = u[ok], R[ok]
    if u.size < 6 or not np.ptp(u) > 0:
        return None
    span = float(np.ptp(u))
    best = None
    for corner in np.linspace(u.min(), u.max(), BILINEAR_CORNERS):
        for f in BILINEAR_WIDTHS:
            fit = _toe_slopes(u, R, corner, f * span, balance is not None)
            if fit is not None and (best is None or fit[0] < best[0]):
                best = (*fit, corner, f * span)
    if best is None:
        return None
    _, k_toe, EA, r0, corner, width = best
    law = {"EA": EA, "toe_EA": k_toe, "toe_eps": corner, "toe_width": width}
    if balance is not None:
        # F(e_b + u) = balance + r0 + G(u), G the law with its corner at u = corner: F's zero is
        # at G = -(balance + r0), and its corner that far above it
        law["toe_eps"] = corner - float(elastic_inverse("bilinear", law)(-(float(balance) + r0)))
    return law if law["toe_eps"] > 0 else None


def bilinear_near_linear(EA: float | None, strain: float) -> dict:
    """A bilinear law near the linear one, where a record shows no toe: a toe of half the stiffness
    up to a tenth of the record's ``strain``; {} without a positive EA and strain."""
    if not (EA and EA > 0 and strain > 0):
        return {}
    return {"EA": EA, "toe_EA": 0.5 * EA, "toe_eps": 0.1 * strain, "toe_width": 0.02 * strain}


def near_linear_law(stiffness: str, EA: float, strain: float) -> dict:
    """The elastic law ``stiffness`` near the linear law EA at the record's ``strain``: the cubic
    with a2 = a3 = 0; the exponential whose strain scale is ten times it (stiffness EA at zero
    strain, 10 % more there); the bilinear's short soft toe (bilinear_near_linear)."""
    if stiffness == "cubic":
        return {"a1": EA, "a2": 0.0, "a3": 0.0}
    if stiffness == "exponential":
        return {"exp_F": 10.0 * strain * EA, "exp_eps": 10.0 * strain}
    if stiffness == "bilinear":
        return bilinear_near_linear(EA, strain)
    return {"EA": EA}
