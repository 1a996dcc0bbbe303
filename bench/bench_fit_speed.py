#!/usr/bin/env python3
"""Time `tether fit` of a 10 s record at 1 kHz (issue 25's speed figure); not a CI test.

The record is the free vibration of bench_fit_full.py (the `full` model: cubic + Bouc-Wen +
displacement damping, m = 4.3 kg, L0 = 16 m, x0 = -0.1669 m, 10,001 samples, Gaussian noise of
0.1 mm), simulated by the engine and written as a trace. Each run goes through the command line,
as a user would run it: `tether fit REC --model full --out P.json`. Printed: the wall time of
every run, their median, the fitted RMS and the machine yardstick of bench_discovery_speed.py
measured in the same run, so that figures from a loaded machine compare as ratios.

    python bench/bench_fit_speed.py [--runs 3] [--out DIR] [--profile FILE.prof] [--baseline TETHER] [--tether TETHER]

--profile runs the fit once more in this process under cProfile and writes the statistics there
(read them with `python -m pstats FILE.prof`).
--baseline TETHER: another `tether` executable (an older checkout's command line) runs beside this
one, in alternating order, with wall and CPU times of both; then both fit every bundled record
(reference_results/*: the model that generated it; datasets/boucwen/train_multisine:
linear+boucwen) and the fitted parameter files are compared: the same values to 1e-6 relative,
and whether they are the same bits (the check of a change meant to leave results as they were);
else whether every value of this one lies inside the baseline's 95 % interval, and how far it
moved in half widths of that interval (the check of a change meant to move results within the
integration tolerance).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

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


def run_cli(stem: Path, out: Path, tether: str | None = None, model: str = MODEL) -> tuple[float, dict, float]:
    """(wall seconds, the fitted parameter file, CPU seconds of the run) of one `tether fit`."""
    tether = tether or str(Path(sys.executable).with_name("tether"))
    c0 = _children_cpu()
    t0 = time.perf_counter()
    p = subprocess.run([tether, "-q", "fit", str(stem), "--model", model, "--out", str(out)],
                       capture_output=True, text=True)
    secs = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{tether} fit {stem.name} failed ({p.returncode}): {p.stderr.strip()}")
    return secs, json.loads(out.read_text()), _children_cpu() - c0


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def bundled_records() -> list[tuple[Path, str]]:
    """(stem, model) of every bundled record: the reference results with the model that made them,
    the Bouc-Wen benchmark's training record with linear+boucwen."""
    out = []
    for meta in sorted((REPO / "reference_results").glob("*.json")):
        doc = json.loads(meta.read_text())
        model = (doc.get("synthetic") or {}).get("model")
        if doc.get("format") == "tether-trace/1" and model:
            out.append((meta.with_suffix(""), model))
    out.append((REPO / "datasets" / "boucwen" / "train_multisine", "linear+boucwen"))
    return out


def _agree(a: dict, b: dict, rel: float = 1e-6) -> tuple[bool, bool]:
    """(every fitted value and the RMS equal to ``rel`` relative, the same bits)."""
    keys = set(a["parameters"]) | set(b["parameters"])
    pairs = [(a["rms"], b["rms"])] + [(a["parameters"].get(k), b["parameters"].get(k)) for k in keys]
    close = all(x is not None and y is not None and abs(x - y) <= rel * max(abs(x), abs(y)) for x, y in pairs)
    return close, a["parameters"] == b["parameters"] and a["rms"] == b["rms"]


def _moves(a: dict, b: dict) -> tuple[bool, float, float]:
    """(every fitted value of ``b`` inside ``a``'s 95 % interval, the largest move of a fitted value
    in units of the half width of a's interval, the RMS's relative change): the check of a change
    meant to move results within the integration tolerance. A value without an interval (not fitted)
    must be the same."""
    inside, worst = True, 0.0
    for k, va in a["parameters"].items():
        vb = b["parameters"].get(k)
        lo_hi = (a.get("intervals") or {}).get(k)
        if vb is None:
            return False, float("inf"), float("inf")
        if lo_hi is None:
            inside &= va == vb
            continue
        lo, hi = lo_hi
        inside &= lo <= vb <= hi
        half = 0.5 * (hi - lo)
        if vb != va:
            worst = max(worst, abs(vb - va) / half if half > 0 else float("inf"))
    return inside, worst, abs(b["rms"] - a["rms"]) / a["rms"]


def compare(stem: Path, out: Path, tether: str, baseline: str, runs: int, yard: float) -> int:
    """tether fit against the baseline's: times, then the bundled records' results."""
    got = {"baseline": [], "this": []}
    for i in range(runs):
        order = [("baseline", baseline), ("this", tether)]
        for label, exe in (order if i % 2 == 0 else order[::-1]):
            secs, doc, cpu = run_cli(stem, out / f"{label}{i}.json", exe)
            got[label].append((secs, cpu, doc))
            print(f"run {i + 1} {label:8s}: {secs:6.2f} s wall, {cpu:6.2f} s CPU, RMS {doc['rms']:.9g}", flush=True)
    med = {k: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v)) for k, v in got.items()}
    for k, (w, c) in med.items():
        print(f"{k:8s}: median {w:.2f} s wall ({w / yard:.0f} yardsticks), {c:.2f} s CPU")
    print(f"this / baseline: wall {med['this'][0] / med['baseline'][0]:.2f}, CPU {med['this'][1] / med['baseline'][1]:.2f}")
    same = inside = 0
    records = bundled_records()
    print(f"\n`tether fit` of the {len(records)} bundled records, baseline and this (CPU seconds; a fitted "
          "value's move in half widths of the baseline's 95 % interval):")
    for rec, model in records:
        tb, db, cb = run_cli(rec, out / f"{rec.name}.baseline.json", baseline, model)
        tt, dt, ct = run_cli(rec, out / f"{rec.name}.this.json", tether, model)
        close, bits = _agree(db, dt)
        within, worst, rms_move = _moves(db, dt)
        same += close
        inside += within
        verdict = "same bits" if bits else "equal to 1e-6" if close else "within the intervals" if within else "OUTSIDE"
        print(f"{rec.name:28s} {model:18s} RMS {db['rms']:.6g} -> {dt['rms']:.6g} ({rms_move:.1e})  "
              f"CPU {cb:6.1f} -> {ct:6.1f} s ({ct / cb:.2f})  largest move {worst:.2g}  {verdict}", flush=True)
    print(f"results the same (1e-6) on {same} of {len(records)}; within the baseline's intervals on {inside}")
    return 0 if inside == len(records) else 1


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
    ap.add_argument("--baseline", default=None, metavar="TETHER", help="another tether executable to compare with")
    ap.add_argument("--tether", default=str(Path(sys.executable).with_name("tether")), metavar="TETHER",
                    help="the tether executable to time (default: the one beside this Python)")
    a = ap.parse_args(argv)
    from bench_discovery_speed import _yardstick

    out = Path(a.out or tempfile.mkdtemp(prefix="fit_speed_"))
    out.mkdir(parents=True, exist_ok=True)
    stem = write_record(out)
    yard = _yardstick()
    print(f"machine yardstick: one FMU simulation of the demo record {1e3 * yard:.1f} ms; "
          f"load average {os.getloadavg()[0]:.2f} at the start")
    if a.baseline:
        return compare(stem, out, a.tether, a.baseline, a.runs, yard)
    times = []
    for i in range(a.runs):
        secs, doc, _cpu = run_cli(stem, out / f"fit{i}.json", a.tether)
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
