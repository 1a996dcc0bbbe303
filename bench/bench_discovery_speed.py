#!/usr/bin/env python3
"""Time one `tether discover` run on 10 s records at 200 Hz (2001 samples); not a CI test.

Issue 25 asks, on this 2-core machine, for at most 30 s per record of up to 4,000 samples and a
median of at most 10 s. The records come from the
independent generator of the tests (python_tests/hidden_effects.py) for the two experiments that
sample at 200 Hz, with no effect, each effect alone and the pairs that cost most, plus the bundled
demo record; each run goes through the command line, one after the other, as a user would run it.
Printed: per record the hidden and the named effects, rmse_final / noise, the wall and CPU time
and a machine yardstick measured just before it (one simulation of the demo record by the FMU),
then a table with each wall time scaled to a quiet machine (wall x quiet yardstick / yardstick of
the record) against the 30 s target, and the medians against the 10 s target.

    python bench/bench_discovery_speed.py [--out DIR] [--only SUBSTRING] [--names A,B] [--baseline TETHER|cache-off]

--baseline TETHER: also run another `tether` executable (an older checkout's command line) on each
record, in alternating order, and print both times (wall, and CPU of all threads, which a loaded
machine moves less) and whether the results agree: the same added_effects and rmse_final equal to
1e-6 relative (the check of a change meant to leave the results as they were); the medians and
largest times of both then stand beside one yardstick. --baseline cache-off: the baseline is this
checkout's command line with the engine's simulation cache off (docs/speed.md, 2026-11-29).
--tether TETHER: the executable to time (default: the one beside this Python). docs/speed.md has
the figures.
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

#: issue 25's targets: each record, and the median over the records [s]
TARGET_S, TARGET_MEDIAN_S = 30.0, 10.0
#: the yardstick on this machine when nothing else ran [s] (docs/speed.md; --quiet-yardstick-ms)
QUIET_YARDSTICK_S = 5.2e-3
CASES = [
    ("free_vibration", ()), ("free_vibration", ("nonlinear_stiffness",)), ("free_vibration", ("hysteresis",)),
    ("free_vibration", ("nonlinear_damping",)), ("free_vibration", ("slack",)),
    ("free_vibration", ("nonlinear_stiffness", "nonlinear_damping")), ("free_vibration", ("hysteresis", "slack")),
    ("forced", ()), ("forced", ("nonlinear_stiffness",)), ("forced", ("hysteresis",)),
    ("forced", ("nonlinear_damping",)), ("forced", ("hysteresis", "nonlinear_damping")),
]


def _yardstick() -> float:
    """Seconds of one FMU simulation of the demo record with the linear model (best of 5)."""
    from tether.run import simulate
    from tether.traces import read_trace

    tr = read_trace(REPO / "reference_results" / "discovery" / "freevib_hidden")
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        simulate(tr, "linear", {})
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None, help="directory for the records and results (default: a temporary one)")
    ap.add_argument("--only", default=None, help="run only the records whose name contains this")
    ap.add_argument("--names", default=None, help="run only these records, in this order (exact names, comma-separated)")
    ap.add_argument("--baseline", default=None, metavar="TETHER",
                    help="another tether executable to run on each record and compare with; 'cache-off': this "
                         "checkout's with the engine's simulation cache off")
    ap.add_argument("--tether", default=str(Path(sys.executable).with_name("tether")), metavar="TETHER",
                    help="the tether executable to time (default: the one beside this Python)")
    ap.add_argument("--quiet-yardstick-ms", type=float, default=1e3 * QUIET_YARDSTICK_S,
                    help="the yardstick of a quiet machine, which the wall times are scaled to [ms]")
    a = ap.parse_args(argv)
    out = Path(a.out or tempfile.mkdtemp(prefix="discovery_speed_"))
    records = speed_records(out, a.only)
    if a.names:
        by_name = {r[0]: r for r in records}
        records = [by_name[n] for n in a.names.split(",") if n in by_name]
    yard = _yardstick()
    print(f"machine yardstick: one FMU simulation of the demo record {1e3 * yard:.1f} ms; "
          f"load average {os.getloadavg()[0]:.2f} at the start\n")
    tether = a.tether
    if a.baseline:
        baseline = _cache_off_launcher(out) if a.baseline == CACHE_OFF else a.baseline
        return _compare(records, out, tether, baseline, yard)
    rows = []
    for name, stem, hidden in records:
        y = _yardstick()
        secs, doc, err, cpu = _discover(tether, stem, out / f"{name}.discovery.json")
        if doc is None:
            print(f"{name:36s} FAILED: {err}")
            continue
        rows.append((name, doc, secs, cpu, y))
        print(f"{name:36s} samples {doc['samples']:5d} hidden {hidden:34s} named "
              f"{','.join(doc['added_effects']) or '-':34s} rmse/noise {doc['rmse_final_over_noise']:5.2f} "
              f"wall {secs:6.1f} s CPU {cpu:6.1f} s yardstick {1e3 * y:.1f} ms", flush=True)
    if not rows:
        return 1
    _table(rows, 1e-3 * a.quiet_yardstick_ms)
    print(f"\n{len(rows)} runs: {_summary([r[2] for r in rows], yard)}; load average {os.getloadavg()[0]:.2f} at the end")
    return 0


#: --baseline's name for this checkout's tether with the engine's simulation cache off
CACHE_OFF = "cache-off"


def _cache_off_launcher(out: Path) -> str:
    """An executable in ``out`` that runs this checkout's command line with the engine's
    simulation cache off (identify_native.simulation_cache_bytes(0))."""
    path = out / "tether_cache_off"
    path.write_text(f"#!{sys.executable}\nimport sys\nsys.path.insert(0, {str(REPO / 'python')!r})\n"
                    "from tether import identify_native\nidentify_native.simulation_cache_bytes(0)\n"
                    "from tether.cli import main\nsys.exit(main())\n")
    path.chmod(0o755)
    return str(path)


def _table(rows: list, quiet: float) -> None:
    """Each record's wall time scaled to a quiet machine and its CPU time against the targets."""
    print(f"\n| record | samples | named | rmse/noise | wall s | CPU s | yardstick ms | wall scaled to "
          f"{1e3 * quiet:.1f} ms s | <= {TARGET_S:.0f} s (scaled) | <= {TARGET_S:.0f} s (CPU) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    scaled, cpus = [], []
    for name, doc, secs, cpu, y in rows:
        sc = secs * quiet / y
        scaled.append(sc)
        cpus.append(cpu)
        print(f"| {name} | {doc['samples']} | {','.join(doc['added_effects']) or '-'} | "
              f"{doc['rmse_final_over_noise']:.2f} | {secs:.1f} | {cpu:.1f} | {1e3 * y:.1f} | {sc:.1f} | "
              f"{'yes' if sc <= TARGET_S else 'NO'} | {'yes' if cpu <= TARGET_S else 'NO'} |")
    for label, v in (("wall scaled", scaled), ("CPU", cpus)):
        med = statistics.median(v)
        print(f"{label}: median {med:.1f} s (target <= {TARGET_MEDIAN_S:.0f} s: "
              f"{'met' if med <= TARGET_MEDIAN_S else 'NOT met'}); <= {TARGET_S:.0f} s on "
              f"{sum(x <= TARGET_S for x in v)} of {len(v)}; largest {max(v):.1f} s; total {sum(v):.0f} s")


def speed_records(out: Path, only: str | None = None) -> list[tuple[str, Path, str]]:
    """(name, trace stem, revealed effects) of the bench's records, the generated ones written to
    ``out``; only: those whose name contains it."""
    import hidden_effects as he

    out.mkdir(parents=True, exist_ok=True)
    records = [("demo_freevib_hidden", REPO / "reference_results" / "discovery" / "freevib_hidden", "nlstiff,slack")]
    for i, (exp, eff) in enumerate(CASES):
        name = f"{exp}_{'+'.join(e.split('_')[-1] for e in eff) or 'null'}"
        tr = he.generate(exp, set(eff), 1000 + i, rate=200.0, duration_s=10.0)
        tr.write(out, name)
        records.append((name, out / name, ",".join(sorted(tr.revealed)) or "-"))
    return [r for r in records if not only or only in r[0]]


def _discover(tether: str, stem: Path, res: Path):
    """(wall seconds, OUT.json document or None, error line, CPU seconds) of one `tether discover` run."""
    c0 = _children_cpu()
    t0 = time.perf_counter()
    p = subprocess.run([tether, "discover", str(stem), "--json", str(res)], capture_output=True, text=True)
    secs = time.perf_counter() - t0
    cpu = _children_cpu() - c0
    if p.returncode != 0:
        return secs, None, f"({p.returncode}) {p.stderr.strip().splitlines()[-1:]}", cpu
    return secs, json.loads(res.read_text()), "", cpu


def _children_cpu() -> float:
    """User + system CPU seconds of the finished child processes so far (all their threads)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _summary(times: list, yard: float) -> str:
    times = sorted(times)
    return (f"median {times[len(times) // 2]:.1f} s, largest {times[-1]:.1f} s (unscaled; targets <= "
            f"{TARGET_S:.0f} s each: {'met' if times[-1] <= TARGET_S else 'NOT met'}, median <= {TARGET_MEDIAN_S:.0f} s: "
            f"{'met' if times[len(times) // 2] <= TARGET_MEDIAN_S else 'NOT met'}); median / yardstick {times[len(times) // 2] / yard:.0f}, "
            f"largest / yardstick {times[-1] / yard:.0f}")


def _same(a: dict, b: dict, rel: float = 1e-6) -> bool:
    """The same named effects and rmse_final equal to ``rel`` relative."""
    ra, rb = float(a["rmse_final"]), float(b["rmse_final"])
    return a["added_effects"] == b["added_effects"] and abs(ra - rb) <= rel * max(abs(ra), abs(rb))


def _compare(records, out: Path, tether: str, baseline: str, yard: float) -> int:
    """Each record with the baseline and this checkout's tether, in alternating order."""
    times = {"baseline": [], "this": []}
    cpus = {"baseline": [], "this": []}
    agree = 0
    for i, (name, stem, hidden) in enumerate(records):
        runs = {}
        order = [("baseline", baseline), ("this", tether)]
        for label, exe in (order if i % 2 == 0 else order[::-1]):
            runs[label] = _discover(exe, stem, out / f"{name}.{label}.discovery.json")
        (tb, db, eb, cb), (tt, dt, et, ct) = runs["baseline"], runs["this"]
        if db is None or dt is None:
            print(f"{name:36s} FAILED: baseline {eb or 'ok'}; this {et or 'ok'}")
            continue
        times["baseline"].append(tb)
        times["this"].append(tt)
        cpus["baseline"].append(cb)
        cpus["this"].append(ct)
        same = _same(db, dt)
        agree += same
        rel = abs(db["rmse_final"] - dt["rmse_final"]) / max(abs(db["rmse_final"]), 1e-300)
        print(f"{name:36s} hidden {hidden:28s} named {','.join(dt['added_effects']) or '-':28s} "
              f"rmse/noise {dt['rmse_final_over_noise']:5.2f}  wall: baseline {tb:6.1f} s this {tt:6.1f} s "
              f"ratio {tt / tb:4.2f}  CPU: baseline {cb:6.1f} s this {ct:6.1f} s ratio {ct / cb:4.2f}  "
              f"{'same' if same else 'DIFFERENT'} (rmse_final rel. diff {rel:.1e}"
              f"{'' if db['added_effects'] == dt['added_effects'] else '; baseline named ' + ','.join(db['added_effects'])})",
              flush=True)
    if not times["this"]:
        return 1
    n = len(times["this"])
    print(f"\nyardstick {1e3 * yard:.1f} ms; {n} records")
    print(f"baseline: {_summary(times['baseline'], yard)}")
    print(f"this:     {_summary(times['this'], yard)}")
    for label in ("baseline", "this"):
        c = sorted(cpus[label])
        print(f"{label + ' CPU:':14s} median {c[len(c) // 2]:.1f} s, largest {c[-1]:.1f} s (user + system, all threads)")
    print("wall ratio this / baseline: median {:.2f}; CPU ratio: median {:.2f}".format(
        sorted(t / b for t, b in zip(times["this"], times["baseline"]))[n // 2],
        sorted(t / b for t, b in zip(cpus["this"], cpus["baseline"]))[n // 2]))
    print(f"results the same (added_effects, rmse_final to 1e-6) on {agree} of {n}; load average "
          f"{os.getloadavg()[0]:.2f} at the end")
    return 0 if agree == n else 1

if __name__ == "__main__":
    sys.exit(main())
