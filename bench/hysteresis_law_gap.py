#!/usr/bin/env python3
"""How much of discovery's remaining gap on a hysteretic record is the form of the hysteresis law?
A research bench, not a CI test: it decides which hysteresis law the FMU should gain next.

Discovery names hysteresis with the paper's Bouc-Wen force. On the generator's Iwan records
(python_tests/hidden_effects.py: parallel Jenkins elements, Masing rules) it ends above the noise
(bench/discovery_eval.py: trace 10 3.4 x, 29 10.4 x, 26 5.6 x) or names an extra nonlinear
stiffness to bend the Bouc-Wen loops (42). This bench fits, outside the FMU, the elastic law
EA eps + c0 u' plus a hysteretic force H that follows the extended Masing rules (a branch from a
turning point is the virgin curve phi scaled by two; a branch that reaches the turning point it
started from rejoins the older branch; the virgin branch mirrored at its first reversal), with
two virgin curves:

* ``tanh``: phi(d) = F_s tanh((K d / F_s)^r)^(1/r), a generic saturating curve (K, F_s, r);
* ``menegotto-pinto``: phi(d) = K d / (1 + (K |d| / F_s)^r)^(1/r), the classic explicit Masing
  curve of structural steel (K, F_s, r);
* ``iwan``: the continuous Iwan element with a power-law spread of slip strains,
  phi(d) = K d (1 - b/(b+1) (d/e_max)^(1/b)) below e_max, K e_max/(b+1) above (K, e_max, b):
  the generator's law in the limit of many elements, so the figure says what a law of that
  family reaches, not what an independent law reaches;
* ``pi``: Prandtl-Ishlinskii, eight Jenkins elements of free stiffness on a fixed geometric grid
  of slip strains (ratio 0.55, the largest free): the general Masing law the FMU gained as
  ``hysteresis = iwan`` (physics/iwan.c), not the generator's twelve equal elements on a power-law
  spread;

and, as a check of this bench's own integrator (fixed-step RK4, four steps per sample, reversals
at the step where the strain rate changes sign), the generator's hidden law itself, which must
give about 1 x noise. Load tests are solved quasi-statically (the strain that carries the load on
the current branch); payload records by integrating the payload's equation of motion, with the
hysteretic element unloaded at the static balance (as the generator's) and held at zero strain
while the tether is slack.

    python bench/hysteresis_law_gap.py [--laws=check,tanh,mp,iwan,pi] TRACE [TRACE ...]
    (TRACE: a stem of NAME.csv + NAME.json)

Prints per record and law the RMS error over the noise (the generator's sigma where the JSON has
it, else the data's estimate) and the fitted values. About a minute per law for a 10 s record at
1 kHz (a Python loop).

Measured (2026-11-24/25, noise sigma of the generator): the fitted law over the noise
                          Bouc-Wen (discovery)  tanh   Menegotto-Pinto  continuous Iwan  check
  10 load test, Iwan            3.40             1.56       2.02             1.002         1.000
  29 forced, Iwan + slack      10.4              3.23        -               1.088         1.009
  42 free vibration, Iwan       2.00 (1.22 with   1.35        -               0.987         0.985
                                      an extra cubic)
tanh reaches the same 1.56 on record 10 from three starts (r 0.5, 1, 0.7): the family's limit, not
a local minimum. A generic saturating curve closes part of the gap; what closes it is a curve whose
tangent falls to zero at a finite strain (the continuous Iwan's), which is the generator's own
family and would make the tests judge the FMU against its own law.

The general law of that kind, eight elements of free stiffness on a grid (``pi``, 2026-11-25):
record 10 1.21 x noise (20 s), 42 1.05 (701 s), 29 4.43 (485 s; this bench's least squares from
one start: the FMU's fit of the same law reaches 4.8 on the grid). Chosen: the FMU's Iwan law.
"""
from __future__ import annotations

import sys
import time

import numpy as np
from scipy.optimize import least_squares

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()


def virgin_tanh(K, Fs, r):
    def phi(d):
        with np.errstate(over="ignore"):
            z = (K * np.abs(d) / Fs) ** r
        z = np.where(np.isfinite(z), z, 50.0)          # tanh has saturated long before
        return np.sign(d) * Fs * np.tanh(z) ** (1.0 / r)
    return phi


def virgin_menegotto_pinto(K, Fs, r):
    def phi(d):
        x = K * np.abs(d) / Fs
        with np.errstate(over="ignore"):
            w = (1.0 + x ** r) ** (1.0 / r)
        w = np.where(np.isfinite(w), w, x)             # far out: phi -> F_s
        return np.sign(d) * Fs * x / w
    return phi


def virgin_iwan(K, emax, b):
    def phi(d):
        a = np.minimum(np.abs(d), emax)
        return np.sign(d) * K * a * (1.0 - b / (b + 1.0) * (a / emax) ** (1.0 / b))
    return phi


PI_ELEMENTS = 8
PI_RATIO = 0.55


def virgin_pi(emax, *w):
    """Prandtl-Ishlinskii (discrete Iwan): Jenkins elements of stiffness w_i slipping at the fixed
    geometric grid of strains e_i = emax PI_RATIO^(n-1-i); any Masing law with a virgin curve whose
    tangent falls stepwise, the general form of a bank of inter-fibre friction contacts."""
    e = emax * PI_RATIO ** np.arange(len(w) - 1, -1, -1)
    w = np.asarray(w, float)

    def phi(d):
        d = np.asarray(d, float)
        return np.sign(d) * (w * np.minimum(np.abs(d)[..., None], e)).sum(-1)
    return phi


def virgin_generator(meta):
    """The generator's discrete Iwan law (12 Jenkins elements), from the hidden metadata."""
    P = meta["hidden"]["params"]
    n = int(P["hyst_n"])
    K = P["hyst_eta"] * P["EA_N"]
    k = np.full(n, K / n)
    f = k * P["hyst_eps_ymax"] * ((np.arange(n) + 0.5) / n) ** P["hyst_beta"]

    def phi(d):
        d = np.asarray(d, float)
        return np.sign(d) * np.minimum(k * np.abs(d)[..., None], f).sum(-1)
    return phi


class Masing:
    """Extended Masing memory of a hysteretic element whose virgin curve ``phi`` starts at ``origin``."""

    def __init__(self, phi, origin):
        self.phi, self.origin = phi, origin
        self.turns = []          # turning points (strain, force), oldest first
        self.up = 1              # direction of the current branch: +1 loading, -1 unloading

    def force(self, e):
        if not self.turns:
            return self.phi(e - self.origin)
        ea, Ha = self.turns[-1]
        return Ha + 2.0 * self.phi((e - ea) / 2.0)

    def advance(self, e_old, e_new):
        """Record a reversal between two strains, then rejoin the branches the new strain passed."""
        if (e_new - e_old) * self.up < 0:
            self.turns.append((e_old, self.force(e_old)))
            self.up = -self.up
        while len(self.turns) >= 2 and self.up * (e_new - self.turns[-2][0]) >= 0:
            del self.turns[-2:]
        if len(self.turns) == 1 and self.up * (e_new - (2 * self.origin - self.turns[0][0])) >= 0:
            self.turns.clear()   # the virgin curve, mirrored at the first reversal, rejoined


def simulate_load(trace, EA, phi):
    """Elongation of a quasi-static load test. With a linear elastic law the whole tension follows
    the Masing rules with the virgin curve EA d + phi(d), so the strain on a branch from the
    turning point (T_a, e_a) is e_a + 2 psi((T - T_a) / 2), psi the inverse of that curve."""
    grid = np.linspace(0.0, 0.2, 40001)
    total = EA * grid + phi(grid)

    def psi(F):
        return np.sign(F) * np.interp(abs(F), total, grid)

    T = trace.input
    eps = np.empty(len(T))
    turns, up = [], 1
    for i, Ti in enumerate(T):
        if i and (Ti - T[i - 1]) * up < 0:
            turns.append((T[i - 1], eps[i - 1]))
            up = -up
        while len(turns) >= 2 and up * (Ti - turns[-2][0]) >= 0:
            del turns[-2:]
        if len(turns) == 1 and up * (Ti + turns[0][0]) >= 0:
            turns.clear()
        if turns:
            Ta, ea = turns[-1]
            eps[i] = ea + 2.0 * psi((Ti - Ta) / 2.0)
        else:
            eps[i] = psi(Ti)
    return eps * trace.length_m


def simulate_payload(trace, EA, c0, phi, slack, substeps=4):
    """Displacement from balance of the payload, RK4 with ``substeps`` steps per sample."""
    L, m, g = trace.length_m, trace.payload_mass_kg, trace.gravity_m_s2
    ub = m * g / EA * L
    hyst = Masing(phi, ub / L)
    f = trace.input if trace.input is not None else np.zeros(len(trace.time))
    t = trace.time
    x, v = trace.initial_displacement_m, trace.initial_velocity_m_s

    def strain(x):
        e = (ub + x) / L
        return max(e, 0.0) if slack else e

    def acc(x, v, F):
        e = (ub + x) / L
        if slack and e <= 0:
            return g + F / m
        T = EA * e + hyst.force(strain(x)) + c0 * v
        return g + (F - (max(T, 0.0) if slack else T)) / m

    out = np.empty(len(t))
    out[0] = x
    for i in range(1, len(t)):
        h = (t[i] - t[i - 1]) / substeps
        for j in range(substeps):
            F0 = f[i - 1] + (f[i] - f[i - 1]) * j / substeps
            F1 = f[i - 1] + (f[i] - f[i - 1]) * (j + 1) / substeps
            Fm = 0.5 * (F0 + F1)
            a1 = acc(x, v, F0)
            a2 = acc(x + h / 2 * v, v + h / 2 * a1, Fm)
            a3 = acc(x + h / 2 * (v + h / 2 * a1), v + h / 2 * a2, Fm)
            a4 = acc(x + h * (v + h / 2 * a2), v + h * a3, F1)
            xn = x + h / 6 * (v + 2 * (v + h / 2 * a1) + 2 * (v + h / 2 * a2) + (v + h * a3))
            vn = v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            hyst.advance(strain(x), strain(xn))
            x, v = xn, vn
        out[i] = x
    return out


def main(argv=None) -> int:
    from tether.discover import estimate_noise
    from tether.fit import fit_traces
    from tether.traces import read_trace

    args = list(argv if argv is not None else sys.argv[1:])
    keys = {"check", "tanh", "mp", "iwan", "pi"}
    for a in [a for a in args if a.startswith("--laws=")]:
        keys = set(a.split("=", 1)[1].split(","))
        args.remove(a)
    stems = args
    if not stems:
        print(__doc__)
        return 2
    for stem in stems:
        tr = read_trace(stem)
        hidden = tr.meta.get("hidden", {})
        sigma = hidden.get("noise_sigma_m") or estimate_noise(tr).sigma
        slack = "slack" in hidden.get("effects", [])
        lin = fit_traces([tr], "linear")
        EA0, c00 = lin.parameters["EA"], lin.parameters.get("c0", 0.0)
        print(f"{tr.name} ({tr.experiment}, {len(tr.time)} samples): linear fit {lin.rms / sigma:.2f} x noise")
        laws = []
        if hidden.get("laws", {}).get("hysteresis") == "iwan":
            laws.append(("check", "generator's Iwan (check)", None, None))
        laws += [("tanh", "Masing, tanh virgin curve", virgin_tanh, [0.3 * EA0, 2.0, 2.0]),
                 ("mp", "Masing, Menegotto-Pinto", virgin_menegotto_pinto, [0.3 * EA0, 2.0, 1.0]),
                 ("iwan", "Masing, continuous Iwan", virgin_iwan, [0.3 * EA0, 0.005, 1.0]),
                 ("pi", f"Prandtl-Ishlinskii, {PI_ELEMENTS} el.", virgin_pi,
                  [0.005] + [0.3 * EA0 / PI_ELEMENTS] * PI_ELEMENTS)]
        for key, label, law, p0 in laws:
            if key not in keys:
                continue
            t0 = time.perf_counter()
            if law is None:
                P = hidden["params"]
                phi = virgin_generator(tr.meta)
                c0 = hidden.get("derived", {}).get("c0_N_s_m", 0.0)
                y = (simulate_load(tr, P["EA_N"], phi) if tr.rig == "load"
                     else simulate_payload(tr, P["EA_N"], c0, phi, slack))
                r = (y - tr.measured) / sigma
                print(f"  {label:30s} {np.sqrt(np.mean(r ** 2)):6.3f} x noise ({time.perf_counter() - t0:.0f} s)")
                continue
            if tr.rig == "load":
                q0 = np.log([EA0] + p0)

                def res(q):
                    p = np.exp(q[:-1])
                    return (simulate_load(tr, p[0], law(*p[1:])) + q[-1] - tr.measured) / sigma
                q0 = np.r_[q0, 0.0]
            else:
                q0 = np.log([EA0, max(c00, 1e-3)] + p0)

                def res(q):
                    p = np.exp(q)
                    return (simulate_payload(tr, p[0], p[1], law(*p[2:]), slack) - tr.measured) / sigma
            def guarded(q, res=res):
                # a trial step the optimiser takes far out (a huge exponent, a runaway payload)
                # costs a large finite residual instead of poisoning the fit with NaN
                with np.errstate(all="ignore"):
                    f = res(q)
                return f if np.all(np.isfinite(f)) else np.full(len(tr.time), 1e3)
            fit = least_squares(guarded, q0, x_scale="jac", max_nfev=150)
            vals = np.exp(fit.x[:len(q0) - (1 if tr.rig == "load" else 0)])
            print(f"  {label:30s} {np.sqrt(np.mean(fit.fun ** 2)):6.3f} x noise ({time.perf_counter() - t0:.0f} s); "
                  f"values {' '.join(f'{v:.4g}' for v in vals)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
