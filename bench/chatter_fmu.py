#!/usr/bin/env python3
"""Timings of the Kawabata + slack + displacement-damping payload under a steady force (issue 27,
F5): the sliding regime that once piled up events. Prints; asserts nothing.

    .venv/bin/python bench/chatter_fmu.py [--fmu build/KevlarTether.fmu] [--repeat 3]

1. One fmi2DoStep(0, 5) of the payload rig (linear stiffness, displacement damping, Kawabata
   hysteresis, slack) under a constant force of 100 N: wall time, status, events, final tension
   against the static balance m g + f.
2. A forced trace of 2,001 samples (dt = 5 ms) with a constant force of 100 N, simulated with
   tether.run.simulate for the models kawabata+nonlinear_damping+slack and kawabata+slack (the
   same model without nonlinear damping): wall time of each and their ratio (target: within 2x).
"""
import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

import this_tree  # noqa: E402  (bench/, this file's folder, is on sys.path)

REPO = this_tree.use()

F5_SWITCHES = dict(rig=2, stiffness=1, damping=2, hysteresis=2, slack=True)


def f5_step(repeat: int):
    import fmu_harness as H
    best = None
    for _ in range(repeat):
        inst = H.cs(dict(F5_SWITCHES, force=100.0), categories=["logEvents"])
        t0 = time.perf_counter()
        st = inst.do_step(0.0, 5.0)
        dt = time.perf_counter() - t0
        _, (T,) = inst.get_reals_raw([H.vr("tension")])
        m, g = inst.get("m", "g")
        events = sum(1 for msg in inst.log.in_category("logEvents") if "reversal" in msg or "rejoin" in msg or "goes" in msg)
        inst.free()
        if best is None or dt < best[0]:
            best = (dt, st, events, T, m * g + 100.0)
    dt, st, events, T, balance = best
    print(f"F5 step fmi2DoStep(0, 5): {dt * 1e3:.1f} ms (best of {repeat}), status {H.STATUS_NAMES[st]}, "
          f"{events} events, tension {T:.3f} N (balance m g + f = {balance:.3f} N)")


def forced_trace(repeat: int):
    from tether.run import simulate
    with tempfile.TemporaryDirectory(prefix="kt-chatter-") as d:
        stem = Path(d) / "forced_100N"
        t = np.arange(2001) * 0.005
        np.savetxt(f"{stem}.csv", np.column_stack([t, np.full_like(t, 100.0), np.zeros_like(t)]),
                   delimiter=",", header="time,force,displacement", comments="")
        Path(f"{stem}.json").write_text(json.dumps({"format": "tether-trace/1", "experiment": "forced",
                                                     "tether": {"length_m": 16.0}, "payload_mass_kg": 4.3}))
        times = {}
        for model in ("kawabata+nonlinear_damping+slack", "kawabata+slack"):
            best = None
            for _ in range(repeat):
                t0 = time.perf_counter()
                try:
                    r = simulate(f"{stem}.csv", model)
                    ok = f"tension {np.min(r.tension):.2f}..{np.max(r.tension):.2f} N"
                except Exception as e:  # noqa: BLE001 -- a bench reports what happened
                    ok = f"failed: {e}"
                dt = time.perf_counter() - t0
                best = dt if best is None else min(best, dt)
            times[model] = best
            print(f"forced trace, 2,001 samples, {model}: {best:.3f} s (best of {repeat}); {ok}")
        a, b = times["kawabata+nonlinear_damping+slack"], times["kawabata+slack"]
        print(f"ratio with / without nonlinear damping: {a / b:.2f} (target <= 2)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu", type=Path, default=REPO / "build" / "KevlarTether.fmu")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    os.environ["KT_FMU"] = str(a.fmu.resolve())
    print(f"chatter_fmu: {a.fmu} ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())})")
    f5_step(a.repeat)
    forced_trace(a.repeat)


if __name__ == "__main__":
    main()
