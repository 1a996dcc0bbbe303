#!/usr/bin/env python3
"""Benchmark: fit of the `full` model (cubic a1 a2 a3 + Bouc-Wen + displacement damping c0 c1 c2)
to a 10 s, 1 kHz free-vibration trace, native engine vs a plain scipy fit, in the same run.

The trace is synthetic: the engine simulates the FMU's physics with known parameters (m = 4.3 kg,
L0 = 16 m, x0 = -0.1669 m) and Gaussian noise (0.1 mm) is added. Both fits start from the same
values (10-50 % off), with the same bounds and log-scaled parameters. The scipy peer is the
obvious one: the same equations in numpy, scipy.integrate.solve_ivp (rtol 1e-8) sampled at the
trace's times, scipy.optimize.least_squares (trf, 2-point Jacobian, diff_step 1e-3).

    python bench/bench_fit_full.py [--scipy-max-nfev N] [--skip-scipy]
Library: env KT_IDENTIFY_LIB or build/fmu_src/identify/libtether_identify.so.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))
from tether import identify_native as idn  # noqa: E402

M, L0, G, X0 = 4.3, 16.0, 9.81, -0.1669
SETTINGS = {"rig": 2, "stiffness": 2, "damping": 2, "hysteresis": 3, "m": M, "L0": L0, "g": G, "x0": X0}
TRUTH = {"a1": 1200.0, "a2": 2e5, "a3": -2e6, "c0": 1.5, "c1": 25.0, "c2": 50.0,
         "bw_A": 60.0, "bw_beta": 15.0, "bw_gamma": 5.0}
FACTOR = {"a1": 1.1, "a2": 0.9, "a3": 0.8, "c0": 1.3, "c1": 0.8, "c2": 1.5, "bw_A": 0.8, "bw_beta": 1.3,
          "bw_gamma": 0.7}
NOISE = 1e-4


def problem(seed: int = 1):
    t = np.arange(10001) * 1e-3
    e = idn.Experiment(t, settings=SETTINGS)
    x = idn.simulate(e, TRUTH)
    e.measured = x + NOISE * np.random.default_rng(seed).standard_normal(t.size)
    start = {n: TRUTH[n] * FACTOR[n] for n in TRUTH}
    bounds = {}
    for n, s in start.items():
        a, b = sorted((s / 20, s * 20))
        bounds[n] = (a, b)
    return t, e, start, bounds


def engine_fit(e, start, bounds, **opts):
    free = {n: (bounds[n][0], bounds[n][1], start[n]) for n in start}
    c0, t0 = time.process_time(), time.perf_counter()
    r = idn.fit([e], free, **opts)
    return r, time.perf_counter() - t0, time.process_time() - c0


# ---- scipy peer: the same model written in numpy ------------------------------------------------
def scipy_simulate(p, t, rtol=1e-8):
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    a1, a2, a3, c0, c1, c2, A, beta, gamma = (p[n] for n in TRUTH)
    F = lambda e: a1 * e + a2 * e * e + a3 * e ** 3  # noqa: E731
    eps_b = brentq(lambda e: F(e) - M * G, 0.0, 0.05)
    ub = eps_b * L0

    def rhs(_t, y):
        x, v, z = y
        eps = (ub + x) / L0
        T = F(eps) + z + (c0 + c1 * abs(x) + c2 * x * x) * v
        if eps <= 0 or T < 0:
            T = 0.0
        psi = gamma + beta * np.sign(v * z)
        return [v, G - T / M, v * (A - abs(z) * psi)]

    s = solve_ivp(rhs, (t[0], t[-1]), [X0, 0.0, 0.0], t_eval=t, rtol=rtol, atol=[1e-8 * L0 * 1e-3, 1e-8 * L0 * 1e-2, 1e-8])
    if not s.success:
        raise RuntimeError(s.message)
    return s.y[0]


def scipy_fit(t, meas, start, bounds, max_nfev):
    from scipy.optimize import least_squares

    names = list(start)
    sign = np.array([np.sign(start[n]) for n in names])
    th0 = np.log(np.abs([start[n] for n in names]))
    lo = np.log([min(abs(bounds[n][0]), abs(bounds[n][1])) for n in names])
    hi = np.log([max(abs(bounds[n][0]), abs(bounds[n][1])) for n in names])
    nsim = [0]

    def res(th):
        nsim[0] += 1
        p = dict(zip(names, sign * np.exp(th)))
        try:
            return scipy_simulate(p, t) - meas
        except Exception:
            return np.full(t.size, 1.0)

    c0, t0 = time.process_time(), time.perf_counter()
    r = least_squares(res, th0, bounds=(lo, hi), method="trf", diff_step=1e-3, x_scale="jac", max_nfev=max_nfev)
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    return dict(zip(names, sign * np.exp(r.x))), dt, cpu, nsim[0], float(np.sqrt(np.mean(r.fun ** 2))), r.message


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scipy-max-nfev", type=int, default=60,
                    help="cap on scipy's cost evaluations (each also costs 9 Jacobian simulations)")
    ap.add_argument("--skip-scipy", action="store_true")
    ap.add_argument("--repeat", type=int, default=3, help="engine fits to time (best is reported)")
    a = ap.parse_args(argv)
    t, e, start, bounds = problem()
    print(f"trace: {t.size} samples, {t[-1]:.0f} s, noise {NOISE:g} m; free: {', '.join(TRUTH)}")
    best = None
    for _ in range(a.repeat):
        r, dt, cpu = engine_fit(e, start, bounds, output_stride=20, horizon_stages=3)
        if best is None or dt < best[1]:
            best = (r, dt, cpu)
    r, dt, cpu = best
    try:
        load = " (load average %.1f on %d cores: other processes share them)" % (os.getloadavg()[0], os.cpu_count())
    except OSError:
        load = ""
    print(f"engine: {dt:.3f} s wall (best of {a.repeat}), {cpu:.3f} s CPU, {r.evaluations} simulations, "
          f"{r.iterations} iterations, rms {r.rms:.4g} m (noise {NOISE:g}), {r.message}{load}")
    inside = 0
    for n, v, s, lo, hi in zip(r.names, r.values, r.std_error, r.ci_low, r.ci_high):
        ok = lo <= TRUTH[n] <= hi
        inside += ok
        print(f"  {n:9s} {v:13.6g}  truth {TRUTH[n]:11.6g}  ({(v / TRUTH[n] - 1) * 100:+6.2f} %, "
              f"{(v - TRUTH[n]) / s:+5.2f} se)  95 % CI [{lo:.6g}, {hi:.6g}]{'' if ok else '  OUTSIDE'}")
    print(f"  truth inside the 95 % interval: {inside}/{len(r.names)}; condition {r.condition:.3g}")
    if r.report:
        print("  undetermined directions:\n    " + r.report.strip().replace("\n", "\n    "))
    if a.skip_scipy:
        return 0
    ps, ds, dcpu, nsim, rms, msg = scipy_fit(t, e.measured, start, bounds, a.scipy_max_nfev)
    print(f"scipy (solve_ivp + least_squares): {ds:.3f} s wall, {dcpu:.3f} s CPU, {nsim} simulations "
          f"({ds / max(nsim, 1) * 1e3:.0f} ms each), rms {rms:.4g} m, {msg}")
    for n in TRUTH:
        print(f"  {n:9s} {ps[n]:13.6g}  ({(ps[n] / TRUTH[n] - 1) * 100:+6.2f} %)")
    capped = ", scipy stopped at max_nfev, not converged: a lower bound" if nsim >= a.scipy_max_nfev else ""
    print(f"ratio scipy / engine: {ds / dt:.1f}x wall (engine {dt:.3f} s, scipy {ds:.3f} s), "
          f"{dcpu / cpu:.1f}x CPU{capped}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
