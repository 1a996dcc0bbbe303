#!/usr/bin/env python3
"""The search's sequencing, this checkout against another, with fits that are not fits; not a CI test.

A refactor of the search (the plan as data, issue 25) must ask for the same fits in the same order,
from the same starts, with the same caps, and record the same steps, refinements and removals. Real
discoveries check that too (bench_discovery_speed.py --baseline), but take minutes each and reach
the rare stages (the Iwan bank's reseeding, the second search, the rival law) on few records. Here
every fit is replaced by a deterministic function of what it is asked (the model, its effects, shape
terms, held terms, starts; its error falls as the model nears a hidden truth drawn per scenario),
the held-out error likewise, and the evidence and noise by constants; each scenario draws its truth
(which effects, which hysteresis law, how much a shape gains, what stays unexplained). Both
checkouts run the same scenarios in their own process; the fits asked (in order) and the records
must be identical. Printed: how many scenarios agree and how often each stage ran.

    python bench/search_plan_check.py --baseline OTHER/python [--n 200]

(OTHER: an older checkout, e.g. `git archive COMMIT python | tar -x -C OTHER`; the build/ of this
checkout supplies the FMU and the engine to both.)
"""
import argparse
import collections
import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
import types
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _run(root: str, out: str, N: int) -> None:
    """The scenarios on the package under ``root``; their records to ``out``."""
    sys.meta_path = [f for f in sys.meta_path
                     if "editable" not in type(f).__module__.lower() and "editable" not in type(f).__name__.lower()]
    sys.path.insert(0, root)
    sys.path.insert(0, str(REPO / "python_tests"))
    import numpy as np
    import tether
    assert tether.__file__.startswith(root), tether.__file__
    import tether.fit
    from tether.discover import search, fitting, judge, refine, rival, starts, laws
    from tether.discover.fitting import ModelFit
    from tether.discover.scales import _Scales
    from tether.models import IWAN_EPS
    import hidden_effects as he

    SIGMA = 1e-4
    fitting.PARALLEL_FITS = 1
    SALT = [0]
    TRUTH = {}
    LOG = []

    def u(*parts):
        h = hashlib.sha256(repr((SALT[0],) + parts).encode()).digest()
        return int.from_bytes(h[:8], "big") / 2 ** 64

    SHAPES = {k for groups in laws.SHAPE_TERMS.values() for g in groups for k in g}

    def gap(spec, shape):
        t = TRUTH
        g = t["rest"]
        have = set(spec.effects)
        for e, w in t["weights"].items():
            if e not in have:
                g += w
        if "hysteresis" in have and "hysteresis" in t["weights"] and spec.hysteresis != t["hyst"]:
            # which law fits better may turn with the other effects named (as Bouc-Wen before slack, the
            # bank after it): the wrong law's misfit changes sign with them
            g += t["lawgap"] * (u("lawturn", tuple(sorted(have))) - 0.35)
        for e in have - set(t["weights"]):
            g -= 0.05 * u("spare", e)
        for k in sorted(set(shape) & SHAPES):
            g -= t["shape_gain"] * u("shape", k)
        return max(g, 0.0)

    def fake_fit(trace, spec, effects, starts_, sc, quick_iterations=12, work_cap=None, extra=(), held=(),
                 own_thread=False, baseline_rms=None, nuisance=(), **options):
        spec = spec.for_experiment(trace.experiment)
        names = laws.free_parameters(spec, trace.experiment)
        names += [e for e in extra if e not in names]
        names = [e for e in names if e not in held]
        start = next((s for s in starts_ if s is not None), {}) or {}
        summary = sorted((k, float("%.6g" % v)) for k, v in start.items() if isinstance(v, (int, float)))
        key = (spec.canonical, tuple(effects), tuple(extra), tuple(held), len(trace.time), len(starts_),
               [s is None for s in starts_], summary)
        LOG.append([repr(key), repr(work_cap), repr(baseline_rms), repr(sorted(options.items()))])
        if u("fail", repr(key)) < 0.03:
            return ModelFit(spec=spec, effects=tuple(effects), params={}, free=names, rms=float("inf"),
                            predicted=np.full(len(trace.time), np.nan), ok=False, message="fake failure")
        params = {}
        for n in list(spec.parameters) + names + list(held) + list(extra):
            params[n] = float(start.get(n, 1e-3 * (1 + u("p", n)) if n not in IWAN_EPS else 1e-4 * (1 + IWAN_EPS.index(n))))
        for k, v in start.items():
            params.setdefault(k, v)
        if "iw_k1" in names:
            for j, n in enumerate([m for m in names if m.startswith("iw_k")]):
                params[n] = (0.0 if u("idle", n, repr(key)) < 0.3 else 100.0 * (1 + u("k", n)))
        g = gap(spec, extra) * (1 + 0.02 * (u("jit", repr(key)) - 0.5))
        rms = SIGMA * math.sqrt(1 + g * g) * (1.0 if len(trace.time) == TRUTH["n"] else 0.97)
        return ModelFit(spec=spec, effects=tuple(effects), params=params, free=list(names), rms=rms,
                        predicted=np.zeros(len(trace.time)), best_start=int(u("best", repr(key)) * len(starts_)),
                        shape=tuple(extra))

    def fake_heldout(trace, spec, params, first):
        shape = [k for k in params if k in SHAPES]
        g = gap(spec, shape)
        return SIGMA * math.sqrt(1 + g * g) * (1.05 + 0.3 * u("held", spec.canonical, sorted(shape)))

    for mod in (search, refine, rival):
        if hasattr(mod, "_heldout"): mod._heldout = fake_heldout
    search.fit_model = fake_fit
    search.predict = lambda tr, sp, p: np.zeros(len(tr.time))
    judge.predict = lambda tr, sp, p: np.full(len(tr.time), 1.0)
    search._simulation_work = lambda *a: 1000         # the work caps' unit (trace, spec, params)
    search._simulation_seconds = lambda *a: 0.001     # its name in a baseline from before the work caps
    search.regimes = lambda tr, fit, *a: {"slack": np.zeros(len(tr.time), bool)}
    search.disagreement = lambda *a, **k: []
    search.regime_table = lambda *a, **k: {}
    search.signatures = lambda *a, **k: {}
    search._evidence = lambda *a, **k: ""
    search._slack_seen_by = lambda *a, **k: ""
    search.estimate_noise = lambda tr: types.SimpleNamespace(sigma=SIGMA, method="fake")
    search.search_thinning = lambda tr, s: 1
    search._scales = lambda tr: _Scales(L0=10.0, ea=1e5, k=1e4, amp=0.01, eps=0.002, force=100.0, rig=tr.rig,
                                         hold=0.0, omega=30.0)
    refine._damping_table_start = lambda *a, **k: None
    starts._damping_table_start = lambda *a, **k: None
    rival._wider_law_starts = lambda trace, cur, new, effect, law: [dict(cur.params)]
    tether.fit.initial_estimate = lambda traces, spec, fixed=None, **k: dict(fixed or {})

    from tether.traces import read_trace
    tmp = tempfile.mkdtemp(prefix="plan_check_")
    RECORDS = {}
    for exp in ("forced", "free_vibration", "load_unload"):
        g = (he.generate(exp, set(), 7, noise=SIGMA, rate=50.0, duration_s=6.0) if exp != "load_unload"
             else he.generate(exp, set(), 7, noise=SIGMA))
        g.write(tmp, exp)
        RECORDS[exp] = read_trace(os.path.join(tmp, exp))
    results = []
    for salt in range(N):
        SALT[0] = salt
        exp = ("forced", "free_vibration", "load_unload")[salt % 3]
        tr = RECORDS[exp]
        cands = laws.candidates(tr)
        weights = {e: 3 + 30 * u("w", e) for e in cands if u("in", e) < 0.5}
        TRUTH.clear()
        TRUTH.update(weights=weights, hyst="iwan" if u("law") < 0.6 else "boucwen", lawgap=1 + 5 * u("lawgap"),
                     rest=(3 * u("rest") ** 2 if SALT[0] % 2 else 1 + 4 * u("rest")), shape_gain=(0.2 + 1.5 * u("sg") if SALT[0] % 2 else 0.02 + 0.2 * u("sg")), n=len(tr.time))
        LOG.clear()
        try:
            d = search.discover(tr, free_nuisance=False, budget=None)
            res = dict(added=d.added_effects, stop=d.stop_reason, final=d.final.label, rms=repr(d.final.rms),
                       steps=[(s.effect, [(c.effect, c.model, c.accepted, c.verdict) for c in s.candidates],
                               [repr(r.__dict__) for r in s.retests]) for s in d.steps],
                       refinements=[repr({k: v for k, v in r.__dict__.items()}) for r in d.refinements],
                       removals=[repr(r.__dict__) for r in d.removals], params=repr(sorted(d.final.params.items())),
                       stages=getattr(d, "stages", None))
        except Exception as ex:  # noqa
            import traceback
            res = dict(error=traceback.format_exc().strip().splitlines()[-1])
        res["log"] = list(LOG)
        res["truth"] = repr(TRUTH)
        results.append(res)
    json.dump(results, open(out, "w"))


def _compare(a: list, b: list) -> int:
    same, coverage = 0, collections.Counter()
    for i, (x, y) in enumerate(zip(a, b)):
        xs = {k: v for k, v in x.items() if k != "stages"}
        ys = {k: v for k, v in y.items() if k != "stages"}
        if xs == ys:
            same += 1
        else:
            print(f"scenario {i}: DIFFERENT in {[k for k in xs if xs[k] != ys.get(k)]}")
        for s in y.get("stages") or []:
            coverage[s] += 1
        for r in y.get("refinements", []):
            coverage["(restart move)"] += "'restart': True" in r
            coverage["(finer move)"] += "'finer': True" in r
            coverage["(rival law tried)"] += "'law': 'boucwen -> iwan'" in r or "'law': 'iwan -> boucwen'" in r
        coverage["(start model failed)"] += "error" in y
    print(f"{same} of {len(a)} scenarios identical (every fit asked, in order, with its starts and caps; every "
          f"step, refinement and removal)")
    print("stages run (this checkout):", dict(coverage))
    return 0 if same == len(a) else 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", metavar="PYTHON_ROOT", help="the other checkout's python/ folder (required)")
    ap.add_argument("--n", type=int, default=200, help="scenarios (default 200)")
    ap.add_argument("--run", nargs=2, metavar=("ROOT", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.run:
        _run(a.run[0], a.run[1], a.n)
        return 0
    if not a.baseline:
        ap.error("--baseline PYTHON_ROOT is required")
    env = dict(os.environ)
    env.setdefault("KT_FMU", str(REPO / "build" / "KevlarTether.fmu"))
    env.setdefault("KT_IDENTIFY_LIB", str(REPO / "build" / "fmu_src" / "identify" / "libtether_identify.so"))
    out = Path(tempfile.mkdtemp(prefix="plan_check_"))
    procs = [subprocess.Popen([sys.executable, __file__, "--n", str(a.n), "--run", str(root), str(out / name)], env=env)
             for name, root in (("baseline.json", a.baseline), ("this.json", REPO / "python"))]
    if any(p.wait() for p in procs):
        return 2
    return _compare(json.loads((out / "baseline.json").read_text()), json.loads((out / "this.json").read_text()))


if __name__ == "__main__":
    sys.exit(main())
