"""Start-up time of the command line: wall time of whole `tether` runs, median of N.

    .venv/bin/python bench/bench_cli_startup.py [--n 7]

Prints, for each command: the median wall time, the time Python spends importing (sum of the
top-level imports of `python -X importtime`), and which heavy modules were loaded. The target
(issue 26) is under 0.3 s where nothing needs scipy: `tether --help` and `tether simulate` of a
trace without an input to interpolate. A bare `python -c pass` is the floor.
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

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TETHER = Path(sys.executable).with_name("tether")
HEAVY = ("numpy", "scipy", "matplotlib", "fmpy", "tqdm")


def write_trace(folder: Path, name: str, experiment: str, n: int) -> Path:
    t = np.arange(n) * 1e-2
    meta = {"format": "tether-trace/1", "experiment": experiment, "tether": {"length_m": 16.0},
            "payload_mass_kg": 4.3}
    cols = {"time": t}
    if experiment == "forced":
        cols["force"] = 5.0 * np.sin(3.0 * t)
    cols["displacement"] = 0.01 * np.cos(14.0 * t)
    (folder / f"{name}.json").write_text(json.dumps(meta))
    with open(folder / f"{name}.csv", "w") as f:
        f.write(",".join(cols) + "\n")
        np.savetxt(f, np.column_stack(list(cols.values())), delimiter=",", fmt="%.17g")
    return folder / name


def wall(argv: list[str], n: int) -> tuple[float, float]:
    """Median (wall time, CPU time user + system) of ``n`` runs; CPU time shows the cost on a loaded
    machine, where the wall time also counts the waits for a core."""
    walls, cpus = [], []
    for _ in range(n):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        walls.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


def imports(args: list[str]) -> tuple[float, list[str]]:
    """(seconds of top-level imports, heavy modules loaded) of `python -X importtime -m tether ARGS`."""
    code = ("import sys; from tether.cli import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            f"print('HEAVY', *[m for m in {HEAVY!r} if m in sys.modules])")
    p = subprocess.run([sys.executable, "-X", "importtime", "-c", code, *args], capture_output=True, text=True)
    total = 0
    for line in p.stderr.splitlines():
        if not line.startswith("import time:"):
            continue
        _self, cumulative, name = line[len("import time:"):].split("|")
        if cumulative.strip().isdigit() and not name.startswith("  "):     # a top-level import (one space)
            total += int(cumulative)
    heavy = next((line.split()[1:] for line in p.stdout.splitlines() if line.startswith("HEAVY")), [])
    return total / 1e6, heavy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=7, help="runs per command (median)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        fv = write_trace(d, "fv", "free_vibration", 201)
        forced = write_trace(d, "forced", "forced", 201)
        out = d / "out.csv"
        cases = [
            ("python -c pass (the floor)", [sys.executable, "-c", "pass"], None),
            ("tether --help", [str(TETHER), "--help"], ["--help"]),
            ("tether --version", [str(TETHER), "--version"], ["--version"]),
            ("tether simulate free vibration (201 samples, no input)",
             [str(TETHER), "simulate", str(fv), "--out", str(out)], ["simulate", str(fv), "--out", str(out)]),
            ("tether simulate forced (201 samples, spline of the force: scipy)",
             [str(TETHER), "simulate", str(forced), "--out", str(out)],
             ["simulate", str(forced), "--out", str(out)]),
            ("tether simulate with a bad trace (exit 2)",
             [str(TETHER), "simulate", str(d / "missing"), "--out", str(out)],
             ["simulate", str(d / "missing"), "--out", str(out)]),
        ]
        load = os.getloadavg()[0]
        print(f"median of {args.n} runs, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, load average "
              f"{load:.2f} on {os.cpu_count()} cores")
        print(f"{'command':<66} {'wall [s]':>9} {'CPU [s]':>8} {'imports [s]':>12}  heavy modules loaded")
        for name, argv, cli_args in cases:
            w, c = wall(argv, args.n)
            if cli_args is None:
                print(f"{name:<66} {w:>9.3f} {c:>8.3f}")
                continue
            imp, heavy = imports(cli_args)
            print(f"{name:<66} {w:>9.3f} {c:>8.3f} {imp:>12.3f}  {' '.join(heavy) or '-'}")


if __name__ == "__main__":
    main()
