"""Constitutive laws of generator B, each written from the physics notes, not from the product.

Every law works in strain eps = elongation / natural length and in newtons. Elastic laws give a
tension T(eps); damping laws a force from the displacement x [m] and the velocity v [m/s];
hysteresis laws a force added in parallel to the spring; creep laws a strain driven by the load
history (they sit in series with the elastic element).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


# ---------------------------------------------------------------------------------------------
# elastic laws


def softplus(y: float) -> float:
    """log(1 + e^y) without overflow."""
    return y + math.log1p(math.exp(-y)) if y > 0.0 else math.log1p(math.exp(y))


def logistic(y: float) -> float:
    """d softplus / dy."""
    if y >= 0.0:
        return 1.0 / (1.0 + math.exp(-y))
    e = math.exp(y)
    return e / (1.0 + e)


@dataclass
class LinearElastic:
    """The format's baseline spring: T = EA eps, in tension and compression."""
    EA: float
    name: str = "linear"

    def tension(self, eps: float) -> float:
        return self.EA * eps

    def tangent(self, eps: float) -> float:
        return self.EA


@dataclass
class ExponentialElastic:
    """Exponential stiffening: T = EA0 eps_c (exp(eps / eps_c) - 1); the tangent grows e-fold per eps_c."""
    EA0: float
    eps_c: float
    name: str = "exponential"

    def tension(self, eps: float) -> float:
        return self.EA0 * self.eps_c * math.expm1(eps / self.eps_c)

    def tangent(self, eps: float) -> float:
        return self.EA0 * math.exp(eps / self.eps_c)


@dataclass
class ToeLinearElastic:
    """Bilinear: a soft toe (slack yarns tightening, k_toe) below eps_t, then the full EA above.

    The corner is rounded over a strain `width` with a softplus, so the law is smooth:
    T = k_toe eps + (EA - k_toe) width (softplus((eps - eps_t)/width) - softplus(-eps_t/width)).
    """
    k_toe: float
    EA: float
    eps_t: float
    width: float
    name: str = "toe_linear"

    def tension(self, eps: float) -> float:
        w = self.width
        bend = softplus((eps - self.eps_t) / w) - softplus(-self.eps_t / w)
        return self.k_toe * eps + (self.EA - self.k_toe) * w * bend

    def tangent(self, eps: float) -> float:
        return self.k_toe + (self.EA - self.k_toe) * logistic((eps - self.eps_t) / self.width)


def elastic_strain_for(law, tension: float, lo: float = -0.5, hi: float = 0.5) -> float:
    """The strain at which the elastic law carries `tension` (the law is increasing)."""
    from scipy.optimize import brentq

    return brentq(lambda e: law.tension(e) - tension, lo, hi, xtol=1e-15, rtol=1e-14, maxiter=200)


# ---------------------------------------------------------------------------------------------
# damping laws: force opposing the motion, from displacement x [m] and velocity v [m/s]


@dataclass
class ViscousDamping:
    """The format's baseline damper: F = c0 v."""
    c0: float
    name: str = "viscous"

    def force(self, x: float, v: float) -> float:
        return self.c0 * v


@dataclass
class CoulombViscousDamping:
    """Dry friction between yarns plus a viscous part: F = c0 v + F_c tanh(v / v_s)."""
    c0: float
    F_c: float
    v_s: float
    name: str = "coulomb_viscous"

    def force(self, x: float, v: float) -> float:
        return self.c0 * v + self.F_c * math.tanh(v / self.v_s)


@dataclass
class AmplitudeDamping:
    """Damping that grows with the oscillation's amplitude and levels off (Jerry and Larry: high
    damping for large oscillations, very low for small ones):
    F = (c0 + c1 (1 - exp(-A / A_d))) v, with the instantaneous amplitude A = hypot(x, v / omega)."""
    c0: float
    c1: float
    A_d: float
    omega: float
    name: str = "amplitude"

    def force(self, x: float, v: float) -> float:
        amplitude = math.hypot(x, v / self.omega)
        return (self.c0 + self.c1 * (-math.expm1(-amplitude / self.A_d))) * v


# ---------------------------------------------------------------------------------------------
# hysteresis laws: a force in parallel with the spring, zero in the relaxed state


@dataclass
class DahlHysteresis:
    """Dahl's friction model in strain, asymmetric (the paper's Kevlar loops are): the force
    saturates at F_up = F_sat (1 + asym) while the strain grows and at -F_down = -F_sat (1 - asym)
    while it falls; dz/deps = k (1 - z / F_up) rising, k (1 + z / F_down) falling.

    As a rate law dz/dt = k (epsdot - z |epsdot| / F), F the saturation of the direction of
    motion. `branch` is its exact solution along a monotone strain change."""
    k: float
    F_sat: float
    asym: float = 0.0
    name: str = "dahl"

    @property
    def F_up(self) -> float:
        return self.F_sat * (1.0 + self.asym)

    @property
    def F_down(self) -> float:
        return self.F_sat * (1.0 - self.asym)

    def rate(self, z: float, eps_rate: float) -> float:
        F = self.F_up if eps_rate > 0.0 else self.F_down
        return self.k * (eps_rate - z * abs(eps_rate) / F)

    def branch(self, z0: float, d_eps: float) -> float:
        if d_eps > 0.0:
            return self.F_up - (self.F_up - z0) * math.exp(-self.k * d_eps / self.F_up)
        if d_eps < 0.0:
            return -self.F_down + (z0 + self.F_down) * math.exp(self.k * d_eps / self.F_down)
        return z0

    def steady_loop_peak(self, amplitude: float) -> float:
        """z at the top of a steady loop over strains +-amplitude (tanh(k A / F) F if symmetric)."""
        e_up = math.exp(-2 * self.k * amplitude / self.F_up)
        e_down = math.exp(-2 * self.k * amplitude / self.F_down)
        return (self.F_up * (1 - e_up) - e_up * self.F_down * (1 - e_down)) / (1 - e_up * e_down)


@dataclass
class StopBankHysteresis:
    """Prandtl-Ishlinskii bank of stop operators (elastic-perfectly-plastic cells: a spring w_i
    that slips once it carries w_i r_i), the friction between yarns:
    z = sum_i w_i s_i, s_i = q - p_i, with the plays p_i kept within [q - r_i, q + r_i] for the
    strain q measured from the relaxed state. Rate-independent; loops close by Masing's rule.
    Thresholds are evenly spaced up to r_max and the weights follow a density w(r) ~ r^(alpha-1),
    scaled so that they sum to `stiffness` (the bank's stiffness before anything slips)."""
    stiffness: float
    r_max: float
    alpha: float
    count: int
    name: str = "pi_stop"
    radii: list = field(init=False, repr=False)
    weights: list = field(init=False, repr=False)

    def __post_init__(self):
        r = self.r_max * np.arange(1, self.count + 1) / self.count
        w = r ** (self.alpha - 1.0)
        self.radii = r.tolist()
        self.weights = (self.stiffness * w / w.sum()).tolist()

    def outputs(self, p: list, q: float) -> list:
        """The plays after the strain moves monotonically from where `p` was set to q."""
        return [min(max(pi, q - r), q + r) for pi, r in zip(p, self.radii)]

    def force(self, p: list, q: float) -> float:
        total = 0.0
        for pi, r, w in zip(p, self.radii, self.weights):
            total += w * (q - min(max(pi, q - r), q + r))
        return total

    def virgin(self, q: float) -> float:
        """Force along a first monotone loading from the relaxed state to strain q >= 0."""
        return float(np.sum(np.asarray(self.weights) * np.minimum(q, np.asarray(self.radii))))


# ---------------------------------------------------------------------------------------------
# creep laws: strain in series with the elastic element, driven by the load history F(t)
# (piecewise linear between the samples, the same path the load column describes)


@dataclass
class BurgersCreep:
    """Burgers: a Maxwell dashpot (eta, unrecoverable flow) in series with a Kelvin cell
    (stiffness K, time constant tau, recoverable). Under a step load F from rest:
    eps_c(t) = F/K (1 - exp(-t/tau)) + F t / eta."""
    K: float
    tau: float
    eta: float
    name: str = "burgers"

    def strain(self, t: np.ndarray, load: np.ndarray) -> np.ndarray:
        """Creep strain at the samples; the Kelvin cell starts in balance with the first load
        (a preload hung long before), the dashpot at zero."""
        kelvin = load[0] / self.K
        flow = 0.0
        out = np.empty(len(t))
        out[0] = kelvin
        for j in range(1, len(t)):
            dt = t[j] - t[j - 1]
            slope = (load[j] - load[j - 1]) / dt
            decay = math.exp(-dt / self.tau)
            start_particular = (load[j - 1] - slope * self.tau) / self.K
            end_particular = (load[j] - slope * self.tau) / self.K
            kelvin = end_particular + (kelvin - start_particular) * decay
            flow += 0.5 * (load[j] + load[j - 1]) * dt / self.eta
            out[j] = kelvin + flow
        return out


@dataclass
class FindleyCreep:
    """Findley's power law with Boltzmann superposition, so it recovers after unloading:
    eps_c(t) = b * integral (t - s)^n dG(F(s)), G(F) = F_s sinh(F / F_s). Under a step F at 0:
    b G(F) t^n; removed at t1: b G(F) (t^n - (t - t1)^n). The first load counts as a step
    `preload_age` seconds before the first sample."""
    b: float
    n: float
    F_s: float
    preload_age: float
    name: str = "findley"

    def G(self, load):
        return self.F_s * np.sinh(np.asarray(load, float) / self.F_s)

    def strain(self, t: np.ndarray, load: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        g = self.G(load)
        n1 = self.n + 1.0
        out = self.b * g[0] * (t - t[0] + self.preload_age) ** self.n
        rates = np.diff(g) / np.diff(t)
        for j in np.nonzero(rates)[0]:
            after = t > t[j]
            tt = t[after]
            start = (tt - t[j]) ** n1
            end = np.clip(tt - t[j + 1], 0.0, None) ** n1
            out[after] += self.b * rates[j] * (start - end) / n1
        return out
