"""The start of a payload record (free vibration, forced) from its equation error
``m x'' + c(x) x' + R(x) + z = f``: linear in the damping's and the restoring force's coefficients,
with Bouc-Wen's (A, beta, gamma) found by a small nonlinear least-squares around it and the Iwan
bank's stiffnesses by non-negative least squares beside it."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import identify_native as idn
from ..models import C_OF_MAGNITUDE, ModelSpec
from ..traces import Trace
from .elastic import bilinear_from_curve, bilinear_near_linear, cubic_from_taylor, exponential_from_taylor
from .equation_error import damping_columns, restoring_columns, scaled_lstsq, taut_for_sure
from .iwan_bank import IWAN_CAP, iwan_params, payload_iwan_bank
from .kinematics import Kinematics, dominant_frequency, kinematics

#: Bouc-Wen's (A, beta, gamma) searches start here: A in units of the linear stiffness, beta and
#: gamma in units of 1/amplitude
BOUC_WEN_STARTS = ([0.3, 1.5, 0.5], [0.5, 1.0, -0.5], [0.15, 3.0, 1.0], [0.6, 0.5, -1.0])


@dataclass
class _Equation:
    """The payload's equation of motion over a record: its kinematics, the right-hand side
    f - m x'', and the law's form (cubic restoring force, displacement-dependent damping)."""

    K: Kinematics
    rhs: np.ndarray
    cubic: bool
    displacement: bool
    swing_rate: float = 0.0   # the amplitude law's clock (equation_error.damping_magnitude); 0: |x|

    def solve(self, z, sel, cubic: bool | None = None, displacement: bool | None = None):
        """Least-squares damping and restoring coefficients (damping's first) over the samples
        ``sel``, the hysteretic force z (or None) taken off the right-hand side; (coef, residual)."""
        cub = self.cubic if cubic is None else cubic
        dsp = self.displacement if displacement is None else displacement
        K = self.K
        A = np.column_stack(damping_columns(K.x[sel], K.v[sel], dsp, self.swing_rate) + restoring_columns(K.x[sel], cub))
        b = self.rhs[sel] - (0.0 if z is None else z[sel])
        coef = scaled_lstsq(A, b)
        return coef, b - A @ coef


def payload_estimate(trace: Trace, spec: ModelSpec) -> dict:
    """Equation-error estimates for one payload trace."""
    t = np.asarray(trace.time, float)
    m_w, m = idn.payload_masses(trace)    # the weight's mass and the inertia's (line density)
    g = float(trace.gravity_m_s2)
    L0 = float(trace.length_m)
    f_dom = dominant_frequency(t, np.asarray(trace.measured, float))
    K = kinematics(trace, f_dom)
    eq = _Equation(K, K.f - m * K.a, spec.stiffness != "linear" or spec.hysteresis == "kawabata",
                   spec.damping in C_OF_MAGNITUDE)
    keep = K.use.copy()
    amp = float(np.max(np.abs(K.x[keep]))) or 1e-9

    # linear first: the stiffness scale; drop samples that may be slack (below the balance stretch)
    coef, _ = eq.solve(None, keep, cubic=False, displacement=False)
    k_lin = float(coef[1]) if coef[1] > 0 else m * (2 * math.pi * f_dom) ** 2
    c_lin = float(coef[0])
    if spec.slack and g > 0:
        slack_free = taut_for_sure(K.x, m_w, g, k_lin)
        if slack_free[keep].sum() > 20:
            keep &= slack_free
    est: dict = {"_k_lin": k_lin, "_c_lin": c_lin, "_amp": amp, "_omega": math.sqrt(max(k_lin, 1e-300) / m)}
    if spec.damping == "amplitude":
        eq.swing_rate = est["_omega"]

    hysteresis, z = {}, None              # the hysteretic force z along the record, where there is one
    if spec.hysteresis == "boucwen":
        hysteresis, z = _bouc_wen_start(eq, keep, k_lin, amp)
    elif spec.hysteresis == "iwan":
        eps_b = m_w * g / (k_lin * L0) if k_lin > 0 and g > 0 else 0.0
        hysteresis, z = _iwan_start(eq, keep, L0, eps_b if spec.slack else None, k_lin)
    est.update(hysteresis)
    coef, res = eq.solve(z, keep)
    nd = 3 if eq.displacement else 1
    est.update(_damping_start([float(v) for v in coef[:nd]], c_lin, k_lin, m, amp))
    if spec.damping == "coulomb":
        c0 = est["c0"] if est["c0"] > 0 else abs(c_lin)
        est.update(coulomb_start(c0, est["_omega"], amp, t, 0.5))
    est.update(_elastic_start([float(v) for v in coef[nd:]], spec, eq.cubic, k_lin, L0, m_w * g))
    if spec.stiffness == "bilinear":
        est.update(_bilinear_start(eq, z, keep, coef[:nd], L0, m_w * g, est["EA"]))
    est["_ee_rms"] = float(np.sqrt(np.mean(res ** 2)))
    return est


def _bilinear_start(eq: _Equation, z, keep: np.ndarray, damping: np.ndarray, L0: float, weight: float,
                    EA: float) -> dict:
    """The bilinear law from the restoring force the equation error leaves (the right-hand side
    less the damping and the hysteretic force) along the strain from the balance."""
    K = eq.K
    D = np.column_stack(damping_columns(K.x[keep], K.v[keep], eq.displacement, eq.swing_rate))
    R = eq.rhs[keep] - D @ np.asarray(damping, float) - (0.0 if z is None else z[keep])
    u = K.x[keep] / L0
    return (bilinear_from_curve(u, R, balance=weight)
            or bilinear_near_linear(EA, weight / EA if weight > 0 else float(np.max(np.abs(u)))))


def _bouc_wen_start(eq: _Equation, keep: np.ndarray, k_lin: float, amp: float) -> tuple[dict, np.ndarray | None]:
    """Bouc-Wen's (A, beta, gamma) by nonlinear least squares from BOUC_WEN_STARTS, the rest
    linear (variable projection); ({bw_A, bw_beta, bw_gamma}, z along the record), or ({}, None)."""
    from scipy.optimize import least_squares

    xs = eq.K.x
    sA, sb = k_lin, 1.0 / amp

    def residual(p):
        # z along the measured path, the law integrated exactly sample to sample (physics/boucwen.c)
        zz = idn.bouc_wen_path(xs, p[0] * sA, p[1] * sb, p[2] * sb, eq.K.periodic)
        _, r = eq.solve(zz, keep)
        return r

    best = None
    for p0 in BOUC_WEN_STARTS:
        try:
            sol = least_squares(residual, p0, bounds=([1e-6, -1e3, -1e3], [10.0, 1e3, 1e3]), x_scale=1.0,
                                diff_step=1e-4, max_nfev=60)
        except (ValueError, FloatingPointError):
            continue
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        return {}, None
    pA, pb, pg = best.x
    est = {"bw_A": float(pA * sA), "bw_beta": float(pb * sb), "bw_gamma": float(pg * sb)}
    return est, idn.bouc_wen_path(xs, est["bw_A"], est["bw_beta"], est["bw_gamma"], eq.K.periodic)


def _iwan_start(eq: _Equation, keep: np.ndarray, L0: float, slack_balance: float | None,
                k_lin: float) -> tuple[dict, np.ndarray | None]:
    """The Iwan bank's spring strains along the measured strain path from the balance, where its
    springs are unloaded (held at zero strain where a slack tether is shortened: ``slack_balance``
    is then the balance strain): the element stiffnesses enter linearly, >= 0. (The bank's
    parameters, its force along the record), or ({}, None)."""
    d = eq.K.x / L0
    if slack_balance is not None:
        d = np.maximum(d + slack_balance, 0.0) - slack_balance
    cols = damping_columns(eq.K.x, eq.K.v, eq.displacement, eq.swing_rate) + restoring_columns(eq.K.x, eq.cubic)
    span = 0.5 * float(np.ptp(d[keep])) or 1e-9
    bank = payload_iwan_bank(np.column_stack(cols), [-np.inf] * len(cols), eq.rhs, d, keep, span, eq.K.periodic)
    if bank is None:
        return {}, None
    _, slip, kb, z = bank
    return {**iwan_params(slip, kb), "_iw_cap": IWAN_CAP * (k_lin * L0 + float(np.sum(kb)))}, z


#: the bounds of a Coulomb friction's smoothing at its start, as a fraction of the speed scale
COULOMB_V_SHARE = (0.01, 0.3)


def coulomb_start(c0: float, omega: float, amp: float, time: np.ndarray, share: float) -> dict:
    """Viscous plus dry friction from a viscous damping ``c0``: the ``share`` of it handed to a
    friction that dissipates as much per cycle at the amplitude ``amp`` (a friction F dissipates
    4 F A per cycle, a viscous c pi c omega A^2); its sign smoothed over the speed one sample
    interval of the record's ``time`` sweeps at a reversal (amp omega^2 dt: a sharper sign the
    record cannot show), within COULOMB_V_SHARE of the speed scale amp omega."""
    t = np.asarray(time, float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    speed_share = min(max(omega * dt, COULOMB_V_SHARE[0]), COULOMB_V_SHARE[1])
    return {"c0": c0 * (1.0 - share), "c_coulomb": share * math.pi * c0 * omega * amp / 4.0,
            "coulomb_v": speed_share * amp * omega}


def _damping_start(c: list[float], c_lin: float, k_lin: float, m: float, amp: float) -> dict:
    """c0 (and c1, c2 of a displacement-dependent damping, when ``c`` has three coefficients)."""
    est = {"c0": c[0]}
    if len(c) == 3:
        # c(x) = c0 + c1 |x| + c2 x^2 >= 0: a term the equation error puts below zero starts small
        # (5 % of the record's linear damping at its amplitude), not at 0, where it has no scale
        c_ref = abs(c_lin) or 2 * 0.01 * math.sqrt(k_lin * m)
        est["c1"] = c[1] if c[1] > 0 else 0.05 * c_ref / amp
        est["c2"] = c[2] if c[2] > 0 else 0.05 * c_ref / amp ** 2
    return est


def _elastic_start(k: list[float], spec: ModelSpec, cubic: bool, k_lin: float, L0: float, weight: float) -> dict:
    """The elastic law from the restoring force's Taylor coefficients k about the balance (Kawabata:
    the coefficients themselves, as '_k_taylor')."""
    if spec.hysteresis == "kawabata":
        return {"_k_taylor": k}
    if spec.stiffness == "exponential":
        # no stiffening seen: a law near linear, its strain scale ten times the balance strain
        k1 = k[0] if k[0] > 0 else k_lin
        e_w = weight / (k1 * L0) if weight > 0 else 1e-3
        return exponential_from_taylor(k1, k[1], L0, weight) or {"exp_F": 9.0 * max(weight, k1 * L0 * 1e-3),
                                                                  "exp_eps": 10.0 * e_w}
    if spec.stiffness == "bilinear":
        return {"EA": (k[0] if k[0] > 0 else k_lin) * L0}   # its toe: _bilinear_start
    if cubic:
        a = cubic_from_taylor(k[0], k[1], k[2], L0, weight)
        if a is None or not a["a1"] > 0:
            a = {"a1": k_lin * L0}            # no consistent balance: the linear part only
        return a
    # (a bank or a damping that took up all the stiffness leaves no valid law: the linear start's)
    return {"EA": (k[0] if k[0] > 0 else k_lin) * L0}
