#!/usr/bin/env python3
"""What the regimes' amplitude envelope costs a discovery: scipy.ndimage's maximum_filter1d (with
its import) against tether.discover.evidence.running_max; not a CI test.

Printed: the CPU seconds of `import scipy.ndimage` in a fresh process that has already loaded what
a discovery loads (numpy, scipy.linalg), median of --runs processes; the CPU per call of both
envelopes on records of 2,001 and 100,001 samples with a window of one period (best of 5); and
whether they agree bit for bit. docs/speed.md has the figures.

    python bench/bench_evidence_envelope.py [--runs N]
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

IMPORT = ("import time, numpy, scipy.linalg\n"
          "t0 = time.process_time()\n"
          "import scipy.ndimage\n"
          "print(time.process_time() - t0)\n")


def _call_cpu(f, *args) -> float:
    best = float("inf")
    for _ in range(5):
        t0 = time.process_time()
        f(*args)
        best = min(best, time.process_time() - t0)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="fresh processes for the import (default 5)")
    a = ap.parse_args(argv)
    imports = [float(subprocess.run([sys.executable, "-c", IMPORT], capture_output=True, text=True,
                                    check=True).stdout) for _ in range(a.runs)]
    print(f"import scipy.ndimage after numpy and scipy.linalg: CPU median {statistics.median(imports):.3f} s "
          f"(of {a.runs} processes: {', '.join(f'{x:.3f}' for x in imports)})")
    from scipy.ndimage import maximum_filter1d

    from tether.discover.evidence import running_max

    rng = np.random.default_rng(0)
    for n, w in ((2001, 40), (100001, 400)):
        t = np.arange(n) * 5e-3
        v = np.abs(np.exp(-t / t[-1]) * np.sin(2 * np.pi * t) + 1e-3 * rng.standard_normal(n))
        same = np.array_equal(running_max(v, w), maximum_filter1d(v, size=w))
        print(f"{n} samples, window {w}: maximum_filter1d {1e3 * _call_cpu(maximum_filter1d, v, w):.3f} ms, "
              f"running_max {1e3 * _call_cpu(running_max, v, w):.3f} ms per call (CPU, best of 5); "
              f"{'the same bits' if same else 'DIFFERENT'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
