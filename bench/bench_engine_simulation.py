#!/usr/bin/env python3
"""What one simulation of a record costs inside a fit, by record kind; not a CI test.

The identification engine's fits are most of a discovery and of a long `tether fit`; a fit is
simulations. This bench draws one record of each kind from the independent generator of the tests
(python_tests/hidden_effects.py, fixed seeds): a free vibration, forced vibrations (linear and with
Bouc-Wen hysteresis, 200 Hz and 1 kHz), a load-unload test and a creep test. For each it builds the
experiment as `tether fit` does (tether.fit.experiments.trace_experiment, the data-based start of
the free-vibration stride: tether.fit.engine._problem) and times the
engine's statistics step, kt_fit with no iteration: 1 + 2 k simulations of the record (central
differences, k free parameters) on one thread. Printed per record: CPU microseconds per sample per
simulation (the best of --repeats), for this build and, with --baseline LIB, for another build of
libtether_identify.so (an older checkout's; run alternately in this process), with the ratio and
the RMS of the start's residuals of both (a change that moves results moves it); then a machine
yardstick measured in the same run (one FMU simulation of the demo record, bench_discovery_speed).

    python bench/bench_engine_simulation.py [--baseline OLD/build/fmu_src/identify/libtether_identify.so]
                                            [--repeats 5] [--only SUBSTRING]
"""
from __future__ import annotations

import argparse
import ctypes as C
import os
import sys
import tempfile
import time
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

#: (name, experiment, hidden effects, model fitted, sampling rate [Hz] or None for the generator's)
RECORDS = [
    ("free vibration", "free_vibration", (), "linear", 200.0),
    ("forced", "forced", (), "linear", 200.0),
    ("forced, hysteresis", "forced", ("hysteresis",), "linear+boucwen", 200.0),
    ("forced 1 kHz", "forced", (), "linear", 1000.0),
    ("load test", "load_unload", (), "linear", None),
    ("creep test", "creep", ("creep",), "linear+creep", None),
]


def load_engine(path: str):
    """The engine library at ``path`` with the binding's argument types, whatever its API version
    (an older build's kt_fit_options is a prefix of this binding's)."""
    from tether import identify_native as idn

    saved_lib, saved_version, saved_env = idn._lib, idn.API_VERSION, os.environ.get("KT_IDENTIFY_LIB")
    try:
        idn._lib = None
        idn.API_VERSION = C.CDLL(path).kt_api_version()
        os.environ["KT_IDENTIFY_LIB"] = path
        return idn.library()
    finally:
        idn._lib, idn.API_VERSION = saved_lib, saved_version
        if saved_env is None:
            os.environ.pop("KT_IDENTIFY_LIB", None)
        else:
            os.environ["KT_IDENTIFY_LIB"] = saved_env


def record_stem(name: str) -> str:
    """The file stem build_record writes the record ``name`` under."""
    return name.replace(" ", "_").replace(",", "")


def build_record(name, experiment, effects, model, rate, seed, folder):
    """(experiment, free parameters {name: (lo, hi, start)}, scaling, engine options) of one record,
    as `tether fit` sets its last stage up (tether.fit.engine._problem: the data-based start)."""
    import hidden_effects as he
    from tether.fit.engine import _problem
    from tether.models import parse_model
    from tether.traces import read_trace

    kw = dict(rate=rate, duration_s=10.0) if rate else {}
    stem = record_stem(name)
    he.generate(experiment, set(effects), seed, **kw).write(folder, stem)
    trace = read_trace(Path(folder) / stem)
    pb = _problem([trace], parse_model(model, trace.experiment), None, {}, {}, None, {})
    free = {n: (*pb.box[n], pb.x0[n]) for n in pb.free}
    return pb.exps[0].exp, free, {n: pb.scaling[n] for n in pb.free}, pb.options


def time_statistics(lib, exp, free, scaling, opts) -> tuple[float, float]:
    """(CPU seconds per simulation, RMS of the start's residuals) of kt_fit's statistics step."""
    from tether import identify_native as idn

    idn._lib = lib
    t0 = time.thread_time()
    r = idn.fit([exp], free, scaling=scaling, max_iterations=0, central_differences=idn.CENTRAL, n_threads=1, **opts)
    return (time.thread_time() - t0) / r.evaluations, r.rms


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=None, metavar="LIB", help="another libtether_identify.so to compare with")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per record and build (best kept; default 5)")
    ap.add_argument("--only", default=None, help="only the records whose name contains this")
    a = ap.parse_args(argv)
    from bench_discovery_speed import _yardstick
    from tether import identify_native as idn
    from tether.resources import identify_library_candidates

    this_path = next(str(p) for p in identify_library_candidates() if p.is_file())
    builds = [("this", load_engine(this_path))]
    if a.baseline:
        builds.insert(0, ("baseline", load_engine(a.baseline)))
    yard = _yardstick()
    print(f"machine yardstick: one FMU simulation of the demo record {1e3 * yard:.1f} ms; "
          f"load average {os.getloadavg()[0]:.2f} at the start")
    print(f"{'record':20s} {'model':16s} {'samples':>7s} {'sims':>4s}  "
          + "  ".join(f"{label + ' us/sample':>19s}" for label, _ in builds)
          + ("  ratio  RMS baseline -> this" if a.baseline else "  RMS of the start"))
    folder = tempfile.mkdtemp(prefix="engine_sim_")
    for i, (name, experiment, effects, model, rate) in enumerate(RECORDS):
        if a.only and a.only not in name:
            continue
        exp, free, scaling, opts = build_record(name, experiment, effects, model, rate, 2000 + i, folder)
        best = {label: (float("inf"), 0.0) for label, _ in builds}
        for rep in range(a.repeats):
            for label, lib in (builds if rep % 2 == 0 else builds[::-1]):
                secs, rms = time_statistics(lib, exp, free, scaling, opts)
                best[label] = (min(best[label][0], secs), rms)
        n = len(exp.time)
        cells = "  ".join(f"{1e6 * best[label][0] / n:19.3f}" for label, _ in builds)
        if a.baseline:
            ratio = best["this"][0] / best["baseline"][0]
            tail = f"  {ratio:5.2f}  {best['baseline'][1]:.9g} -> {best['this'][1]:.9g}"
        else:
            tail = f"  {best['this'][1]:.9g}"
        print(f"{name:20s} {model:16s} {n:7d} {1 + 2 * len(free):4d}  {cells}{tail}", flush=True)
    idn._lib = None
    print(f"yardstick {1e3 * yard:.1f} ms; load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
