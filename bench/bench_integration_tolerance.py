#!/usr/bin/env python3
"""What CVODE's tolerance costs and buys in the engine's simulations, by record kind; not a CI test.

The records of bench/bench_engine_simulation.py (the tests' independent generator, fixed seeds),
each set up as `tether fit` sets its last stage up (the data-based start). For each relative
tolerance (the FMU parameter rtol; CVODE runs at rtol x INTEGRATOR_LOCAL_TOLERANCE_FACTOR) printed
per record: the evaluations of the equations per sample and per simulation and the CPU microseconds
per sample, both from kt_fit's statistics step (1 + 2 k simulations, as a fit simulates: the
input's pieces carried on), and the largest difference of the start's prediction from the one at
the tightest tolerance, in units of the record's noise (tether's estimate). docs/speed.md (2026-12-06, session 65) has
the figures and what a looser tolerance did to discovery.

    python bench/bench_integration_tolerance.py [--rtol 1e-10,1e-8,1e-6] [--only SUBSTRING]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

DEFAULT_RTOLS = "1e-10,1e-9,1e-8,1e-7,1e-6,1e-5"


def statistics_step(exp, free, scaling, opts, rtol: float) -> tuple[float, float]:
    """(equation evaluations per simulation, CPU seconds per simulation) of kt_fit's statistics step."""
    from tether import identify_native as idn

    t0 = time.thread_time()
    r = idn.fit([exp], free, scaling=scaling, max_iterations=0, central_differences=idn.CENTRAL, n_threads=1,
                rtol=rtol, **opts)
    return r.rhs_evaluations / r.evaluations, (time.thread_time() - t0) / r.evaluations


def prediction(exp, free, rtol: float) -> np.ndarray:
    """The start's prediction of the measured column at ``rtol``."""
    from tether import identify_native as idn

    return idn.simulate(exp, {**{n: v[2] for n, v in free.items()}, "rtol": rtol})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtol", default=DEFAULT_RTOLS, help=f"tolerances, tightest first (default {DEFAULT_RTOLS})")
    ap.add_argument("--only", default=None, help="only the records whose name contains this")
    a = ap.parse_args(argv)
    from bench_engine_simulation import RECORDS, build_record, record_stem
    from tether import identify_native as idn
    from tether.noise import estimate_noise
    from tether.traces import read_trace

    rtols = [float(x) for x in a.rtol.split(",")]
    idn.simulation_cache_bytes(0)
    print(f"load average {os.getloadavg()[0]:.2f} at the start")
    print(f"{'record':20s} {'model':16s} {'rtol':>7s} {'evals/sample':>12s} {'us/sample':>10s} {'max diff/noise':>15s}")
    folder = tempfile.mkdtemp(prefix="integration_tolerance_")
    for i, (name, experiment, effects, model, rate) in enumerate(RECORDS):
        if a.only and a.only not in name:
            continue
        exp, free, scaling, opts = build_record(name, experiment, effects, model, rate, 2000 + i, folder)
        noise = estimate_noise(read_trace(os.path.join(folder, record_stem(name)))).sigma
        n = len(exp.time)
        reference = prediction(exp, free, rtols[0])
        for rtol in rtols:
            work, secs = statistics_step(exp, free, scaling, opts, rtol)
            diff = float(np.max(np.abs(prediction(exp, free, rtol) - reference))) / noise
            print(f"{name:20s} {model:16s} {rtol:7.0e} {work / n:12.2f} {1e6 * secs / n:10.3f} {diff:15.2e}",
                  flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
