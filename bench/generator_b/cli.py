"""`python -m bench.generator_b --n 48 --seed S --out DIR`: draw a suite and write its traces."""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import sys
import time
from pathlib import Path

from .draw import suite
from .experiments import generate
from .traceio import write_trace

HELD_OUT_SEED = 2026     # the draw kept for measuring; never look at it while tuning
OPEN_SEED = 7            # a draw anyone may look at


def write_suite(specs: list[dict], out: Path, progress=sys.stderr) -> list[Path]:
    """Generate and write every spec; a line of progress per trace. Returns the stems."""
    out = Path(out)
    stems, start = [], time.perf_counter()
    for i, spec in enumerate(specs, 1):
        t0 = time.perf_counter()
        columns, meta = generate(copy.deepcopy(spec))
        stems.append(write_trace(out, spec["name"], columns, meta))
        if progress is not None:
            print(f"[{i}/{len(specs)}] {spec['name']}: {len(columns['time'])} samples, "
                  f"{time.perf_counter() - t0:.1f} s", file=progress, flush=True)
    manifest = {"generator": "generator_b/1", "suite_seed": specs[0].get("suite_seed") if specs else None,
                "traces": [s["name"] for s in specs],
                "seconds": round(time.perf_counter() - start, 1)}
    # not *.json: a runner that globs the traces must not take the manifest for one
    (out / "suite.manifest").write_text(json.dumps(manifest, indent=1) + "\n")
    return stems


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.generator_b", description=__doc__)
    ap.add_argument("--n", type=int, default=48, help="number of traces (default 48)")
    ap.add_argument("--seed", type=int, default=OPEN_SEED,
                    help=f"seed of the draw (default {OPEN_SEED}; {HELD_OUT_SEED} is the held-out draw)")
    ap.add_argument("--out", type=Path, required=True, help="directory for NAME.csv + NAME.json")
    args = ap.parse_args(argv)
    if args.n < 1:
        ap.error(f"--n must be at least 1, got {args.n}")
    if args.out.exists() and (not args.out.is_dir() or any(args.out.iterdir())):
        ap.error(f"--out {args.out} exists and is not an empty directory; choose a new one")
    partial = args.out.with_name(args.out.name + ".part")
    if partial.exists():
        ap.error(f"{partial} is left from an interrupted run; remove it first")
    start = time.perf_counter()
    try:
        write_suite(suite(args.n, args.seed), partial)
    except BaseException:
        shutil.rmtree(partial, ignore_errors=True)     # all the traces or none
        raise
    if args.out.exists():
        args.out.rmdir()
    partial.rename(args.out)
    print(f"wrote {args.n} traces (seed {args.seed}) to {args.out} in {time.perf_counter() - start:.1f} s")
    return 0
