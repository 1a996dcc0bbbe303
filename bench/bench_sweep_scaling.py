"""The issue-28 sweep (64 full-model runs, --vary a1=900:1500:8 --vary c0=1:5:8, on
reference_results/freevib_full_0p1184) on a local Dask cluster of one worker and of two: prints the
times, their ratio (target >= 1.5 x on two cores), and the scheduler's overhead per task, with a
machine yardstick measured in the same run (one simulation of the sweep's first run, best of 5, and
the 64 runs one after another in this process), so that figures from a loaded or slower machine can
be compared as ratios.

Each timing starts once the cluster is up and its workers hold the FMU (a first, untimed sweep
warms them), and ends when the last row is written: what a sweep costs beyond starting Dask.

--spawned runs `dask scheduler` and `dask worker` processes, each in a session of its own, in place
of the local cluster (whose workers share this session). Where the kernel shares the CPU between
sessions (autogroup) and other sessions keep the machine busy, each spawned worker gets a session's
part of it: the ratio then measures that sharing, not the cluster (docs/scale.md). Hold a quiet
machine's local-cluster figure against the target.

    python bench/bench_sweep_scaling.py [--grid 8] [--repeat 3] [--tasks 2000] [--spawned]
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()


def _noop(x):
    return x


def plain_pair(grid: int) -> list[float]:
    """The serial loop in two plain processes started together (no Dask): what two cores give."""
    import subprocess

    at = time.time() + 5.0
    cmd = [sys.executable, __file__, "--grid", str(grid), "--loop-at", str(at)]
    procs = [subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True) for _ in range(2)]
    return [float(p.communicate()[0].split()[-1]) for p in procs]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", type=int, default=8, help="points per axis (default 8: 64 runs)")
    ap.add_argument("--repeat", type=int, default=3, help="timed sweeps per cluster size (the best is kept)")
    ap.add_argument("--tasks", type=int, default=2000, help="empty tasks for the overhead per task")
    ap.add_argument("--spawned", action="store_true",
                    help="dask scheduler and workers as processes of their own sessions, not a local cluster")
    ap.add_argument("--loop-at", type=float, help=argparse.SUPPRESS)   # one plain serial loop, from this time
    args = ap.parse_args()

    import psutil

    from tether.campaign import dask_client, spawned_cluster

    @contextlib.contextmanager
    def cluster(workers: int, tmp: Path, spawned: bool):
        if not spawned:
            with dask_client(None, workers) as client:
                yield client
            return
        folder = tmp / f"cluster_{workers}"
        folder.mkdir()
        with spawned_cluster(folder, workers) as address, dask_client(address) as client:
            yield client
    from tether.sweep import execute, grid_plan, run_one
    from tether.sweep_output import RowsFile
    from tether.traces import read_trace

    trace = read_trace(REPO / "reference_results" / "freevib_full_0p1184")
    g = args.grid
    plan = grid_plan(trace, "full", {}, [f"a1=900:1500:{g}", f"c0=1:5:{g}"])
    n = len(plan.runs)

    def one(i):
        return run_one(plan.trace, plan.model, plan.base, dict(zip(plan.names, plan.runs[i])))

    one(0)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        one(0)
        best = min(best, time.perf_counter() - t0)
    if args.loop_at is not None:
        time.sleep(max(0.0, args.loop_at - time.time()))
    t0 = time.perf_counter()
    for i in range(n):
        one(i)
    serial = time.perf_counter() - t0
    if args.loop_at is not None:
        print(f"{serial:.4f}")
        return 0
    pair = plain_pair(args.grid)
    print(("spawned dask scheduler and workers" if args.spawned else "local cluster") + f", {n} runs")
    print(f"machine yardstick: one run {1e3 * best:.1f} ms (best of 5); {n} runs one after another in this "
          f"process {serial:.2f} s; load average {os.getloadavg()[0]:.2f}; {os.cpu_count()} cores")
    print(f"the machine's ceiling: two plain processes running the {n} runs at once take {pair[0]:.2f} and "
          f"{pair[1]:.2f} s: {2 * serial / max(pair):.2f} x the work of one in the same time")

    trials: dict = {1: [], 2: []}
    overhead = {}
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        clients = {w: stack.enter_context(cluster(w, Path(tmp), args.spawned)) for w in (1, 2)}

        def sweep(workers: int, k: int) -> float:
            rows = RowsFile(Path(tmp) / f"rows_{workers}_{k}.csv", plan.columns, plan.fingerprint())
            rows.start()
            t0 = time.perf_counter()
            execute(plan, clients[workers], rows, list(range(n)), seconds_per_run=best)
            dt = time.perf_counter() - t0
            rows.finish()
            return dt

        for workers in (1, 2):                                  # warm the workers, untimed
            sweep(workers, 0)
        for k in range(1, args.repeat + 1):                     # interleaved: a load that changes hits both
            for workers in (1, 2):
                trials[workers].append(sweep(workers, k))
        for workers, client in clients.items():
            # the cost per task: empty tasks, submitted at once, waited for; wall time, and the CPU
            # time of this process (client and scheduler) and of the workers, which a loaded
            # machine does not inflate as it does the wall time
            client.gather(client.map(_noop, range(200), pure=False))
            procs = [psutil.Process(pid) for pid in client.run(os.getpid).values()]
            sched = client.run_on_scheduler(os.getpid)
            here = [psutil.Process()] + ([psutil.Process(sched)] if sched != os.getpid() else [])

            def cpu(ps):
                return sum(sum(p.cpu_times()[:2]) for p in ps)

            w0, c0, t0 = cpu(procs), cpu(here), time.perf_counter()
            client.gather(client.map(_noop, range(args.tasks), pure=False))
            overhead[workers] = ((time.perf_counter() - t0) / args.tasks, (cpu(here) - c0) / args.tasks,
                                 (cpu(procs) - w0) / args.tasks)
        files = {p.read_bytes() for p in Path(tmp).glob("rows_*.csv")}
    times = {w: min(t) for w, t in trials.items()}
    for w in (1, 2):
        wall, cpu_here, cpu_workers = overhead[w]
        print(f"{w} worker{'s' if w > 1 else ' '}: sweep of {n} runs {times[w]:.2f} s (best of {args.repeat}: "
              f"{', '.join(f'{t:.2f}' for t in trials[w])}); per empty task ({args.tasks}): {1e3 * wall:.2f} ms "
              f"wall, CPU {1e3 * cpu_here:.2f} ms client + scheduler, {1e3 * cpu_workers:.2f} ms workers")
    ratio = times[1] / times[2]
    print(f"speed-up from one worker to two: {ratio:.2f} x (target >= 1.5 x); "
          f"one worker against the serial loop: {times[1] / serial:.2f} x its time")
    print(f"every sweep wrote the same file: {len(files) == 1}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
