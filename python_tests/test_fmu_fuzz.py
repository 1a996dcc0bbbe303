"""The FMU under sanitizers, built from its own sources/ (fuzz/build_fuzz.py):

- a fixed-seed fuzz campaign under AddressSanitizer, LeakSanitizer and UBSan: random FMI call
  sequences (every fmi2 function, both interfaces, hostile values, NULL and foreign components,
  out-of-order calls) with FMU states serialized, mutated and restored (fuzz/fmu_fuzz.c). Any
  sanitizer report, crash or leak fails the test. bench/fuzz_fmu.py runs the long campaign.
- ThreadSanitizer: eight instances of five models simulated in eight threads at once, with states
  saved and restored, bit-identical to the same runs made one after the other (fuzz/fmu_threads.c).

The builds are cached in build/fuzz/ (rebuilt when the FMU or a driver changes).
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import pytest

import fmu_harness as H

FUZZ_SEED, FUZZ_SEQUENCES = 27, 30_000
SANITIZER_MARKS = ("ERROR: AddressSanitizer", "ERROR: LeakSanitizer", "runtime error", "WARNING: ThreadSanitizer",
                   "FINDING", "SUMMARY:")


def build(sanitize: str, driver: str) -> str:
    if not shutil.which("gcc"):
        pytest.fail("gcc is needed to build the sanitizer drivers", pytrace=False)
    r = subprocess.run([sys.executable, str(H.REPO / "fuzz" / "build_fuzz.py"), str(H.require_fmu()),
                        str(H.REPO / "build" / "fuzz"), "--sanitize", sanitize, "--driver", driver],
                       capture_output=True, text=True)
    assert r.returncode == 0, f"building {driver} with -fsanitize={sanitize} failed:\n{r.stderr[-3000:]}"
    return r.stdout.strip().splitlines()[-1]


def run(exe: str, *args: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([exe, *args], capture_output=True, text=True, env=dict(os.environ, **env))


def reports(r: subprocess.CompletedProcess) -> list[str]:
    return [ln for ln in (r.stdout + r.stderr).splitlines() if any(m in ln for m in SANITIZER_MARKS)]


def test_fixed_seed_fuzz_campaign_under_asan_ubsan_lsan():
    exe = build("address,undefined,float-cast-overflow", "fmu_fuzz.c")
    r = run(exe, str(FUZZ_SEED), str(FUZZ_SEQUENCES),
            env={"ASAN_OPTIONS": "detect_leaks=1:halt_on_error=1", "UBSAN_OPTIONS": "halt_on_error=1:print_stacktrace=1"})
    print(r.stdout.strip())
    assert r.returncode == 0 and not reports(r), f"exit {r.returncode}; " + "\n".join(reports(r) or [r.stderr[-3000:]])
    assert f"fmu_fuzz: {FUZZ_SEQUENCES} sequences" in r.stdout
    # the campaign reaches the deep states, not only the refusals
    steps, restored = (int(re.search(r"(\d+) " + w, r.stdout).group(1)) for w in ("steps OK", "restored"))
    assert steps > 1000 and restored > 1000, r.stdout


def test_instances_in_threads_are_race_free_and_bit_identical_to_serial():
    exe = build("thread", "fmu_threads.c")
    r = run(exe, "8", env={"TSAN_OPTIONS": "halt_on_error=1"})
    print(r.stdout.strip())
    assert r.returncode == 0 and not reports(r), f"exit {r.returncode}; " + "\n".join(reports(r) or [r.stderr[-3000:]])
    assert "bit-identical to serial" in r.stdout
