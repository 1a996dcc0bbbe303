#!/usr/bin/env python3
"""Benchmark: the wall times the tests used to assert, printed instead.

The tests once failed on a loaded machine on these limits; a test checks behaviour, this script
measures speed. It prints each figure beside the limit the test asserted then:

* the independent generator's 48-trace suite (python_tests/hidden_effects.py, ``suite(n=48)``),
  formerly ``elapsed < 30 s`` in test_hidden_effects.test_suite_composition;
* the generator's command line writing 6 traces, formerly a subprocess timeout of 120 s in
  test_hidden_effects.test_cli_writes_suite;
* ``fmutool -check`` of build/KevlarTether.fmu, formerly a timeout of 120 s in
  test_fmu_conformance.test_fmutool_check;
* a fresh interpreter importing the generator, formerly a timeout of 60 s in
  test_hidden_effects.test_no_team_model_imported.

    python bench/bench_test_timings.py [--repeat N]
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TESTS = REPO / "python_tests"


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def run(cmd: list[str]) -> None:
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)}: exit {r.returncode}: {r.stderr.strip()[-300:]}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (the best is printed beside the median)")
    args = ap.parse_args()
    sys.path.insert(0, str(TESTS))
    import hidden_effects as he  # noqa: E402

    tmp = Path(tempfile.mkdtemp(prefix="bench-timings-"))
    fmu = Path(os.environ.get("KT_FMU", REPO / "build" / "KevlarTether.fmu"))
    fmutool = shutil.which("fmutool") or str(Path(sys.executable).parent / "fmutool")
    cases = [
        ("hidden_effects.suite(n=48)", 30.0, lambda: he.suite(n=48, seed=0)),
        ("hidden_effects.py CLI, 6 traces", 120.0,
         lambda: run([sys.executable, str(TESTS / "hidden_effects.py"), str(tmp / "traces"), "--n", "6"])),
        ("fresh interpreter: import + 1 forced trace", 60.0,
         lambda: run([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(TESTS)!r}); import hidden_effects as he; "
                      "he.generate('forced', frozenset(['hysteresis']), 1, rate=100.0)"])),
    ]
    if fmu.is_file() and Path(fmutool).exists():
        cases.append(("fmutool -check", 120.0, lambda: run([fmutool, "-input", str(fmu), "-check"])))
    print(f"{'what':45s} {'best [s]':>9s} {'median [s]':>11s} {'former test limit [s]':>22s}")
    try:
        for name, limit, fn in cases:
            times = sorted(timed(fn) for _ in range(max(1, args.repeat)))
            print(f"{name:45s} {times[0]:9.2f} {times[len(times) // 2]:11.2f} {limit:22.0f}", flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
