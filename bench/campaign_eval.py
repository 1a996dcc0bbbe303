"""Campaign discovery (issue 29) on campaigns of the project's generator: N campaigns of three
records of one tether (free vibration, load-unload, creep; python_tests/campaign_records.py),
each discovered jointly (tether.discover.campaign) and its three records one at a time
(tether.discover). Prints, per campaign: the hidden union, the named set, each record's final
RMS error over its noise, the seconds, who revealed what; then the same records one at a time:
what each names and how their fitted shared parameters disagree. Ends with the summary and,
with --large, the time of one campaign of records of up to 4,000 samples each.

    nice -n 19 .venv/bin/python bench/campaign_eval.py --n 10 --seed 1 --jobs 1 [--large]

Seed 1 is the tuning draw; seed 2 is kept for an independent check. Figures go to
docs/campaign-discovery.md with their date.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

#: the shared law's parameters compared between the one-at-a-time discoveries
SHARED = ("EA", "a1", "a2", "a3", "bw_A", "creep_J1", "slip_capacity0")

#: rates and programs of the --large campaign: records of up to 4,000 samples each
LARGE = {"free_vibration": {"rate": 200.0}, "load_unload": {"rate": 20.0},
         "creep": {"rate": 0.2, "creep_program": [[100.0, 3.0], [5.0, 2.5]]}}


def one_campaign(seed: int, budget: float, alone: bool, large: bool = False, progress: bool = False) -> dict:
    import campaign_records as cr
    from tether import discover as D
    from tether.discover.campaign import discover_campaign
    from tether.traces import read_trace

    recs, effects, material = cr.campaign(seed, sizes={**cr.SMALL, **LARGE} if large else None)
    with tempfile.TemporaryDirectory() as tmp:
        stems = cr.write_campaign(recs, Path(tmp), prefix=f"c{seed}_")
        traces = [read_trace(s) for s in stems]
        t0, c0 = time.perf_counter(), time.process_time()
        say = (lambda m: print(f"  [{seed} {time.process_time() - c0:7.1f} s CPU] {m}", flush=True)
               ) if progress else None
        d = discover_campaign(traces, budget=budget, progress=say)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        out = {"seed": seed, "tether_effects": sorted(effects), "hidden_union": sorted(cr.hidden_union(recs)),
               "named": sorted(d.added_effects), "seconds": seconds, "cpu": cpu, "samples": [len(t.time) for t in traces],
               "records": [{"name": r.name, "experiment": r.trace.experiment, "revealed_hidden": sorted(rec.revealed),
                            "rmse_over_noise": e / r.sigma,
                            "revealed": [s.effect for s in d.steps if s.effect and r.name in s.revealed_by]}
                           for r, e, rec in zip(d.records, d.final.rms_records, recs)],
               "contradicting": [c["name"] for c in d.contradicting],
               "removed": [x.effect for x in d.removals],
               "wider_laws": [f"{x.effect} {x.law}: {'kept' if x.accepted else 'not kept'}" for x in d.refinements],
               "campaign_params": {k: d.final.params[k] for k in SHARED if k in d.final.params},
               "material_EA": material["EA_N"], "alone": []}
        if alone:
            for tr in traces:
                t1 = time.perf_counter()
                one = D.discover(tr, budget=budget)
                p = one.final.law_params
                out["alone"].append({"name": tr.name, "experiment": tr.experiment, "named": sorted(one.added_effects),
                                     "rmse_over_noise": one.final.rms / one.noise.sigma,
                                     "params": {k: p[k] for k in SHARED if k in p},
                                     "seconds": time.perf_counter() - t1})
    return out


def show(r: dict) -> None:
    ok = set(r["named"]) == set(r["hidden_union"])
    within = all(x["rmse_over_noise"] <= 1.5 for x in r["records"])
    print(f"\ncampaign seed {r['seed']}: tether effects {r['tether_effects']}; samples {r['samples']}")
    print(f"  hidden union {r['hidden_union']}  named {r['named']}  {'RIGHT' if ok else 'WRONG'}; "
          f"{r['seconds']:.0f} s ({r['cpu']:.0f} s CPU); every record within 1.5 x noise: {within}"
          + (f"; CONTRADICTING {r['contradicting']}" if r["contradicting"] else "")
          + (f"; removed {r['removed']}" if r["removed"] else "")
          + (f"; wider laws {r['wider_laws']}" if r["wider_laws"] else ""))
    print(f"  {'record':<28} {'experiment':<15} {'rmse/noise':>10}  {'hidden revealed':<34} revealed (campaign)")
    for x in r["records"]:
        print(f"  {x['name']:<28} {x['experiment']:<15} {x['rmse_over_noise']:>10.2f}  "
              f"{','.join(x['revealed_hidden']) or '-':<34} {','.join(x['revealed']) or '-'}")
    if r["alone"]:
        print(f"  one at a time:  {'record':<28} {'named':<40} {'rmse/noise':>10}  shared parameters (campaign: "
              + ", ".join(f"{k} {v:.4g}" for k, v in r["campaign_params"].items()) + ")")
        for a in r["alone"]:
            print(f"                  {a['name']:<28} {','.join(a['named']) or '-':<40} {a['rmse_over_noise']:>10.2f}  "
                  + ", ".join(f"{k} {v:.4g}" for k, v in a["params"].items()) + f"  ({a['seconds']:.0f} s)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10, help="campaigns (default 10)")
    ap.add_argument("--seed", type=int, default=1, help="draw of campaigns (1: tuning; 2: kept for a check)")
    ap.add_argument("--jobs", type=int, default=1, help="campaigns run side by side (default 1)")
    ap.add_argument("--budget", type=float, default=None,
                    help="wall-time budget of each discovery [s] (default: none; the figures are CPU-bound)")
    ap.add_argument("--no-alone", action="store_true", help="skip the one-at-a-time discoveries")
    ap.add_argument("--large", action="store_true", help="one campaign of records of up to 4,000 samples, timed")
    ap.add_argument("--progress", action="store_true",
                    help="print the discovery's progress with the CPU seconds spent (where the time goes; on with --large)")
    args = ap.parse_args(argv)
    seeds = [1000 * args.seed + i for i in range(1 if args.large else args.n)]
    print(f"campaign_eval: {len(seeds)} campaigns, seed {args.seed}, jobs {args.jobs}, load average "
          f"{os.getloadavg()[0]:.2f} at start")
    if args.large:
        yardstick()
    results = []
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            shown = args.progress or args.large
            futs = [pool.submit(one_campaign, s, args.budget, not args.no_alone, args.large, shown) for s in seeds]
            for f in futs:
                results.append(f.result())
                show(results[-1])
    else:
        for s in seeds:
            results.append(one_campaign(s, args.budget, not args.no_alone, args.large, args.progress or args.large))
            show(results[-1])
    right = sum(set(r["named"]) == set(r["hidden_union"]) for r in results)
    within = sum(all(x["rmse_over_noise"] <= 1.5 for x in r["records"]) for r in results)
    print(f"\nnamed the hidden union on {right} of {len(results)} campaigns; every record within 1.5 x noise on "
          f"{within} of {len(results)}; seconds per campaign: "
          + ", ".join(f"{r['seconds']:.0f} ({r['cpu']:.0f} CPU)" for r in results)
          + f"; load average {os.getloadavg()[0]:.2f} at the end")
    if args.large:
        yardstick()
    return 0


def yardstick() -> None:
    """bench/bench_discovery_speed.py's machine yardstick (one FMU simulation of the demo record, best
    of 5), in wall and CPU seconds: the campaign's time read as a ratio on a loaded machine."""
    from bench_discovery_speed import _yardstick

    c0 = time.process_time()
    wall = _yardstick()
    print(f"machine yardstick (bench/bench_discovery_speed.py): one FMU simulation of the demo record "
          f"{1e3 * wall:.1f} ms best of 5 wall, {1e3 * (time.process_time() - c0) / 5:.1f} ms CPU on average; "
          f"load average {os.getloadavg()[0]:.2f}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
