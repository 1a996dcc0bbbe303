#!/usr/bin/env python3
"""Where a `tether discover` run spends its CPU time, per record of the speed bench; not a CI test.

Each record of bench/bench_discovery_speed.py is discovered in a fresh process (as the command
line runs it), with every engine fit (tether.identify_native.fit) wrapped to count what it did.
Printed per record: the process's CPU time (user + system, all threads), the part of it inside the
engine's fits, in the data-based starts (``initial_estimate``), in simulations outside the fits
(``identify_native.simulate``) and in the imports before the run (what is left is Python: the
search, the judge, the evidence, lazy imports), the fits, their simulations (median per fit, total) and the share of those that
were finite-difference Jacobian columns, the named effects and rmse_final; then the totals, with
the machine yardstick of the speed bench measured in the same run.

    python bench/profile_discovery.py [--out DIR] [--only NAME,NAME] [--json FILE] [--compare FILE]
                                      [--engine OPTION=VALUE ...]

--json FILE writes the rows (with each record's OUT.json essentials) for a later comparison:
``--compare FILE`` prints, beside this run, the named effects and rmse_final of that earlier one
and whether they agree (the same named effects, rmse_final within 2 %). docs/speed.md has the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

#: the looser rule of a change that may move results (issue 25's speed work): the same named
#: effects and rmse_final within this relative difference
RMSE_REL = 0.01
#: each discovery's wall-time budget: far beyond any record's need, so that the results do not
#: depend on the machine's load (the default 900 s ran out on a busy machine)
BUDGET_S = 100000.0


def _timed(owners: list, name: str, spent: dict, key: str, depth: threading.local) -> None:
    """Replace ``name`` on each of ``owners`` (modules) by a wrapper that adds the calling thread's CPU
    seconds of its outermost calls to ``spent[key]`` (a call inside another wrapped one is not counted)."""
    plain = getattr(owners[0], name)

    def timed(*args, **kwargs):
        if getattr(depth, "n", 0):
            return plain(*args, **kwargs)
        depth.n, t0 = 1, time.thread_time()
        try:
            return plain(*args, **kwargs)
        finally:
            depth.n = 0
            spent[key] += time.thread_time() - t0

    for owner in owners:
        setattr(owner, name, timed)


def _cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def _one(stem: str, result: str, stats: str, budget: str, engine: str = "{}") -> int:
    """Discover ``stem`` in this process, the engine's fits counted; write the counts to ``stats``."""
    c0 = _cpu()
    from tether.blas import limit_process

    limit_process()
    import tether.fit as tf
    import tether.fit.engine as tfe
    import tether.fit.start as tfs
    import tether.identify_native as idn
    from tether.cli import main

    spent = {"imports": _cpu() - c0, "starts": 0.0, "simulations": 0.0}
    depth = threading.local()
    _timed([tfs, tf, tfe], "initial_estimate", spent, "starts", depth)
    _timed([idn], "simulate", spent, "simulations", depth)
    fits: list[dict] = []
    lock = threading.Lock()
    plain_fit = idn.fit

    def counted_fit(experiments, free, **options):
        t0 = time.thread_time()
        for key, value in json.loads(engine).items():
            options.setdefault(key, value)
        row = {"k": len(free), "central": int(options.get("central_differences", idn.POLISH_CENTRAL))}
        try:
            r = plain_fit(experiments, free, **options)
        except BaseException:
            row.update(failed=True, cpu=time.thread_time() - t0)
            with lock:
                fits.append(row)
            raise
        row.update(failed=False, cpu=r.cpu_seconds, sims=r.evaluations, jac=r.jacobian_evaluations,
                   iterations=r.iterations, n=r.n_residuals)
        with lock:
            fits.append(row)
        return r

    idn.fit = counted_fit
    t0 = time.perf_counter()
    rc = main(["discover", stem, "--json", result, "--budget", budget])
    wall = time.perf_counter() - t0
    Path(stats).write_text(json.dumps({"rc": rc, "wall": wall, "cpu": _cpu(), "fits": fits, **spent}))
    return 0


def _profile(name: str, stem: Path, out: Path, budget: float, engine: dict) -> dict:
    """One record discovered in a child process; its row."""
    res, stats = out / f"{name}.profile.discovery.json", out / f"{name}.profile.stats.json"
    p = subprocess.run([sys.executable, __file__, "--one", str(stem), str(res), str(stats), str(budget),
                        json.dumps(engine)],
                       capture_output=True, text=True)
    if p.returncode != 0 or not stats.is_file():
        return {"name": name, "error": (p.stderr.strip().splitlines() or ["?"])[-1]}
    st = json.loads(stats.read_text())
    doc = json.loads(res.read_text())
    fits = st["fits"]
    done = [f for f in fits if not f["failed"]]
    sims = sorted(f["sims"] for f in done)
    return {"name": name, "cpu": st["cpu"], "wall": st["wall"], "engine_cpu": sum(f["cpu"] for f in fits),
            "fits": len(fits), "abandoned": len(fits) - len(done), "sims": sum(sims),
            "sims_median": sims[len(sims) // 2] if sims else 0, "jac": sum(f["jac"] for f in done),
            "iterations": sum(f["iterations"] for f in done),
            "imports_cpu": st["imports"], "starts_cpu": st["starts"], "simulations_cpu": st["simulations"],
            "named": doc["added_effects"], "rmse_final": doc["rmse_final"],
            "rmse_over_noise": doc["rmse_final_over_noise"]}


def _earlier(path: str | None) -> dict:
    """The rows of an earlier run's --json file by name ({} if none, or not there yet)."""
    if not path or not Path(path).is_file():
        return {}
    return {r["name"]: r for r in json.loads(Path(path).read_text())}


def _share(row: dict, key: str) -> str:
    """CPU seconds and share of the record's CPU of one part (rows of an older run lack it: '-')."""
    return f"{row[key]:5.1f} s ({100 * row[key] / max(row['cpu'], 1e-9):3.0f} %)" if key in row else "-"


def _print_row(row: dict, earlier: dict | None) -> None:
    if "error" in row:
        print(f"{row['name']:34s} FAILED: {row['error']}", flush=True)
        return
    line = (f"{row['name']:34s} CPU {row['cpu']:6.1f} s  engine {row['engine_cpu']:6.1f} s "
            f"({100 * row['engine_cpu'] / max(row['cpu'], 1e-9):3.0f} %)  starts {_share(row, 'starts_cpu')}  "
            f"simulations {_share(row, 'simulations_cpu')}  imports {_share(row, 'imports_cpu')}  fits {row['fits']:3d} "
            f"(abandoned {row['abandoned']})  sims {row['sims']:6d} (median/fit {row['sims_median']:4d}, "
            f"Jacobian {100 * row['jac'] / max(row['sims'], 1):3.0f} %)  it {row['iterations']:5d}  "
            f"named {','.join(row['named']) or '-':36s} rmse/noise {row['rmse_over_noise']:5.3f}")
    if earlier and "error" not in earlier:
        rel = abs(row["rmse_final"] - earlier["rmse_final"]) / max(abs(earlier["rmse_final"]), 1e-300)
        same = row["named"] == earlier["named"] and rel <= RMSE_REL
        line += (f"  | before: CPU {earlier['cpu']:6.1f} s ({row['cpu'] / earlier['cpu']:4.2f} x), sims "
                 f"{earlier['sims']:6d}, named {','.join(earlier['named']) or '-'}, rmse rel. diff {rel:.1e} "
                 f"{'SAME' if same else 'DIFFERENT'}")
    print(line, flush=True)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--one":
        return _one(*argv[1:6])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None, help="directory for the records and results (default: a temporary one)")
    ap.add_argument("--only", default=None, help="run only the records whose name is one of these (comma-separated)")
    ap.add_argument("--budget", type=float, default=BUDGET_S,
                    help=f"each discovery's time budget [s] (default {BUDGET_S:g}: never reached, so that a "
                         "loaded machine does not change the results)")
    ap.add_argument("--json", default=None, help="write the rows to this file")
    ap.add_argument("--compare", default=None, help="an earlier --json file to compare the results with")
    ap.add_argument("--engine", action="append", default=[], metavar="OPTION=VALUE",
                    help="an engine option (kt_fit_options field, an integer or a number) for every fit that "
                         "does not set it, e.g. broyden_updates=4; repeatable")
    a = ap.parse_args(argv)
    engine = {k: json.loads(v) for k, v in (e.split("=", 1) for e in a.engine)}
    from bench_discovery_speed import _yardstick, speed_records

    out = Path(a.out or tempfile.mkdtemp(prefix="discovery_profile_"))
    records = speed_records(out)
    if a.only:
        records = [r for r in records if r[0] in a.only.split(",")]
    yard = _yardstick()
    print(f"machine yardstick: one FMU simulation of the demo record {1e3 * yard:.1f} ms; "
          f"load average {os.getloadavg()[0]:.2f} at the start\n", flush=True)
    rows = []
    for name, stem, _hidden in records:
        rows.append(_profile(name, stem, out, a.budget, engine))
        earlier = _earlier(a.compare)   # read as it goes: the earlier run may still be writing it
        _print_row(rows[-1], earlier.get(name))
        if a.json:
            Path(a.json).write_text(json.dumps(rows, indent=1))
    ok = [r for r in rows if "error" not in r]
    if not ok:
        return 1
    cpu = sorted(r["cpu"] for r in ok)
    eng, tot = sum(r["engine_cpu"] for r in ok), sum(r["cpu"] for r in ok)
    sims, jac = sum(r["sims"] for r in ok), sum(r["jac"] for r in ok)
    parts = {k: sum(r.get(k, 0.0) for r in ok) for k in ("starts_cpu", "simulations_cpu", "imports_cpu")}
    print("\nshares of the CPU: engine fits {:.0f} %, starts {:.0f} %, simulations {:.0f} %, imports {:.0f} %, "
          "the rest (Python) {:.0f} %".format(100 * eng / tot, *(100 * v / tot for v in parts.values()),
                                              100 * (tot - eng - sum(parts.values())) / tot))
    print(f"{len(ok)} records; yardstick {1e3 * yard:.1f} ms; CPU median {cpu[len(cpu) // 2]:.1f} s, largest "
          f"{cpu[-1]:.1f} s, total {tot:.0f} s; engine fits {100 * eng / tot:.0f} % of it; simulations {sims} "
          f"({100 * jac / max(sims, 1):.0f} % Jacobian columns); load average {os.getloadavg()[0]:.2f} at the end")
    earlier = _earlier(a.compare)
    if earlier:
        both = [r for r in ok if r["name"] in earlier and "error" not in earlier[r["name"]]]
        same = sum(r["named"] == earlier[r["name"]]["named"] and abs(r["rmse_final"] - earlier[r["name"]]["rmse_final"])
                   <= RMSE_REL * abs(earlier[r["name"]]["rmse_final"]) for r in both)
        ratios = sorted(r["cpu"] / earlier[r["name"]]["cpu"] for r in both)
        print(f"against the earlier run: the same named effects and rmse_final within {100 * RMSE_REL:g} % on "
              f"{same} of {len(both)}; CPU ratio median {ratios[len(ratios) // 2]:.2f}, total "
              f"{sum(r['cpu'] for r in both) / sum(earlier[r['name']]['cpu'] for r in both):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
