#!/usr/bin/env python3
"""Could a discovery's quick rounds drop starts early? Each start's path, recorded; not a CI test.

`fit_model` (tether.discover.fitting) fits a candidate with several starts by a quick round (its
quick_iterations, 12 by default, from each) and carries the winner on. This script discovers each
record given with the search's fits one at a time (as bench/discovery_eval.py runs them) and
records, for every fit_model call with several starts, each quick fit's error after every
iteration (tether.fit's progress reports), its simulations, and the start that won the call in
the end. Then it asks, for each rule "rank the starts by their error after j iterations and fit
only the best m of them on":

- how often the start that won is among those kept;
- what share of the calls' simulations the dropped starts' remaining iterations are;
- how much worse the best kept start's quick fit is than the best of all (the regret).

    python bench/quick_round_study.py --out DIR STEM [STEM ...]    # record (one process per record)
    python bench/quick_round_study.py --analyze DIR                 # the tables

docs/speed.md (2026-12-06, session 67) has the figures.
"""
from __future__ import annotations

import argparse
import inspect
import json
import math
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

#: iterations after which the starts are ranked, and how many of them are kept
RANK_AFTER = (1, 2, 3, 4, 6)
KEEP = (1, 2, 3)
#: a kept start whose quick fit is this much worse than the best start's counts as a loss
REGRET = 1.02


def record(stem: str, out: Path) -> None:
    """Discover ``stem`` with fit_model and tether.fit.fit_traces wrapped; write the calls to ``out``."""
    this_tree.use()
    import tether.discover.campaign as campaign
    import tether.discover.campaign_contradictions as contradictions
    import tether.discover.search as search
    import tether.fit as tfit
    from discovery_eval import _one_fit_at_a_time
    from tether import discover as D
    from tether.discover import fitting
    from tether.traces import read_trace

    _one_fit_at_a_time(D)              # the fits one after the other: one call open at a time
    calls: list = []
    open_call: list = []
    fit_traces, fit_model = tfit.fit_traces, fitting.fit_model
    quick_default = inspect.signature(fit_model).parameters["quick_iterations"].default

    def traced_fit_traces(*a, **k):
        if not open_call or "progress" in k:
            return fit_traces(*a, **k)
        path: list = []
        k["progress"] = lambda p: path.append((p.stage_index, p.horizon, p.iteration, p.rms, p.evaluations))
        r = fit_traces(*a, **k)
        open_call[0]["fits"].append({"max_iterations": k.get("max_iterations"), "rms": r.rms,
                                     "simulations": r.evaluations, "path": path})
        return r

    def traced_fit_model(trace, spec, effects, starts, sc, *a, **k):
        if len(starts) <= 1:
            return fit_model(trace, spec, effects, starts, sc, *a, **k)
        call = {"model": spec.canonical, "effects": list(effects), "starts": len(starts),
                "quick_iterations": k.get("quick_iterations", quick_default), "fits": []}
        open_call[:] = [call]
        try:
            r = fit_model(trace, spec, effects, starts, sc, *a, **k)
            call.update(won=r.best_start, rms=r.rms)
            return r
        finally:
            open_call.clear()
            calls.append(call)

    tfit.fit_traces = traced_fit_traces
    for module in (fitting, search, campaign, contradictions):
        module.fit_model = traced_fit_model
    t0 = time.perf_counter()
    doc = D.discovery_document(D.discover(read_trace(stem)))
    out.write_text(json.dumps({"stem": stem, "seconds": time.perf_counter() - t0, "named": doc["added_effects"],
                               "rmse_final_over_noise": doc["rmse_final_over_noise"], "calls": calls}))


def _quick_fits(call: dict) -> list | None:
    """The call's quick round (its first ``starts`` fits, of its quick iterations each), or None where
    a start's fit failed (the fits then do not line up with the starts)."""
    quick = call["fits"][:call["starts"]]
    if (len(quick) < call["starts"] or call.get("won") is None
            or any(q["max_iterations"] != call["quick_iterations"] for q in quick)):
        return None
    return quick


def _after(q: dict, j: int) -> tuple[float, int]:
    """(error, simulations made) of quick fit ``q`` after its j-th iteration (its last if fewer)."""
    its = [i for i, p in enumerate(q["path"]) if p[2] >= 0]
    if not its:
        return math.inf, 0
    k = its[min(j, len(its)) - 1]
    last: dict = {}
    for p in q["path"][:k + 1]:
        last[(p[0], p[1])] = p[4]          # the simulation count restarts with each stage
    rms = q["path"][k][3]
    return (rms if math.isfinite(rms) else math.inf), sum(last.values())


def analyze(folder: Path) -> None:
    runs = [json.loads(f.read_text()) for f in sorted(folder.glob("*.json"))]
    kept, loss, saved = defaultdict(list), defaultdict(list), defaultdict(float)
    total = quick_total = 0
    won_by = defaultdict(lambda: defaultdict(int))
    for run in runs:
        for call in run["calls"]:
            quick = _quick_fits(call)
            if quick is None:
                continue
            total += sum(f["simulations"] for f in call["fits"])
            quick_total += sum(q["simulations"] for q in quick)
            won_by[(call["effects"][-1] if call["effects"] else "-", call["starts"])][call["won"]] += 1
            best_quick = min(q["rms"] for q in quick)
            for j in RANK_AFTER:
                at = [_after(q, j) for q in quick]
                order = sorted(range(len(quick)), key=lambda i: at[i][0])
                for m in KEEP:
                    if m >= len(quick):
                        continue
                    keep = order[:m]
                    kept[(j, m)].append(call["won"] in keep)
                    loss[(j, m)].append(min(quick[i]["rms"] for i in keep) / best_quick)
                    saved[(j, m)] += sum(quick[i]["simulations"] - at[i][1] for i in order[m:])
    print(f"{len(runs)} records; simulations of the calls with several starts: {total}, "
          f"their quick rounds {quick_total} ({quick_total / max(total, 1):.0%})")
    print(f"rank after j iterations, keep m | winner kept | kept best worse by > {REGRET - 1:.0%} | "
          f"simulations saved")
    for (j, m) in sorted(kept):
        k, l_ = kept[(j, m)], loss[(j, m)]
        print(f"  j={j} m={m} | {sum(k)}/{len(k)} | {sum(x > REGRET for x in l_)}/{len(l_)} "
              f"(worst {max(l_):.2f} x) | {saved[(j, m)] / max(total, 1):.0%}")
    print("the start that won, by the effect added and the number of starts:")
    for key in sorted(won_by, key=lambda k: (k[0], k[1])):
        wins = ", ".join(f"start {i}: {n}" for i, n in sorted(won_by[key].items()))
        print(f"  {key[0]:20s} {key[1]} starts: {wins}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stems", nargs="*", help="records to discover (without .csv)")
    ap.add_argument("--out", type=Path, help="folder for one JSON per record")
    ap.add_argument("--analyze", type=Path, help="print the tables of a folder written by --out")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)      # STEM OUT.json, in a fresh process
    a = ap.parse_args(argv)
    if a.one:
        record(a.one[0], Path(a.one[1]))
        return 0
    if a.analyze:
        analyze(a.analyze)
        return 0
    if not a.out or not a.stems:
        ap.error("give --out DIR and records, or --analyze DIR")
    a.out.mkdir(parents=True, exist_ok=True)
    for stem in a.stems:
        dest = a.out / f"{Path(stem).parent.name}_{Path(stem).name}.json"
        if not dest.is_file():
            subprocess.run([sys.executable, __file__, "--one", stem, str(dest)], check=True)
            print(f"{stem}: {json.loads(dest.read_text())['seconds']:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
