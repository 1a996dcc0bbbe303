#!/usr/bin/env python3
"""Independent generator of synthetic "measured" tether traces with hidden physical effects.

Purpose
=======
Test data for the project's *discovery* workflow, which must name the effects a trace contains
(names from ``docs/trace-format.md``: ``nonlinear_stiffness``, ``hysteresis``,
``nonlinear_damping``, ``creep``, ``slack``).  The generator deliberately does **not** use the
team's model equations (cubic tension law, Bouc-Wen / Kawabata hysteresis, polynomial c(x),
Kelvin-chain creep) and does not import the ``tether`` package or the FMU: discovery is tested
against model-form mismatch.  It has its own integrator (fixed-step RK4 with sub-steps and
located slack events) and its own quasi-static solver.  Only numpy and scipy are used.

Files written follow ``tether-trace/1`` exactly (``STEM.csv`` + ``STEM.json``).  The JSON carries an
extra key ``hidden`` (allowed: readers ignore unknown keys) with the true effects, the effects the
record can reveal, every generating parameter and the noise sigma.  A discovery run must not read
it; a scoring harness does.

Mechanical model (own laws)
===========================
Coordinates: natural length ``L``, elongation ``u``, strain ``eps = u/L``; payload mass ``m``,
gravity ``g``; displacement ``x = u - u_b`` from the static balance ``u_b`` (the elongation at
which the elastic law carries ``m g`` with the friction elements of the hysteresis law unloaded).

Tension (taut tether)::

    T = F_el(eps) + F_h(eps history) + F_d(x, u')

Baseline (no effect): ``F_el = EA eps`` (also in compression), ``F_h = 0``, ``F_d = c0 u'`` with
``c0 = 2 zeta sqrt(k m)``, ``k = EA/L`` (tangent at balance when stiffness is nonlinear),
``zeta`` log-uniform in 0.5-5 %.  ``EA`` uniform 2000-6000 N (dynamic tests: capped so that the
static stretch ``m g L / EA`` is at least 0.08 m), ``L`` in {8,10,12,14,16} m, ``m`` 2-6 kg,
``g`` = 9.81, diameter in {1.5, 1.8, 2.0} mm (recorded only).

Effects and the laws used
-------------------------
=====================  ==========================================================================
effect                 law (parameters; why it differs from the team's model)
=====================  ==========================================================================
nonlinear_stiffness    two laws, alternated by the suite (override ``stiffness_law``):
                       *logcosh* (exponential-tanh stiffening): tangent
                       ``EA (1 + alpha tanh(eps/eps_r))``, i.e.
                       ``F_el = EA (eps + alpha eps_r ln cosh(eps/eps_r))``, alpha 0.6-0.95,
                       eps_r 0.7-1.4 x the static strain (load tests: 0.005-0.015);
                       *power*: ``F_el = EA eps_ref sgn(eps)|eps/eps_ref|^p``, p 1.25-1.6,
                       eps_ref = static strain (load tests 0.01), secant = EA there.
                       Override ``stiff_ref_strain`` sets eps_r (logcosh) or eps_ref (power)
                       for every experiment: one tether's law in a campaign.
                       Neither is a polynomial; the cubic a1 e + a2 e^2 + a3 e^3 is not exact
                       for either.
hysteresis             Iwan model: N = 12 parallel Jenkins elements (spring k_i = eta EA / N in
                       series with a Coulomb slider of strength f_i = k_i eps_y,i), in parallel
                       with the elastic law.  eta 0.2-0.5, total slip force sum f_i 0.8-3 N,
                       slip strains eps_y,i = eps_ymax ((i-1/2)/N)^beta, beta 0.7-1.5.
                       Rate-independent, piecewise-linear, Masing, closes minor loops; no
                       Bouc-Wen state equation, no Kawabata power branches.  The elements are
                       unloaded at the static balance (dynamic tests, tether "shaken down")
                       or at zero load (virgin tether, load tests).
nonlinear_damping      two laws (override ``damping_law``): *gauss* (saturating amplitude
                       dependence) ``c(x) = c0 (1 + a (1 - exp(-(x/x_c)^2)))``, a 3-8,
                       x_c 0.3-0.6 x the initial/target amplitude; *drag* (quadratic in
                       velocity) ``F_d = c0 u' + c_q |u'| u'`` with ``c_q = a c0 / (w A0)``.
                       Neither is c0 + c1|x| + c2 x^2.  Both: low damping at small amplitude,
                       high at large (Jerry and Larry's observation).
creep                  in series with the elastic/hysteretic element (tension = load):
                       recoverable part by Boltzmann superposition with a *Findley power-law*
                       compliance ``J(t) = (e1h/100 N)(t/1 h)^n`` (n 0.15-0.35) or a
                       *logarithmic* one ``J(t) = (e1h/100 N) ln(1+t/tau)/ln(1+1h/tau)``
                       (tau 300-1800 s), e1h = creep strain after 1 h at 100 N, 2-5e-4;
                       unrecoverable part by *time-hardening Norton-Bailey* viscoplasticity
                       ``eps_p = C s^q``, reduced time ``s = int (T/100 N)^r dt`` [h], r 3-5,
                       q 0.4-0.7, eps_p after 10 h at 100 N 2-5e-4 (so repeated loadings leave
                       less and less, as the paper's 8, 5, 3 mm).  Not a Kelvin chain, no
                       strain-hardening state.  Evaluated in closed form for piecewise-linear
                       load (ramp responses); not modelled in the (seconds-long) dynamic tests.
slack                  the tether carries no compression: ``T = 0`` for ``eps <= 0`` (all of
                       it, damping and hysteresis included) and ``T = max(T, 0)`` otherwise.
                       Entry/exit at eps = 0 are located (Hermite-cubic root of the RK4 step,
                       then re-step to the root); during slack the payload is in free flight.
                       Free-vibration slack traces release the payload 1.3-1.8 static
                       stretches ABOVE balance; forced slack traces scale the force so the
                       linear response reaches 1.2-1.5 static stretches above balance.
=====================  ==========================================================================

Which experiment reveals which effect (the ``hidden.revealed`` list)
--------------------------------------------------------------------
    effect                free_vibration  forced  load_unload            creep
    nonlinear_stiffness   yes             yes     yes                    yes (0/100/5 N levels)
    hysteresis            yes             yes     yes                    present, not counted (+)
    nonlinear_damping     yes             yes     no (quasi-static)      no
    creep                 refused         refused present, not counted   yes
    slack                 yes*            yes*    no (load >= 0)         no

``*`` only if the record actually went slack (always, for the generated slack traces).
``+`` a creep test holds each load and changes it within one sample interval, so no sample lies on
a loading or unloading path, only on the held levels. A Masing-type hysteresis (Iwan, Kawabata)
then returns to the same strain at every revisit of a level (a minor loop closes at its turning
point; a reload to the old maximum meets the virgin curve), so elongation is a single-valued
function of the held load plus creep: exactly what a nonlinear elastic law with a value at each
level gives. Such a record shows the hysteresis only as a level-dependent stiffness, it cannot
reveal it as hysteresis; the suite does not hide hysteresis in creep tests.
``hidden.effects`` = what the generating model contains; ``hidden.revealed`` = the subset the
record can reveal, i.e. what a discovery run should name.  A name in effects but not in revealed
is neither required nor wrong; a name outside effects is a false positive.  ``creep`` is refused
for the dynamic experiments (records of seconds); in ``load_unload`` (minutes) it acts but is too
weak against the stiffness to count (about 1-2 noise sigma), so the suite does not use it there.
Slack and nonlinear damping are accepted in load tests but have no effect there.

Experiments
===========
* ``free_vibration``: payload held at ``x0`` (0.5-0.8 static stretches from balance, either
  side; slack traces: 1.3-1.8 above) and released at rest; 5-20 s; 100-1000 Hz.
* ``forced``: starts at rest at balance; input force = random-phase multisine (flat amplitude
  on the grid k/T in a stated band around the natural frequency) or a linear sine sweep, 0.5 s
  cosine fade-in, linear interpolation between samples; amplitude scaled (via a linear
  ``scipy.signal.lsim`` estimate) so the peak displacement is 0.4-0.7 static stretches
  (taut traces) or the upward peak 1.2-1.5 (slack traces); 10-20 s; 100-1000 Hz.
* ``load_unload``: quasi-static (no inertia, no damper), load from 0 N ramped at 0.5-2 N/s
  through 2-4 cycles of peaks 30-100 N and valleys 0 N or partial (minor loops), back to 0;
  5-50 Hz.
* ``creep``: 0 N at t=0, then 1-3 repetitions of [hold 60-100 N for 2-8 h, hold 5 N for
  2-8 h], total <= 36 h; load steps ramp over one sample interval; 0.1-1 Hz.
The input column is exact; the recorded input is, by construction, the linear interpolant
that drove the simulation.  Optional sampling jitter (non-uniform time) via ``jitter``.

Noise: white Gaussian on the measured column only; sigma from {1e-5, 1e-4, 3e-4, 1e-3} m
(displacement) or {1e-5, 5e-5, 1e-4, 2e-4} m (elongation) unless given.

Suite (``suite(n=48, seed=0)``)
===============================
Per experiment: a null, every revealable effect alone, every pair, a second null
(free_vibration 12, forced 12, load_unload 5, creep 5 = 34 base traces, interleaved across
experiments), then the list is repeated with new seeds and the other law variants until ``n``
(for 48: one more null per experiment, nlstiff x3, creep, hyst x3, nlstiff, nldamp x2).  Trace ``i`` has seed
``1000 seed + i + 1``; law variants alternate per (experiment, effect); noise levels and
sampling rates cycle per
experiment (the subtle single/paired nonlinear stiffness/damping traces get the three lower
noise levels); every third load_unload/creep trace has non-uniform (jittered) time.  Every
effect trace of the default suite leaves a best-fit baseline (linear spring + viscous damper)
residual at least ~4.7 times the noise; nulls leave 1.0.

API
===
``generate(experiment, effects, seed, noise=None, rate=None, **overrides) -> Trace``;
``Trace.write(dirpath, stem)``; ``suite(n=48, seed=0) -> [(name, Trace)]``;
``nuisance_specs(n=24, seed=0)``: the nuisance family (see ``generate``'s ``nuisance``).
CLI ``python python_tests/hidden_effects.py OUTDIR --n 48 [--seed 0] [--jobs 2] [--nuisance]``.
"""
from __future__ import annotations

import argparse
import io
import json
import math
import os
import sys
import tempfile
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import signal

FORMAT = "tether-trace/1"
GENERATOR = "hidden_effects/1"
EFFECTS = ("nonlinear_stiffness", "hysteresis", "nonlinear_damping", "creep", "slack")
EXPERIMENTS = ("free_vibration", "forced", "load_unload", "creep")
DYNAMIC = ("free_vibration", "forced")
REVEALABLE = {
    "free_vibration": ("nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"),
    "forced": ("nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"),
    "load_unload": ("nonlinear_stiffness", "hysteresis"),
    "creep": ("creep", "nonlinear_stiffness"),
}
MEASURED = {"free_vibration": "displacement", "forced": "displacement",
            "load_unload": "elongation", "creep": "elongation"}
INPUT = {"free_vibration": None, "forced": "force", "load_unload": "load", "creep": "load"}
NOISE_LEVELS = {"displacement": (1e-5, 1e-4, 3e-4, 1e-3), "elongation": (1e-5, 5e-5, 1e-4, 2e-4)}
RATES = {"free_vibration": (100.0, 200.0, 500.0, 1000.0), "forced": (100.0, 200.0, 500.0, 1000.0),
         "load_unload": (5.0, 10.0, 20.0, 50.0), "creep": (0.1, 0.2, 0.5, 1.0)}
P_REF = 100.0          # N, reference load of the creep laws
HOUR = 3600.0
LN2 = math.log(2.0)
MAX_CREEP_SAMPLES = 40000
H_MAX = 2e-3           # s, largest RK4 sub-step (also <= 0.02 / natural angular frequency)


# ----------------------------------------------------------------------------------------------
# Constitutive pieces
# ----------------------------------------------------------------------------------------------
class Elastic:
    """Elastic law F_el(eps): linear, logcosh (exp-tanh stiffening) or power law."""

    def __init__(self, EA, law="linear", alpha=0.0, eps_r=1.0, p=1.0, eps_ref=1.0):
        self.EA, self.law = float(EA), law
        self.alpha, self.eps_r, self.p, self.eps_ref = float(alpha), float(eps_r), float(p), float(eps_ref)

    def force(self, e):
        EA = self.EA
        if self.law == "linear":
            return EA * e
        if self.law == "logcosh":
            y = abs(e / self.eps_r)
            return EA * (e + self.alpha * self.eps_r * (y + math.log1p(math.exp(-2.0 * y)) - LN2))
        y = abs(e / self.eps_ref) ** self.p
        return EA * self.eps_ref * (y if e >= 0 else -y)

    def tangent(self, e):
        if self.law == "linear":
            return self.EA
        if self.law == "logcosh":
            return self.EA * (1.0 + self.alpha * math.tanh(e / self.eps_r))
        return self.EA * self.p * abs(e / self.eps_ref) ** (self.p - 1.0)

    def force_vec(self, e):
        e = np.asarray(e, float)
        if self.law == "linear":
            return self.EA * e
        if self.law == "logcosh":
            y = np.abs(e / self.eps_r)
            return self.EA * (e + self.alpha * self.eps_r * (y + np.log1p(np.exp(-2 * y)) - LN2))
        return self.EA * self.eps_ref * np.sign(e) * np.abs(e / self.eps_ref) ** self.p

    def inverse_vec(self, F):
        """Strain carrying tension F (vectorised bisection; the law is strictly increasing)."""
        F = np.asarray(F, float)
        lo = np.full(F.shape, -0.5)
        hi = np.full(F.shape, 0.5)
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            big = self.force_vec(mid) > F
            hi = np.where(big, mid, hi)
            lo = np.where(big, lo, mid)
        return 0.5 * (lo + hi)


class Iwan:
    """Parallel Jenkins elements (elastic-perfectly-plastic); exact for monotone strain steps."""

    def __init__(self, k, f):
        self.k = [float(v) for v in k]
        self.f = [float(v) for v in f]
        self.z = [0.0] * len(self.k)
        self.eps0 = 0.0

    def reset(self, eps0):
        self.z = [0.0] * len(self.k)
        self.eps0 = float(eps0)

    def force(self, e):
        d = e - self.eps0
        s = 0.0
        for k, f, z in zip(self.k, self.f, self.z):
            w = z + k * d
            s += f if w > f else (-f if w < -f else w)
        return s

    def tangent(self, e):
        d = e - self.eps0
        s = 0.0
        for k, f, z in zip(self.k, self.f, self.z):
            if -f < z + k * d < f:
                s += k
        return s

    def commit(self, e):
        d = e - self.eps0
        z = []
        for k, f, zi in zip(self.k, self.f, self.z):
            w = zi + k * d
            z.append(f if w > f else (-f if w < -f else w))
        self.z = z
        self.eps0 = float(e)


# ----------------------------------------------------------------------------------------------
# Trace container
# ----------------------------------------------------------------------------------------------
def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return [_jsonable(v) for v in o.tolist()]
    return o


def _atomic_write_text(path: Path, text: str):
    fd, tmp = tempfile.mkstemp(prefix="." + path.name + ".", suffix=".tmp", dir=str(path.parent))
    try:
        with os.fdopen(fd, "w", newline="\n") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


@dataclass
class Trace:
    """One synthetic record: ``columns`` (ordered name -> array, as written), ``meta`` (the JSON
    dict, including ``hidden``) and ``truth`` (noise-free arrays, never written)."""
    columns: dict
    meta: dict
    truth: dict = field(default_factory=dict)

    @property
    def experiment(self):
        return self.meta["experiment"]

    @property
    def time(self):
        return self.columns["time"]

    @property
    def measured_name(self):
        return MEASURED[self.experiment]

    @property
    def measured(self):
        return self.columns[self.measured_name]

    @property
    def effects(self):
        return frozenset(self.meta["hidden"]["effects"])

    @property
    def revealed(self):
        return frozenset(self.meta["hidden"]["revealed"])

    def csv_text(self):
        names = list(self.columns)
        data = np.column_stack([self.columns[n] for n in names])
        buf = io.StringIO()
        fmt = ["%.12g"] + ["%.10g"] * (len(names) - 1)
        np.savetxt(buf, data, delimiter=",", fmt=fmt, header=",".join(names), comments="")
        return buf.getvalue()

    def json_text(self):
        return json.dumps(_jsonable(self.meta), indent=2) + "\n"

    def write(self, dirpath, stem):
        d = Path(dirpath)
        d.mkdir(parents=True, exist_ok=True)
        csv_path, json_path = d / f"{stem}.csv", d / f"{stem}.json"
        _atomic_write_text(csv_path, self.csv_text())
        _atomic_write_text(json_path, self.json_text())
        return csv_path, json_path


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------
def _r(x, nd=4):
    return float(round(float(x), nd))


def _draw_params(experiment, rng):
    """Primary parameters (drawn whether or not the effect is on, so the rng stream is fixed)."""
    P = {}
    P["length_m"] = float(rng.choice([8.0, 10.0, 12.0, 14.0, 16.0]))
    P["diameter_mm"] = float(rng.choice([1.5, 1.8, 2.0]))
    P["gravity_m_s2"] = 9.81
    P["mass_kg"] = _r(rng.uniform(2.0, 6.0), 2)
    ea_hi = 6000.0
    if experiment in DYNAMIC:   # static stretch >= ~0.08 m, so amplitudes stand above the noise
        ea_hi = float(np.clip(P["mass_kg"] * 9.81 * P["length_m"] / 0.08, 2000.0, 6000.0))
    P["EA_N"] = _r(rng.uniform(2000.0, ea_hi), 0)
    P["zeta"] = _r(math.exp(rng.uniform(math.log(0.005), math.log(0.05))), 5)
    # nonlinear stiffness
    P["stiffness_law"] = str(rng.choice(["logcosh", "power"]))
    P["stiff_alpha"] = _r(rng.uniform(0.6, 0.95))
    P["stiff_eps_r_factor"] = _r(rng.uniform(0.7, 1.4))
    P["stiff_eps_r_load"] = _r(rng.uniform(0.005, 0.015), 5)
    P["stiff_p"] = _r(rng.uniform(1.25, 1.6))
    # hysteresis (Iwan)
    P["hyst_n"] = 12
    P["hyst_eta"] = _r(rng.uniform(0.2, 0.5))
    P["hyst_slip_N"] = _r(rng.uniform(0.8, 3.0))
    P["hyst_beta"] = _r(rng.uniform(0.7, 1.5))
    # nonlinear damping
    P["damping_law"] = str(rng.choice(["gauss", "drag"]))
    P["damp_gain"] = _r(rng.uniform(3.0, 8.0))
    P["damp_xc_factor"] = _r(rng.uniform(0.3, 0.6))
    # creep
    P["creep_kernel"] = str(rng.choice(["findley", "log"]))
    P["creep_e1h"] = _r(rng.uniform(2e-4, 5e-4), 7)
    P["creep_n"] = _r(rng.uniform(0.15, 0.35))
    P["creep_tau_s"] = _r(rng.uniform(300.0, 1800.0), 1)
    P["plastic_e10h"] = _r(rng.uniform(2e-4, 5e-4), 7)
    P["plastic_q"] = _r(rng.uniform(0.4, 0.7))
    P["plastic_r"] = _r(rng.uniform(3.0, 5.0))
    # experiment
    if experiment == "free_vibration":
        P["x0_factor"] = _r(rng.uniform(0.5, 0.8) * rng.choice([-1.0, 1.0]))
        P["slack_x0_factor"] = _r(-rng.uniform(1.3, 1.8))
        P["v0_m_s"] = 0.0
    elif experiment == "forced":
        P["excitation"] = str(rng.choice(["multisine", "sweep"]))
        P["duration_s"] = _r(rng.uniform(10.0, 20.0), 1)
        P["peak_factor"] = _r(rng.uniform(0.4, 0.7))
        P["slack_peak_factor"] = _r(rng.uniform(1.2, 1.5))
        P["band_lo_factor"] = _r(rng.uniform(0.2, 0.4))
        P["band_hi_factor"] = _r(rng.uniform(2.5, 4.0))
        P["excitation_seed"] = int(rng.integers(0, 2**31 - 1))
    elif experiment == "load_unload":
        nc = int(rng.integers(2, 5))
        peaks = [_r(rng.uniform(30.0, 100.0), 1) for _ in range(nc)]
        valleys = []
        for i in range(nc - 1):
            valleys.append(0.0 if rng.random() < 0.5 else _r(rng.uniform(0.1, 0.5) * min(peaks[i], peaks[i + 1]), 1))
        P["lu_peaks_N"] = peaks
        P["lu_valleys_N"] = valleys
        P["lu_rate_N_s"] = _r(rng.uniform(0.5, 2.0), 3)
    elif experiment == "creep":
        nrep = int(rng.integers(1, 4))
        phases = []
        for _ in range(nrep):
            phases.append([_r(rng.choice([100.0, 100.0, rng.uniform(60.0, 100.0)]), 1), _r(rng.uniform(2.0, 8.0), 2)])
            phases.append([5.0, _r(rng.uniform(2.0, 8.0), 2)])
        total = sum(h for _, h in phases)
        if total > 36.0:
            phases = [[p, _r(h * 36.0 / total, 2)] for p, h in phases]
        P["creep_program"] = phases
    return P


# ----------------------------------------------------------------------------------------------
# Integrator for the dynamic rig (own fixed-step RK4 with located slack events)
# ----------------------------------------------------------------------------------------------
class _Rig:
    def __init__(self, L, m, g, elastic, iwan, damp, slack, u_b):
        self.L, self.m, self.g = L, m, g
        self.el, self.iwan, self.damp, self.slack, self.u_b = elastic, iwan, damp, slack, u_b
        self.slack_events = 0

    def tension(self, u, v, taut):
        if not taut:
            return 0.0
        e = u / self.L
        T = self.el.force(e) + self.damp(u - self.u_b, v)
        if self.iwan is not None:
            T += self.iwan.force(e)
        if self.slack and T < 0.0:
            T = 0.0
        return T

    def _step(self, t, u, v, h, taut, fa, fb, tk):
        g, m, ten = self.g, self.m, self.tension
        fA = fa + fb * (t - tk)
        fM = fa + fb * (t + 0.5 * h - tk)
        fB = fa + fb * (t + h - tk)
        a1 = g + (fA - ten(u, v, taut)) / m
        u2, v2 = u + 0.5 * h * v, v + 0.5 * h * a1
        a2 = g + (fM - ten(u2, v2, taut)) / m
        u3, v3 = u + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = g + (fM - ten(u3, v3, taut)) / m
        u4, v4 = u + h * v3, v + h * a3
        a4 = g + (fB - ten(u4, v4, taut)) / m
        return (u + h / 6.0 * (v + 2 * v2 + 2 * v3 + v4),
                v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4))

    @staticmethod
    def _hermite_root(u0, v0, u1, v1, h):
        def p(s):
            s2, s3 = s * s, s * s * s
            return ((2 * s3 - 3 * s2 + 1) * u0 + (s3 - 2 * s2 + s) * h * v0
                    + (-2 * s3 + 3 * s2) * u1 + (s3 - s2) * h * v1)
        lo, hi = 0.0, 1.0
        plo = p(lo)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            pm = p(mid)
            if (pm < 0) == (plo < 0):
                lo, plo = mid, pm
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def advance(self, t, u, v, h, taut, fa, fb, tk):
        """One sub-step of length h with slack entry/exit located inside it."""
        for _ in range(20):
            un, vn = self._step(t, u, v, h, taut, fa, fb, tk)
            crossed = self.slack and ((taut and un < 0.0) or ((not taut) and un > 0.0))
            if not crossed:
                if taut and self.iwan is not None:
                    self.iwan.commit(un / self.L)
                return un, vn, taut
            s = self._hermite_root(u, v, un, vn, h)
            hs = s * h
            if hs > 1e-14:
                u, v = self._step(t, u, v, hs, taut, fa, fb, tk)
            u = 0.0
            if taut and self.iwan is not None:
                self.iwan.commit(0.0)
            taut = not taut
            self.slack_events += 1
            t += hs
            h -= hs
            if h <= 1e-14:
                return u, v, taut
        raise RuntimeError("too many slack events in one step")

    def run(self, times, u0, v0, force=None, hmax=2e-3):
        n = len(times)
        U = np.empty(n)
        V = np.empty(n)
        T = np.empty(n)
        taut = not (self.slack and u0 < 0.0)
        u, v = float(u0), float(v0)
        U[0], V[0], T[0] = u, v, self.tension(u, v, taut)
        for i in range(n - 1):
            t0, t1 = float(times[i]), float(times[i + 1])
            dt = t1 - t0
            ns = max(1, int(math.ceil(dt / hmax - 1e-9)))
            h = dt / ns
            if force is None:
                fa = fb = 0.0
            else:
                fa = float(force[i])
                fb = (float(force[i + 1]) - fa) / dt
            for s in range(ns):
                u, v, taut = self.advance(t0 + s * h, u, v, h, taut, fa, fb, t0)
            U[i + 1], V[i + 1], T[i + 1] = u, v, self.tension(u, v, taut)
        return U, V, T


# ----------------------------------------------------------------------------------------------
# Builders
# ----------------------------------------------------------------------------------------------
def _blas_free(x):
    """x rounded to 9 significant digits. A value from a BLAS-backed routine (``signal.lsim``)
    differs in its last bits between BLAS kernels (SkylakeX against Haswell); rounded, the draw
    is the same on every machine."""
    return float(f"{x:.9g}")


def _times(rate, duration, rng, jitter=0.0):
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    if jitter:
        if not 0.0 < jitter < 0.5:
            raise ValueError("jitter must be in (0, 0.5)")
        t[1:-1] += rng.uniform(-jitter, jitter, n - 2) / rate
    return t


def _make_elastic(P, effects, eps_static=None):
    EA = P["EA_N"]
    if "nonlinear_stiffness" not in effects:
        return Elastic(EA)
    # one tether in several experiments (campaign_records) fixes the law's strain scale for all
    ref = P.get("stiff_ref_strain")
    if P["stiffness_law"] == "logcosh":
        er = ref or (P["stiff_eps_r_factor"] * eps_static if eps_static else P["stiff_eps_r_load"])
        return Elastic(EA, "logcosh", alpha=P["stiff_alpha"], eps_r=er)
    eref = ref or (eps_static if eps_static else 0.01)
    return Elastic(EA, "power", p=P["stiff_p"], eps_ref=eref)


def _make_iwan(P, effects):
    if "hysteresis" not in effects:
        return None
    n = int(P["hyst_n"])
    K = P["hyst_eta"] * P["EA_N"]
    shape = ((np.arange(n) + 0.5) / n) ** P["hyst_beta"]
    # sum f_i = (K/n) eps_ymax sum(shape) = hyst_slip_N
    eps_ymax = P["hyst_slip_N"] * n / (K * shape.sum())
    k = np.full(n, K / n)
    f = k * eps_ymax * shape
    P["hyst_eps_ymax"] = float(eps_ymax)
    return Iwan(k, f)


def _check_effects(experiment, effects):
    if experiment not in EXPERIMENTS:
        raise ValueError(f"unknown experiment {experiment!r}; expected one of {EXPERIMENTS}")
    effects = frozenset(effects)
    bad = effects - set(EFFECTS)
    if bad:
        raise ValueError(f"unknown effect(s) {sorted(bad)}; expected names from {EFFECTS}")
    if experiment in DYNAMIC and "creep" in effects:
        raise ValueError("creep is not modelled in dynamic experiments (records last seconds); "
                         "use a creep or load_unload experiment")
    return effects


def _dynamic(experiment, effects, P, rate, rng):
    L, m, g = P["length_m"], P["mass_kg"], P["gravity_m_s2"]
    eps_lin = m * g / P["EA_N"] if g > 0 else None
    el = _make_elastic(P, effects, eps_lin)
    eps_b = float(el.inverse_vec(np.array([m * g]))[0]) if g > 0 else 0.0
    u_b = eps_b * L
    k_lin = el.tangent(eps_b) / L
    w_n = math.sqrt(k_lin / m)
    c0 = 2.0 * P["zeta"] * math.sqrt(k_lin * m)
    slack = "slack" in effects
    hidden = {"balance_elongation_m": u_b, "k_lin_N_m": k_lin, "c0_N_s_m": c0,
              "natural_frequency_Hz": w_n / (2 * math.pi)}

    if experiment == "free_vibration":
        fac = P["slack_x0_factor"] if slack else P["x0_factor"]
        x0 = P.get("x0_m", fac * u_b)
        amp0 = abs(x0) if not slack else 1.4 * u_b
        duration = P.get("duration_s", float(np.clip(round(2 * 5.0 / (P["zeta"] * w_n)) / 2, 5.0, 20.0)))
    else:
        x0 = 0.0
        duration = P["duration_s"]
        amp0 = (P["slack_peak_factor"] if slack else P["peak_factor"]) * u_b
    P["duration_s"] = duration
    preroll = float(P.get("_preroll_s", 0.0)) if experiment == "forced" else 0.0
    cut = int(round(preroll * rate))      # samples run before the record starts (in motion)

    nd_on = "nonlinear_damping" in effects
    if nd_on and P["damping_law"] == "gauss":
        xc = P["damp_xc_factor"] * amp0
        a = P["damp_gain"]
        hidden["damp_xc_m"] = xc

        def damp(x, v):
            return c0 * (1.0 + a * (1.0 - math.exp(-(x / xc) ** 2))) * v
    elif nd_on:
        cq = P["damp_gain"] * c0 / (w_n * amp0)
        hidden["damp_cq_N_s2_m2"] = cq

        def damp(x, v):
            return c0 * v + cq * abs(v) * v
    else:
        def damp(x, v):
            return c0 * v

    t = _times(rate, duration + cut / rate, rng) if cut else _times(rate, duration, rng)
    hmax = min(H_MAX, 0.02 / w_n)
    force = None
    if experiment == "forced":
        er = np.random.default_rng(P["excitation_seed"])
        fn = w_n / (2 * math.pi)
        flo = round(max(0.1, P["band_lo_factor"] * fn), 2)
        fhi = round(min(P["band_hi_factor"] * fn, rate / 8.0), 2)
        T_rec = t[-1]
        if P["excitation"] == "multisine":
            kk = np.arange(max(1, math.ceil(flo * T_rec)), math.floor(fhi * T_rec) + 1)
            freqs = kk / T_rec
            ph = er.uniform(0, 2 * np.pi, len(freqs))
            shape = np.cos(2 * np.pi * np.outer(t, freqs) + ph).sum(axis=1)
            desc_exc = f"random-phase multisine, {len(freqs)} lines on {flo:g}-{fhi:g} Hz"
        else:
            shape = np.sin(2 * np.pi * (flo * t + 0.5 * (fhi - flo) * t ** 2 / T_rec))
            desc_exc = f"linear sine sweep {flo:g}->{fhi:g} Hz"
        fade = np.where(t < 0.5, 0.5 - 0.5 * np.cos(np.pi * t / 0.5), 1.0)
        shape = shape * fade
        shape /= np.max(np.abs(shape))
        sys_lin = signal.lti([1.0], [m, c0, k_lin])
        _, xl, _ = signal.lsim(sys_lin, shape, t)
        if slack:
            scale = P["slack_peak_factor"] * u_b / max(1e-12, -xl.min())
        else:
            scale = P["peak_factor"] * u_b / max(1e-12, np.abs(xl).max())
        scale = _blas_free(scale)
        force = shape * scale
        hidden.update(excitation=P["excitation"], band_Hz=[flo, fhi], force_scale_N=float(scale))
        P["_desc_exc"] = desc_exc

    iwan = _make_iwan(P, effects)
    for attempt in range(4):
        if iwan is not None:
            iwan.reset(eps_b)
            if experiment == "free_vibration":
                iwan.commit(max(u_b + x0, 0.0) / L)   # monotone pre-displacement from balance
        rig = _Rig(L, m, g, el, iwan, damp, slack, u_b)
        U, V, T = rig.run(t, u_b + x0, P["v0_m_s"] if experiment == "free_vibration" else 0.0,
                          force, hmax)
        # keep taut traces taut and slack traces slack (rescale the excitation if needed)
        if experiment == "forced" and slack and rig.slack_events == 0:
            force = force * 1.3
        elif not slack and U.min() < 0.05 * u_b and g > 0:
            if experiment == "forced":
                force = force * 0.7
            else:
                x0 *= 0.7
        else:
            break
    if cut:
        # the record is cut out of a longer run: it starts where the run was at t = preroll
        x0 = float(U[cut] - u_b)
        hidden.update(preroll_s=cut / rate, v0_m_s=float(V[cut]))
        t, force, U, V, T = t[cut:] - t[cut], force[cut:], U[cut:], V[cut:], T[cut:]
    if experiment == "forced":
        hidden["force_scale_N"] = float(np.max(np.abs(force)))
    hidden.update(slack_events=rig.slack_events, min_strain=float(U.min() / L),
                  max_strain=float(U.max() / L), max_tension_N=float(T.max()),
                  initial_displacement_m=float(x0), step_s=float(hmax))
    truth = {"displacement": U - u_b, "elongation": U, "velocity": V, "tension": T}
    return t, force, truth, hidden, x0


def _ramp_integral(kernel, P, tt):
    """R(t) = int_0^t J(s) ds for the recoverable creep compliance (tt >= 0)."""
    A = P["creep_e1h"] / P_REF
    if kernel == "findley":
        n = P["creep_n"]
        return A * HOUR / (n + 1.0) * (tt / HOUR) ** (n + 1.0)
    tau = P["creep_tau_s"]
    return A / math.log1p(HOUR / tau) * ((tt + tau) * np.log1p(tt / tau) - tt)


def _creep_strain(t, load, P):
    """Recoverable (Boltzmann superposition of ramp responses) + unrecoverable (Norton-Bailey)."""
    kernel = P["creep_kernel"]
    slopes = np.diff(load) / np.diff(t)
    ds = np.diff(np.concatenate([[0.0], slopes]))
    knots = np.nonzero(np.abs(ds) > 1e-12 * max(1.0, np.abs(slopes).max()))[0]
    eve = np.zeros_like(t)
    if load[0] != 0.0:
        raise ValueError("creep load history must start at 0 N")
    for j in knots:
        dt = t - t[j]
        pos = dt > 0
        eve[pos] += ds[j] * _ramp_integral(kernel, P, dt[pos])
    r, q = P["plastic_r"], P["plastic_q"]
    C = P["plastic_e10h"] / 10.0 ** q
    p0 = np.clip(load[:-1], 0, None) / P_REF
    p1 = np.clip(load[1:], 0, None) / P_REF
    h = np.diff(t) / HOUR
    same = np.abs(p1 - p0) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        seg = np.where(same, p0 ** r * h,
                       (p1 ** (r + 1) - p0 ** (r + 1)) / ((r + 1) * np.where(same, 1.0, p1 - p0)) * h)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    ep = C * s ** q
    return eve, ep


def _quasi_static(el, iwan, load):
    """Strain of the elastic(+Iwan) element carrying `load` (sequential when hysteretic)."""
    if iwan is None:
        return el.inverse_vec(load)
    out = np.empty(len(load))
    e = 0.0
    iwan.reset(0.0)
    prev = None
    for i, P in enumerate(load):
        if prev is not None and P == prev:
            out[i] = e
            continue
        def g(x):
            return el.force(x) + iwan.force(x) - P
        gv = g(e)
        if gv != 0.0:
            # bracket on the side the load moved to, then safeguarded Newton
            step = max(abs(gv) / el.EA, 1e-9)
            sgn = -1.0 if gv > 0 else 1.0
            a = e
            b = e + sgn * step
            while g(b) * sgn < 0:
                a = b
                step *= 2.0
                b = e + sgn * step
            lo, hi = (a, b) if a < b else (b, a)
            x = 0.5 * (lo + hi)
            for _ in range(100):
                gx = g(x)
                if gx > 0:
                    hi = x
                else:
                    lo = x
                if hi - lo < 1e-15 or abs(gx) < 1e-11:
                    break
                d = el.tangent(x) + iwan.tangent(x)
                xn = x - gx / d if d > 0 else 0.5 * (lo + hi)
                x = xn if lo < xn < hi else 0.5 * (lo + hi)
            e = x
        iwan.commit(e)
        out[i] = e
        prev = P
    return out


def _load_test(experiment, effects, P, rate, rng, jitter):
    L = P["length_m"]
    if experiment == "load_unload":
        peaks, valleys, rr = P["lu_peaks_N"], P["lu_valleys_N"], P["lu_rate_N_s"]
        levels = [0.0]
        for i, pk in enumerate(peaks):
            levels.append(pk)
            levels.append(valleys[i] if i < len(valleys) else 0.0)
        tk = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(levels)) / rr)])
        duration = math.ceil(float(tk[-1]) * rate - 1e-9) / rate    # ends on a sample at 0 N
        t = _times(rate, duration, rng, jitter)
        load = np.interp(t, tk, levels)
        desc = (f"quasi-static load-unload, {len(peaks)} cycles, peaks "
                f"{', '.join(f'{p:g}' for p in peaks)} N at {rr:g} N/s")
    else:
        prog = P["creep_program"]
        duration = sum(h for _, h in prog) * HOUR
        if rate * duration > MAX_CREEP_SAMPLES:
            ok = [r for r in RATES["creep"] if r * duration <= MAX_CREEP_SAMPLES]
            rate = max(ok) if ok else MAX_CREEP_SAMPLES / duration
        t = _times(rate, duration, rng, jitter)
        load = np.zeros_like(t)
        t_start = 0.0
        for lvl, hrs in prog:
            load[t > t_start] = lvl
            t_start += hrs * HOUR
        desc = ("constant-load holds: " + ", ".join(f"{lvl:g} N for {h:g} h" for lvl, h in prog))
    el = _make_elastic(P, effects, None)
    iwan = _make_iwan(P, effects)
    es = _quasi_static(el, iwan, load)
    eve = ep = np.zeros_like(t)
    if "creep" in effects:
        eve, ep = _creep_strain(t, load, P)
    U = L * (es + eve + ep)
    truth = {"elongation": U, "tension": load.copy(), "elastic_elongation": L * es,
             "creep_recoverable": L * eve, "creep_unrecoverable": L * ep}
    hidden = {"max_strain": float(U.max() / L)}
    return t, load, truth, hidden, desc, rate


# ----------------------------------------------------------------------------------------------
# Public API
# ----------------------------------------------------------------------------------------------
#: the nuisance family (issue 30; ``generate(..., nuisance=True)``): the effective mass the
#: simulation uses relative to the JSON's payload_mass_kg, the offset of the measured column in
#: noise levels (random sign), the share of forced records cut out of a longer run (in motion) and
#: how far into that run they start [s]
NUISANCE_MASS_FACTOR = (1.1, 1.3)
NUISANCE_OFFSET_NOISE = (2.0, 5.0)
NUISANCE_IN_MOTION_SHARE = 0.5
NUISANCE_PREROLL_S = (2.0, 4.0)


def _nuisance_draw(experiment, seed):
    """The nuisance family's draws for one trace, from a stream of their own (the default draws
    stay bit for bit what they were): mass factor, offset in noise levels (signed), pre-roll [s]
    (0 = the record starts at rest, as its JSON says)."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 30]))
    factor = _r(rng.uniform(*NUISANCE_MASS_FACTOR))
    offset = _r(rng.uniform(*NUISANCE_OFFSET_NOISE) * rng.choice([-1.0, 1.0]))
    moving = rng.random() < NUISANCE_IN_MOTION_SHARE
    preroll = _r(rng.uniform(*NUISANCE_PREROLL_S), 2)
    return factor, offset, (preroll if experiment == "forced" and moving else 0.0)


def generate(experiment, effects=frozenset(), seed=0, noise=None, rate=None, nuisance=False, **overrides):
    """Generate one trace.

    experiment: one of EXPERIMENTS; effects: iterable of EFFECTS names; seed: int (the trace is a
    pure function of the arguments); noise: sigma [m] of the Gaussian noise on the measured column
    (default: drawn from NOISE_LEVELS); rate: sampling rate [Hz] (default: drawn from RATES);
    overrides: any primary parameter of ``_draw_params`` (e.g. ``length_m``, ``mass_kg``,
    ``EA_N``, ``zeta``, ``stiffness_law``, ``damping_law``, ``creep_kernel``, ``creep_program``,
    ``x0_m``, ``duration_s``) plus ``jitter`` (fraction of the sample interval, non-uniform time)
    and ``description``.

    nuisance (dynamic experiments only; issue 30): what a real lab record knows imperfectly about
    itself. The simulation's payload mass (inertia and weight) is the JSON's payload_mass_kg times
    NUISANCE_MASS_FACTOR; the measured column carries a constant offset of NUISANCE_OFFSET_NOISE
    noise levels, random sign; about half of the forced records are cut NUISANCE_PREROLL_S into a
    longer run, so they start in motion. The JSON then omits initial_displacement_m and
    initial_velocity_m_s (free vibration too: its release point is read off the offset column).
    ``hidden.nuisance`` holds the truths: m_true, mass_factor, offset_measured, x0, v0, in_motion.
    A forced record of the family states ``"input_interpolation": "linear"`` (how its force acts
    between samples, as a lab's record would say); the default draws stay as they were.
    Overrides ``mass_factor``, ``offset_noise`` (signed, in noise levels) and ``preroll_s`` replace
    the draws. Off (the default), every draw is bit for bit what it was without the option.
    """
    effects = _check_effects(experiment, effects)
    ss = np.random.SeedSequence(int(seed))
    r_par, r_noise, r_time = [np.random.default_rng(s) for s in ss.spawn(3)]
    P = _draw_params(experiment, r_par)
    mname = MEASURED[experiment]
    if noise is None:
        noise = float(r_par.choice(NOISE_LEVELS[mname]))
    if rate is None:
        rate = float(r_par.choice(RATES[experiment]))
    jitter = float(overrides.pop("jitter", 0.0))
    description = overrides.pop("description", None)
    nz = None
    if nuisance:
        if experiment not in DYNAMIC:
            raise ValueError(f"nuisance=True applies to the payload rig's experiments {DYNAMIC}, not {experiment!r}")
        factor, offset, preroll = _nuisance_draw(experiment, seed)
        nz = {"mass_factor": float(overrides.pop("mass_factor", factor)),
              "offset_noise": float(overrides.pop("offset_noise", offset)),
              "preroll_s": float(overrides.pop("preroll_s", preroll)) if experiment == "forced" else 0.0}
    allowed = set(P) | {"x0_m", "duration_s", "v0_m_s", "stiff_ref_strain"}
    unknown = set(overrides) - allowed
    if unknown:
        raise TypeError(f"unknown override(s) {sorted(unknown)}")
    P.update(overrides)
    if noise < 0:
        raise ValueError("noise must be >= 0")

    meta = {"format": FORMAT, "experiment": experiment,
            "tether": {"length_m": P["length_m"], "diameter_mm": P["diameter_mm"]}}
    if experiment in DYNAMIC:
        if jitter:
            raise ValueError("jitter is only supported for load-controlled experiments")
        if nz is None:
            t, force, truth, hid, x0 = _dynamic(experiment, effects, P, float(rate), r_time)
        else:
            Ps = dict(P, mass_kg=P["mass_kg"] * nz["mass_factor"], _preroll_s=nz["preroll_s"])
            t, force, truth, hid, x0 = _dynamic(experiment, effects, Ps, float(rate), r_time)
            P.update({k: v for k, v in Ps.items() if k not in ("mass_kg", "_preroll_s")})
        meta["payload_mass_kg"] = P["mass_kg"]
        meta["gravity_m_s2"] = P["gravity_m_s2"]
        if nz is None:
            meta["initial_displacement_m"] = float(x0)
            meta["initial_velocity_m_s"] = float(P["v0_m_s"]) if experiment == "free_vibration" else 0.0
        if experiment == "free_vibration":
            desc = (f"free vibration: {P['mass_kg']:g} kg payload on a {P['length_m']:g} m tether, "
                    f"released at rest {x0:+.4f} m from static balance, {rate:g} Hz")
        else:
            desc = (f"forced vibration: {P['mass_kg']:g} kg payload on a {P['length_m']:g} m tether, "
                    f"from rest at balance, force = {P.pop('_desc_exc')}, {rate:g} Hz")
        inp = force
    else:
        t, inp, truth, hid, desc, rate = _load_test(experiment, effects, P, float(rate), r_time, jitter)
        meta["gravity_m_s2"] = P["gravity_m_s2"]
        desc += f", {rate:g} Hz"
    clean = truth[mname]
    if nz is not None:
        clean = clean + nz["offset_noise"] * noise
        v0 = float(hid.get("v0_m_s", P["v0_m_s"] if experiment == "free_vibration" else 0.0))
        nz.update(m_true=P["mass_kg"] * nz["mass_factor"], offset_measured=nz["offset_noise"] * noise,
                  x0=float(x0), v0=v0, in_motion=bool(nz["preroll_s"] > 0))
        if INPUT[experiment]:
            # what a lab states of its record: how the force acts between samples (issue 30: with a
            # cubic spline, the fitted mass's error is several times its interval)
            meta["input_interpolation"] = "linear"
        desc += (f"; effective mass {nz['mass_factor']:g} x the stated, offset {nz['offset_noise']:+g} noise levels"
                 + (f", cut {nz['preroll_s']:g} s into a longer run" if nz["in_motion"] else ""))
    meas = clean + noise * r_noise.standard_normal(len(clean))
    cols = {"time": t}
    if INPUT[experiment]:
        cols[INPUT[experiment]] = inp
    cols[mname] = meas
    truth["measured"] = clean
    revealed = [e for e in REVEALABLE[experiment] if e in effects]
    if "slack" in revealed and hid.get("slack_events", 0) == 0:
        revealed.remove("slack")
    laws = {"elastic": P["stiffness_law"] if "nonlinear_stiffness" in effects else "linear",
            "hysteresis": "iwan" if "hysteresis" in effects else None,
            "damping": (P["damping_law"] if "nonlinear_damping" in effects else "linear")
            if experiment in DYNAMIC else "none (quasi-static)",
            "creep": (P["creep_kernel"] + "+norton_bailey") if "creep" in effects else None,
            "slack": "slack" in effects}
    meta["description"] = description or (f"synthetic record ({GENERATOR}, seed {seed}): " + desc
                                          + f"; noise sigma {noise:g} m")
    meta["hidden"] = {"generator": GENERATOR, "seed": int(seed), "effects": sorted(effects),
                      "revealed": sorted(revealed), "noise_sigma_m": float(noise),
                      "rate_Hz": float(rate), "jitter": jitter, "laws": laws,
                      "params": {k: v for k, v in P.items() if not k.startswith("_")},
                      "derived": hid}
    if nz is not None:
        meta["hidden"]["nuisance"] = nz
    meta = _jsonable(meta)
    return Trace(cols, meta, truth)


_SHORT = {"nonlinear_stiffness": "nlstiff", "hysteresis": "hyst", "nonlinear_damping": "nldamp",
          "creep": "creep", "slack": "slack"}
SUBTLE = {"nonlinear_stiffness", "nonlinear_damping"}
_VARIANT = {"nonlinear_stiffness": ("stiffness_law", ("logcosh", "power")),
            "nonlinear_damping": ("damping_law", ("gauss", "drag")),
            "creep": ("creep_kernel", ("findley", "log"))}


def suite_specs(n=48, seed=0):
    """The suite as a list of (name, kwargs for generate)."""
    per_exp = {}
    for exp in EXPERIMENTS:
        eff = REVEALABLE[exp]
        combos = [()] + [(e,) for e in eff] + [(a, b) for i, a in enumerate(eff) for b in eff[i + 1:]] + [()]
        per_exp[exp] = combos
    order = []
    longest = max(len(v) for v in per_exp.values())
    for i in range(longest):
        for exp in EXPERIMENTS:
            if i < len(per_exp[exp]):
                order.append((exp, per_exp[exp][i]))
    specs = []
    count = {}
    k_exp = {e: 0 for e in EXPERIMENTS}
    i = 0
    while len(specs) < n:
        exp, combo = order[i % len(order)]
        k = k_exp[exp]
        k_exp[exp] += 1
        mname = MEASURED[exp]
        # the subtle effects (nonlinear stiffness/damping alone or together) get the three lower
        # noise levels; the highest level goes to nulls, hysteresis and slack
        subtle = bool(combo) and set(combo) <= SUBTLE
        levels = NOISE_LEVELS[mname][:3] if subtle else NOISE_LEVELS[mname]
        kw = {"experiment": exp, "effects": frozenset(combo), "seed": 1000 * int(seed) + len(specs) + 1,
              "noise": levels[k % len(levels)], "rate": RATES[exp][(3 * k + 1 + k // 4) % 4]}
        for e in combo:
            if e in _VARIANT:
                key, vals = _VARIANT[e]
                c = count.get((exp, e), 0)
                count[(exp, e)] = c + 1
                kw[key] = vals[c % 2]
        if exp in ("load_unload", "creep") and k % 3 == 2:
            kw["jitter"] = 0.3
        name = f"{len(specs):02d}_{exp}_{'+'.join(_SHORT[e] for e in combo) or 'null'}"
        specs.append((name, kw))
        i += 1
    return specs


def nuisance_specs(n=24, seed=0):
    """The nuisance family (issue 30): the first ``n`` free-vibration and forced records of
    ``suite_specs`` (for n = 24: each experiment's null, every effect alone, every pair and a second
    null), each drawn with ``nuisance=True``."""
    total = n
    while True:
        specs = [(name, dict(kw, nuisance=True)) for name, kw in suite_specs(total, seed)
                 if kw["experiment"] in DYNAMIC]
        if len(specs) >= n:
            return specs[:n]
        total += n


def _gen_spec(spec):
    name, kw = spec
    kw = dict(kw)
    return name, generate(kw.pop("experiment"), kw.pop("effects"), kw.pop("seed"), **kw)


def suite(n=48, seed=0):
    """At least every revealable effect alone and in pairs per experiment, plus nulls (34 base
    traces, then repeats with new seeds and the other law variants), with cycling noise levels and
    rates. Returns [(name, Trace)]."""
    return [_gen_spec(s) for s in suite_specs(n, seed)]


def main(argv=None):
    ap = argparse.ArgumentParser(description="Write a suite of synthetic tether traces with hidden effects.")
    ap.add_argument("outdir")
    ap.add_argument("--n", type=int, default=48)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--nuisance", action="store_true",
                    help="the nuisance family: free-vibration and forced records with a hidden effective mass, "
                         "an offset and (forced) some starting in motion")
    a = ap.parse_args(argv)
    t0 = _time.perf_counter()
    specs = nuisance_specs(a.n, a.seed) if a.nuisance else suite_specs(a.n, a.seed)
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(a.jobs) as ex:
            items = list(ex.map(_gen_spec, specs))
    else:
        items = [_gen_spec(s) for s in specs]
    for name, tr in items:
        tr.write(a.outdir, name)
        h = tr.meta["hidden"]
        print(f"{name:45s} n={len(tr.time):6d} sigma={h['noise_sigma_m']:.0e} "
              f"revealed={','.join(h['revealed']) or '-'}")
    print(f"{len(items)} traces written to {a.outdir} in {_time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
