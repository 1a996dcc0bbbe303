#!/usr/bin/env python3
"""How far the element rig coupled with a point-mass FMU lands from the payload rig, by step.

The payload rig split in two FMUs (python_tests/test_fmu_cosim_switches.py checks one point of
this in fmpy, libcosim and ecos): KevlarTether in its element rig takes the mass's position and
velocity as elongation and its rate, the mass (build/fixtures/PointMass.fmu) takes the tension.
Both FMUs step together, each holding its inputs over the step (Jacobi, as libcosim and ecos do),
a delay of one step round the loop: the error is of first order in the step. Prints the largest
distance from the payload rig over 5 s, for a release that keeps the tether taut (0.15 m below the
balance) and one where it goes slack (0.35 m). Linear law, viscous damping, Bouc-Wen, BDF.

usage: python bench/bench_cosim_coupling.py [--steps 1e-3,1e-4]
"""
import argparse
import time
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

REPO = Path(__file__).resolve().parents[1]
TETHER_FMU = REPO / "build" / "KevlarTether.fmu"
MASS_FMU = REPO / "build" / "fixtures" / "PointMass.fmu"
SWITCHES = dict(stiffness=1, damping=1, hysteresis=3, integrator=2)
T_END = 5.0


def slave(path: Path, name: str, integers=None, reals=None):
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    s = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    for k, v in (integers or {}).items():
        s.setInteger([vr[k]], [v])
    for k, v in (reals or {}).items():
        s.setReal([vr[k]], [v])
    s.enterInitializationMode()
    s.exitInitializationMode()
    return s, vr


def payload(x0: float, h: float, n: int):
    s, vr = slave(TETHER_FMU, "payload", SWITCHES | dict(rig=2), dict(x0=x0))
    bal = s.getReal([vr["balance_elongation"]])[0]
    x = [s.getReal([vr["displacement"]])[0]]
    for k in range(n):
        s.doStep(k * h, h)
        x.append(s.getReal([vr["displacement"]])[0])
    s.terminate()
    s.freeInstance()
    return np.array(x), bal


def coupled(x0: float, bal: float, h: float, n: int):
    t, tv = slave(TETHER_FMU, "element", SWITCHES | dict(rig=1), dict(elongation=bal + x0))
    m, mv = slave(MASS_FMU, "mass", reals=dict(position0=bal + x0))
    x = []
    for k in range(n + 1):
        pos, vel = m.getReal([mv["position"], mv["velocity"]])
        x.append(pos - bal)
        if k == n:
            break
        tension = t.getReal([tv["tension"]])[0]
        t.setReal([tv["elongation"], tv["elongation_rate"]], [pos, vel])
        m.setReal([mv["tether_force"]], [tension])
        t.doStep(k * h, h)
        m.doStep(k * h, h)
    for s in (t, m):
        s.terminate()
        s.freeInstance()
    return np.array(x)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", default="1e-3,1e-4", help="communication steps [s], comma-separated")
    args = ap.parse_args()
    for path in (TETHER_FMU, MASS_FMU):
        if not path.is_file():
            raise SystemExit(f"{path} not found: build it (cmake --build build)")
    print("step [s]  release [m]  max |x - x_payload| [m]  wall [s]")
    for h in (float(s) for s in args.steps.split(",")):
        n = int(round(T_END / h))
        for x0 in (0.15, 0.35):
            t0 = time.perf_counter()
            ref, bal = payload(x0, h, n)
            diff = float(np.max(np.abs(coupled(x0, bal, h, n) - ref)))
            slack = " (goes slack)" if ref.min() < -bal else ""
            print(f"{h:8.0e}  {x0:11.2f}  {diff:24.3g}  {time.perf_counter() - t0:8.1f}{slack}", flush=True)


if __name__ == "__main__":
    main()
