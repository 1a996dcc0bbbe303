#!/usr/bin/env python3
"""Where a `tether discover` run's engine fits go, per stage of the search; not a CI test.

Each record of bench/bench_discovery_speed.py is discovered in a fresh process with every engine
fit (tether.identify_native.fit) wrapped: its free-parameter count k, simulations, iterations, CPU
seconds and the stage of the search that asked for it, read from the main thread's stack when the
fit starts (the stage a Search.run loop is in, plan.PLAN; "start model" before it). Printed per
record: its CPU, named effects and rmse_final, and per stage the fits, their k, simulations and CPU
(--json FILE keeps every fit, for tables across runs).

    python bench/profile_discovery_stages.py [--out DIR] [--only NAME,NAME] [--json FILE]
                                             [--code PYTHON_DIR] [--engine OPTION=VALUE ...]
                                             [--discover-arg=ARG ...]

--code PYTHON_DIR runs the `tether` package found there (an older checkout's python/, with its own
engine library through KT_IDENTIFY_LIB) instead of this one, on the same records; its stages are
named from its own stack (an older monolithic discover.py: see _stage_of_old). --discover-arg
passes an argument to every discovery (--no-nuisance: the nuisance parameters held). docs/speed.md
has the figures.
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

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
sys.path.insert(0, str(REPO / "python_tests"))

BUDGET_S = 100000.0
#: the stage names of an older discover.py (one function with nested ones) by the function on the stack
_OLD_NESTED = {"refine_shapes": "shapes", "rival_law": "rival law", "restart_idle_elements": "reseed",
               "finer_bank": "reseed"}


def _cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def _main_stack() -> list:
    """(function name, frame) of the main thread's frames in tether.discover, innermost first."""
    frame = sys._current_frames().get(threading.main_thread().ident)
    out = []
    while frame is not None:
        if "tether" in frame.f_code.co_filename and "discover" in frame.f_code.co_filename:
            out.append((frame.f_code.co_name, frame))
        frame = frame.f_back
    return out


def _stage_of(stack: list) -> tuple:
    """(stage, role) of a fit from the main thread's stack: the stage of Search.run, or the old code's."""
    names = [n for n, _ in stack]
    role = next((n for n in names if n not in ("fit", "shape_fit", "<lambda>", "_side_by_side", "fit_model",
                                                   "_fit_once", "map", "run", "discover")), "")
    for n, f in stack:
        if n == "run" and "stage" in f.f_locals:
            return f.f_locals["stage"].name, role
    if "fit_start_model" in names:
        return "start model", role
    return _stage_of_old(stack, role)


def _stage_of_old(stack: list, role: str) -> tuple:
    """An older discover.py: the nested function on the stack, else the sweep of its loop, else
    where discover() is (before the loop: the start model; past it: the final fit)."""
    names = [n for n, _ in stack]
    if "reshape" in names:
        return ("reseed" if "iwan_stages" in names else "rival law"), role
    for n in names:
        if n in _OLD_NESTED:
            sweep = next((f.f_locals.get("sweep") for m, f in stack if m == "discover"), 1)
            stage = _OLD_NESTED[n]
            return (stage + " again" if stage == "shapes" and sweep == 2 else stage), role
    top = next((f for n, f in stack if n == "discover" and "sweep" in f.f_code.co_varnames), None)
    if top is None:
        return "?", role
    if "sweep" not in top.f_locals:
        return "start model", role
    if "adopt" in top.f_locals:          # past the loop (adopt is defined after it)
        return "final fit", role
    return ("effects" if top.f_locals["sweep"] == 1 else "effects again"), role or "step"


def _one(stem: str, result: str, stats: str, budget: str, engine: str, extra: str = "[]") -> int:
    """Discover ``stem`` in this process, the engine's fits counted; write the counts to ``stats``."""
    import tether.identify_native as idn
    from tether.cli import main

    fits: list[dict] = []
    lock = threading.Lock()
    plain_fit = idn.fit

    def counted_fit(experiments, free, **options):
        for key, value in json.loads(engine).items():
            options.setdefault(key, value)
        stage, role = _stage_of(_main_stack())
        alone = options.get("n_threads") == 1
        t0, c0 = time.thread_time(), _cpu()
        row = {"k": len(free), "stage": stage, "role": role, "ftol": options.get("ftol"),
               "max_iterations": options.get("max_iterations"), "horizon": options.get("horizon_stages"),
               "central": int(options.get("central_differences", getattr(idn, "POLISH_CENTRAL", 0)))}
        try:
            r = plain_fit(experiments, free, **options)
            row.update(failed=False, sims=r.evaluations, jac=getattr(r, "jacobian_evaluations", -1),
                       iterations=r.iterations, engine_cpu=getattr(r, "cpu_seconds", None))
        except BaseException:
            row.update(failed=True, sims=0, jac=0, iterations=0)
            raise
        finally:
            # the engine's own count where it has one (its threads'); else a fit on its own thread (beside
            # others): that thread's CPU; else the process's (an older engine's threads)
            row["cpu"] = row.get("engine_cpu") or (time.thread_time() - t0 if alone else _cpu() - c0)
            with lock:
                fits.append(row)
        return r

    idn.fit = counted_fit
    t0 = time.perf_counter()
    rc = main(["discover", stem, "--json", result, "--budget", budget, *json.loads(extra)])
    Path(stats).write_text(json.dumps({"rc": rc, "wall": time.perf_counter() - t0, "cpu": _cpu(), "fits": fits}))
    return 0


def _launch(code: str | None) -> list:
    """The child's command: this file with this Python, the package from ``code`` where given (the
    editable install's finder of this checkout taken off sys.meta_path)."""
    if not code:
        return [sys.executable, __file__]
    boot = ("import sys; sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower() "
            f"and '__editable__' not in type(f).__module__]; sys.path.insert(0, {code!r}); "
            f"sys.argv = [{__file__!r}] + sys.argv[1:]; import runpy; runpy.run_path({__file__!r}, run_name='__main__')")
    return [sys.executable, "-c", boot]


def _profile(name: str, stem: Path, out: Path, budget: float, engine: dict, code: str | None,
             extra: list) -> dict:
    res, stats = out / f"{name}.stages.discovery.json", out / f"{name}.stages.stats.json"
    p = subprocess.run(_launch(code) + ["--one", str(stem), str(res), str(stats), str(budget), json.dumps(engine),
                                        json.dumps(extra)],
                       capture_output=True, text=True)
    if p.returncode != 0 or not stats.is_file():
        return {"name": name, "error": (p.stderr.strip().splitlines() or ["?"])[-1]}
    st = json.loads(stats.read_text())
    doc = json.loads(res.read_text())
    return {"name": name, "cpu": st["cpu"], "wall": st["wall"], "fits": st["fits"], "named": doc["added_effects"],
            "rmse_final": doc["rmse_final"], "rmse_over_noise": doc["rmse_final_over_noise"]}


def _by_stage(fits: list) -> dict:
    """stage -> {fits, k (sorted counts), sims, jac, cpu}, in the order the stages first appear."""
    out: dict = {}
    for f in fits:
        s = out.setdefault(f["stage"], {"fits": 0, "k": {}, "sims": 0, "jac": 0, "cpu": 0.0, "failed": 0})
        s["fits"] += 1
        s["k"][f["k"]] = s["k"].get(f["k"], 0) + 1
        s["sims"] += f["sims"]
        s["jac"] += max(f["jac"], 0)
        s["cpu"] += f["cpu"]
        s["failed"] += f["failed"]
    return out


def _print_row(row: dict) -> None:
    if "error" in row:
        print(f"{row['name']}: FAILED: {row['error']}", flush=True)
        return
    eng = sum(f["cpu"] for f in row["fits"])
    print(f"{row['name']}: CPU {row['cpu']:.1f} s, engine fits {eng:.1f} s, {len(row['fits'])} fits, "
          f"{sum(f['sims'] for f in row['fits'])} simulations; named {','.join(row['named']) or '-'}, "
          f"rmse/noise {row['rmse_over_noise']:.3f}", flush=True)
    for stage, s in _by_stage(row["fits"]).items():
        ks = " ".join(f"{k}x{n}" for k, n in sorted(s["k"].items()))
        jac = f" ({100 * s['jac'] / max(s['sims'], 1):.0f} % Jacobian)" if s["jac"] else ""
        print(f"  {stage:14s} fits {s['fits']:4d} (failed {s['failed']})  CPU {s['cpu']:6.1f} s  sims {s['sims']:6d}"
              f"{jac}  k: {ks}", flush=True)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] == "--one":
        return _one(*argv[1:7])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=None, help="directory for the records and results (default: a temporary one)")
    ap.add_argument("--only", default=None, help="run only these records, in this order (comma-separated)")
    ap.add_argument("--budget", type=float, default=BUDGET_S, help=f"each discovery's budget [s] (default {BUDGET_S:g})")
    ap.add_argument("--json", default=None, help="write the rows (every fit) to this file")
    ap.add_argument("--code", default=None, help="another checkout's python/ directory to run instead of this one")
    ap.add_argument("--engine", action="append", default=[], metavar="OPTION=VALUE",
                    help="an engine option for every fit that does not set it, e.g. broyden_updates=4")
    ap.add_argument("--discover-arg", action="append", default=[], metavar="ARG",
                    help="an argument for every `tether discover` run, e.g. --no-nuisance; repeatable")
    a = ap.parse_args(argv)
    engine = {k: json.loads(v) for k, v in (e.split("=", 1) for e in a.engine)}
    sys.path.insert(0, str(REPO / "python"))
    from bench_discovery_speed import _yardstick, speed_records

    out = Path(a.out or tempfile.mkdtemp(prefix="discovery_stages_"))
    records = {r[0]: r for r in speed_records(out)}
    names = a.only.split(",") if a.only else list(records)
    print(f"yardstick {1e3 * _yardstick():.1f} ms; load average {os.getloadavg()[0]:.2f}; code "
          f"{a.code or REPO / 'python'}\n", flush=True)
    rows = []
    for name in names:
        rows.append(_profile(name, records[name][1], out, a.budget, engine, a.code, a.discover_arg))
        _print_row(rows[-1])
        if a.json:
            Path(a.json).write_text(json.dumps(rows, indent=1))
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
