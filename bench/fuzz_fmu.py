#!/usr/bin/env python3
"""Fuzz campaign of the FMU under AddressSanitizer, LeakSanitizer and UBSan; prints the count and
every finding.

    .venv/bin/python bench/fuzz_fmu.py [--sequences 1000000] [--seed 2026] [--chunk 20000] [--jobs 1]

Builds fuzz/fmu_fuzz.c with the FMU's own sources/ (fuzz/build_fuzz.py, build/fuzz/), then runs
the sequences in chunks, each chunk a process (so that a finding stops one chunk, not the
campaign, and leaks are checked at each chunk's exit). Every sequence mixes random FMI calls with
serialized states that are mutated and restored. A chunk that ends in a sanitizer report, a crash,
a leak or a time-out is a finding: its replay command and the sanitizer's summary are printed.
Exit status 1 if there was any finding.
"""
import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SAN_ENV = {"ASAN_OPTIONS": "detect_leaks=1:halt_on_error=1:abort_on_error=0",
           "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1"}


def build(fmu: Path) -> Path:
    out = subprocess.run([sys.executable, str(REPO / "fuzz" / "build_fuzz.py"), str(fmu), str(REPO / "build" / "fuzz")],
                         capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"fuzz_fmu: building the fuzzer failed:\n{out.stderr}")
    return Path(out.stdout.strip().splitlines()[-1])


def run_chunk(exe: Path, seed: int, first: int, count: int, timeout: float):
    env = dict(os.environ, **SAN_ENV)
    try:
        r = subprocess.run([str(exe), str(seed), str(count), str(first)], capture_output=True, text=True,
                           timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return first, count, None, f"time-out after {timeout:.0f} s (sequences {first}..{first + count - 1})"
    report = [ln for ln in r.stderr.splitlines()
              if "FINDING" in ln or "SUMMARY" in ln or "runtime error" in ln or "ERROR:" in ln]
    if r.returncode != 0 or report or "fmu_fuzz:" not in r.stdout:
        return first, count, None, f"exit {r.returncode}: " + (" | ".join(report) or r.stderr.strip()[-500:])
    return first, count, r.stdout.strip(), None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--chunk", type=int, default=20_000)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per chunk")
    ap.add_argument("--fmu", type=Path, default=REPO / "build" / "KevlarTether.fmu")
    a = ap.parse_args()
    exe = build(a.fmu)
    print(f"fuzz_fmu: {exe}, seed {a.seed}, {a.sequences} sequences in chunks of {a.chunk}", flush=True)
    chunks = [(f, min(a.chunk, a.sequences - f)) for f in range(0, a.sequences, a.chunk)]
    done = calls = 0
    findings = []
    t0 = time.monotonic()
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(run_chunk, exe, a.seed, f, n, a.timeout) for f, n in chunks]
        for fut in futures:
            first, count, summary, finding = fut.result()
            done += count
            if finding:
                findings.append(finding)
                print(f"fuzz_fmu: FINDING in sequences {first}..{first + count - 1}: {finding}", flush=True)
            else:
                calls += int(summary.split(" sequences, ")[1].split(" calls")[0])
            print(f"fuzz_fmu: {done}/{a.sequences} sequences, {calls} calls, {len(findings)} findings, "
                  f"{time.monotonic() - t0:.0f} s", flush=True)
    print(f"fuzz_fmu: done: {done} sequences with state mutation, {calls} FMI calls, "
          f"{len(findings)} findings, {time.monotonic() - t0:.0f} s")
    for f in findings:
        print(f"  finding: {f}")
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
