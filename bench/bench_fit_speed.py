#!/usr/bin/env python3
"""Time `tether fit` of a 10 s record at 1 kHz (issue 25's speed figure); not a CI test.

The record is the free vibration of bench_fit_full.py (the `full` model: cubic + Bouc-Wen +
displacement damping, m = 4.3 kg, L0 = 16 m, x0 = -0.1669 m, 10,001 samples, Gaussian noise of
0.1 mm), simulated by the engine and written as a trace. Each run goes through the command line,
as a user would run it: `tether fit REC --model full --out P.json`. Printed: the wall time of
every run, their median, the fitted RMS and the machine yardstick of bench_discovery_speed.py
measured in the same run, so that figures from a loaded machine compare as ratios.

    python bench/bench_fit_speed.py [--runs 3] [--out DIR] [--profile FILE.prof]

--profile runs the fit once more in this process under cProfile and writes the statistics there
(read them with `python -m pstats FILE.prof`).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "python"))
sys.path.insert(0, str(REPO / "bench"))

MODEL = "full"
NAME = "freevib_full_10s_1khz"


def write_record(folder: Path) -> Path:
    """The 10 s, 1 kHz free-vibration record of bench_fit_full.py as NAME.csv + NAME.json."""
    import numpy as np

    from bench_fit_full import G, L0, M, X0, problem

    t, e, _start, _bounds = problem(seed=1)
    stem = folder / NAME
    np.savetxt(stem.with_suffix(".csv"), np.column_stack([t, e.measured]), delimiter=",",
               header="time,displacement", comments="", fmt="%.10g")
    meta = {"format": "tether-trace/1", "experiment": "free_vibration",
            "tether": {"length_m": L0, "diameter_mm": 1.5}, "payload_mass_kg": M, "gravity_m_s2": G,
            "initial_displacement_m": X0, "initial_velocity_m_s": 0.0,
            "description": "SYNTHETIC: bench/bench_fit_speed.py (the record of bench/bench_fit_full.py)"}
    stem.with_suffix(".json").write_text(json.dumps(meta, indent=1))
    return stem


def run_cli(stem: Path, out: Path) -> tuple[float, dict]:
    tether = str(Path(sys.executable).with_name("tether"))
    t0 = time.perf_counter()
    p = subprocess.run([tether, "-q", "fit", str(stem), "--model", MODEL, "--out", str(out)],
                       capture_output=True, text=True)
    secs = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"tether fit failed ({p.returncode}): {p.stderr.strip()}")
    return secs, json.loads(out.read_text())


def profile(stem: Path, path: Path) -> None:
    import cProfile

    from tether.cli import main

    out = path.with_suffix(".params.json")
    cProfile.runctx("main(['-q', 'fit', str(stem), '--model', MODEL, '--out', str(out)])", globals(),
                    {"main": main, "stem": stem, "MODEL": MODEL, "out": out}, str(path))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3, help="command-line runs to time (default 3)")
    ap.add_argument("--out", default=None, help="directory for the record and results (default: a temporary one)")
    ap.add_argument("--profile", default=None, metavar="FILE.prof", help="also profile one run in-process")
    a = ap.parse_args(argv)
    from bench_discovery_speed import _yardstick

    out = Path(a.out or tempfile.mkdtemp(prefix="fit_speed_"))
    out.mkdir(parents=True, exist_ok=True)
    stem = write_record(out)
    yard = _yardstick()
    print(f"machine yardstick: one FMU simulation of the demo record {1e3 * yard:.1f} ms; "
          f"load average {os.getloadavg()[0]:.2f} at the start")
    times = []
    for i in range(a.runs):
        secs, doc = run_cli(stem, out / f"fit{i}.json")
        times.append(secs)
        print(f"run {i + 1}: {secs:6.2f} s wall, RMS {doc['rms']:.9g}", flush=True)
    med = statistics.median(times)
    print(f"`tether fit {NAME} --model {MODEL}`: median {med:.2f} s over {len(times)} runs; "
          f"median / yardstick {med / yard:.0f}; load average {os.getloadavg()[0]:.2f} at the end")
    if a.profile:
        profile(stem, Path(a.profile))
        print(f"profile: {a.profile}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
