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

With ``--suite [PYTEST ARGS...]`` it runs pytest instead (default: python_tests) and prints each
test's wall time beside its CPU time (this process, all its threads, and its children): the CPU
seconds change little with what else runs on the machine, the wall seconds do. The slowest tests
first (``--top N``), then the totals and the load average before and after (docs/test-suite-time.md).

    python bench/bench_test_timings.py --suite [--top N] [--jsonl FILE] [-- PYTEST ARGS...]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
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


def cpu_seconds() -> float:
    """CPU seconds of this process (all threads) and of its children that have ended."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


class TestClock:
    """A pytest plugin: wall and CPU seconds of each test, its setup and teardown included (a
    module fixture's work is counted in the first test that uses it)."""

    def __init__(self):
        self.started: dict[str, tuple[float, float]] = {}
        self.rows: list[dict] = []

    def pytest_runtest_logstart(self, nodeid, location):
        self.started[nodeid] = (time.perf_counter(), cpu_seconds())

    def pytest_runtest_logfinish(self, nodeid, location):
        wall0, cpu0 = self.started.pop(nodeid)
        self.rows.append({"test": nodeid, "wall_s": time.perf_counter() - wall0, "cpu_s": cpu_seconds() - cpu0,
                          "load1": os.getloadavg()[0]})


def suite(pytest_args: list[str], top: int, jsonl: Path | None) -> int:
    import pytest

    clock = TestClock()
    load_before = os.getloadavg()
    wall0, cpu0 = time.perf_counter(), cpu_seconds()
    status = pytest.main(["-q", "-p", "no:cacheprovider", *(pytest_args or [str(TESTS)])], plugins=[clock])
    wall, cpu = time.perf_counter() - wall0, cpu_seconds() - cpu0
    rows = sorted(clock.rows, key=lambda r: -r["wall_s"])
    if jsonl is not None:
        jsonl.write_text("".join(json.dumps(r) + "\n" for r in clock.rows))
    print(f"\n{'wall [s]':>9s} {'CPU [s]':>8s}  test (slowest {min(top, len(rows))} of {len(rows)} by wall time)")
    for r in rows[:top]:
        print(f"{r['wall_s']:9.1f} {r['cpu_s']:8.1f}  {r['test']}")
    print(f"total: {wall:.0f} s wall, {cpu:.0f} s CPU, {len(rows)} tests, pytest exit {int(status)}; load average "
          f"(1, 5, 15 min) before {', '.join(f'{x:.2f}' for x in load_before)}, after "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return int(status)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (the best is printed beside the median)")
    ap.add_argument("--suite", action="store_true", help="time the tests instead: pytest with each test's wall and "
                                                         "CPU seconds (arguments after -- go to pytest)")
    ap.add_argument("--top", type=int, default=30, help="--suite: the slowest N tests printed (default 30)")
    ap.add_argument("--jsonl", type=Path, help="--suite: every test's figures, one JSON object a line")
    args, rest = ap.parse_known_args()
    if args.suite:
        return suite([a for a in rest if a != "--"], args.top, args.jsonl)
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
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
