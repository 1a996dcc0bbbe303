#!/usr/bin/env python3
"""Discovery on records drawn by our own engine with a wider law hidden (issue 25); not a CI test.

Two records, each with one effect whose law is beyond the search's own:
  exponential   a load-unload test (two cycles 0-60-0 N, 16 m) of a tether whose elastic law is
                T = exp_F (exp(eps/exp_eps) - 1), hidden effect nonlinear_stiffness;
  primary       a creep test (4 h at 80 N, 2 h unloaded, 2 h at 50 N, a sample a minute) of a
                linear tether with primary creep, eps_p = (J T / n)((1 + t/tau)^n - 1), n = 0.2,
                and one Kelvin cell, hidden effect creep;
and two of the search's own laws on the same loads (cubic, kelvin: the FMU's default cubic and
Kelvin cells with slip), whose times with and without the wider laws are their cost on records
that do not need them.
Each is run through tether.discover twice: with the wider laws (rival.wider_law, and the exponential
law as a candidate of nonlinear stiffness in a load test) and without them (the search as it was),
one after the other on one thread. Printed per run:
the named effects, rmse_final / noise, the wider law's verdict and the wall time.

    nice -n 19 python bench/wider_laws_discovery.py [--only NAME] [--noise-rel R]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

L0 = 16.0


def _write(folder: Path, name: str, experiment: str, columns: dict) -> Path:
    (folder / f"{name}.json").write_text(json.dumps({"format": "tether-trace/1", "experiment": experiment,
                                                     "tether": {"length_m": L0}}))
    names = list(columns)
    with open(folder / f"{name}.csv", "w") as f:
        f.write(",".join(names) + "\n")
        np.savetxt(f, np.column_stack([columns[n] for n in names]), delimiter=",", fmt="%.17g")
    return folder / name


#: the load cycles of the load-test records (two cycles 0-60-0 N) and the loads of the creep records
#: (4 h at 80 N, 2 h unloaded, 2 h at 50 N, a sample a minute)
def _load_cycles():
    t = np.linspace(0.0, 400.0, 1601)
    return t, 60.0 * np.sin(np.pi * t / 200.0) ** 2


def _creep_loads():
    t = np.arange(0.0, 8 * 3600.0 + 1.0, 60.0)
    return t, np.where(t < 4 * 3600.0, 80.0, np.where(t < 6 * 3600.0, 0.0, 50.0))


def _drawn(folder: Path, name: str, experiment: str, t, load, settings: dict, noise: float, seed: int) -> Path:
    """A record of the load rig drawn by the engine with ``settings``, its elongation with noise."""
    from tether import identify_native as idn
    settings = dict(rig=3, damping=1, hysteresis=1, slack=0, L0=L0, **settings)
    u = idn.simulate(idn.Experiment(t, settings=settings, input_kind=idn.INPUT_LOAD, input=load, output="elongation"))
    u = u + np.random.default_rng(seed).normal(0.0, noise, t.size)
    return _write(folder, name, experiment, {"time": t, "load": load, "elongation": u})


def exponential_record(folder: Path, noise: float) -> Path:
    return _drawn(folder, "exponential", "load_unload", *_load_cycles(),
                  dict(stiffness=3, exp_F=30.0, exp_eps=0.015, creep=0), noise, 11)


def primary_record(folder: Path, noise: float) -> Path:
    return _drawn(folder, "primary", "creep", *_creep_loads(),
                  dict(stiffness=1, EA=3000.0, creep=1, creep_law=2, creep_J1=1e-6, creep_tau1=1800.0, creep_J2=0.0,
                       creep_J3=0.0, primary_J=2e-6, primary_tau=30.0, primary_n=0.2), noise, 12)


def cubic_record(folder: Path, noise: float) -> Path:
    """The search's own law (the FMU's default cubic), on the exponential record's load cycles."""
    return _drawn(folder, "cubic", "load_unload", *_load_cycles(), dict(stiffness=2, creep=0), noise, 13)


def kelvin_record(folder: Path, noise: float) -> Path:
    """The search's own creep law (the FMU's default Kelvin cells and slip), on the primary record's loads."""
    return _drawn(folder, "kelvin", "creep", *_creep_loads(), dict(stiffness=1, EA=3000.0, creep=1), noise, 14)


#: name -> (draw, the hidden effect, noise [m]); the last two need no wider law: their times with
#: and without the wider laws are the cost of the wider laws on records that do not need them
RECORDS = {"exponential": (exponential_record, "nonlinear_stiffness", 2e-4),
           "primary": (primary_record, "creep", 2e-5),
           "cubic": (cubic_record, "nonlinear_stiffness", 2e-4),
           "kelvin": (kelvin_record, "creep", 2e-5)}


def run(stem: Path, wider: bool) -> dict:
    import tether.discover.rival as rival
    import tether.discover.search as search
    from tether import discover
    from tether.traces import read_trace
    saved, models_for = dict(rival.WIDER_LAWS), search._models_for
    if not wider:
        # the search as it was: no wider law swapped in, no exponential candidate in a load test
        rival.WIDER_LAWS.clear()
        search._models_for = lambda spec, effect, trace: [m for m in models_for(spec, effect, trace)
                                                          if m.stiffness != "exponential"]
    try:
        t0 = time.perf_counter()
        d = discover(read_trace(stem))
        seconds = time.perf_counter() - t0
    finally:
        rival.WIDER_LAWS.update(saved)
        search._models_for = models_for
    laws = [r for r in d.refinements if r.law and "->" in r.law and r.law.split(" -> ")[1] in ("exponential", "primary")]
    return {"named": d.added_effects, "model": d.final.model, "rms_over_noise": d.final.rms / d.noise.sigma,
            "seconds": seconds, "wider": [f"{r.law}: {'kept' if r.accepted else 'not kept'}: {r.verdict}" for r in laws]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="one record: " + ", ".join(RECORDS))
    ap.add_argument("--noise-rel", type=float, default=1.0, help="scale the records' noise")
    ap.add_argument("--with-only", action="store_true", help="only the run with the wider laws")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name, (draw, hidden, noise) in RECORDS.items():
            if args.only and name != args.only:
                continue
            stem = draw(Path(tmp), noise * args.noise_rel)
            for wider in ((True,) if args.with_only else (False, True)):
                r = run(stem, wider)
                print(f"{name:12s} hidden {hidden:20s} {'with' if wider else 'without':7s} the wider laws: named "
                      f"{'+'.join(r['named']) or '(none)'} ({r['model']}), rmse_final {r['rms_over_noise']:.2f} x noise, "
                      f"{r['seconds']:.1f} s", flush=True)
                for line in r["wider"]:
                    print(f"    {line}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
