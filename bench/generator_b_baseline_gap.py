"""How far each trace of a generator-B draw stands from the best baseline model, in noise units.

    .venv/bin/python bench/generator_b_baseline_gap.py [--n 48] [--seed 7] [--only NAME,...]

The baseline is the trace format's: a linear spring (also in compression) and a viscous damper.
Load and creep tests: elongation = L load / EA, fitted in closed form. Dynamic tests: EA and c0
fitted by least squares, started from the generating tangent stiffness and damper (and EA +-3 %:
the output-error cost is multimodal in EA), each simulated in closed form (the free part) and by
a first-order-hold filter on a 0.5 ms grid (the forced part; it agrees with scipy's lsim to
1e-9 m), not by generator B's integrator. A null trace should sit at about 1.0; a trace with
effects well above the 1.5 that discovery must reach.
Prints a line per trace and a summary; never run this on the held-out draw while tuning.
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import cont2discrete, lfilter, ss2tf

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.generator_b import generate, suite  # noqa: E402
from bench.generator_b.experiments import force_function  # noqa: E402


def load_test_gap(meta: dict, columns: dict) -> float:
    F, y = columns["load"], columns["elongation"]
    compliance = float(F @ y / (F @ F))
    return float(np.sqrt(np.mean((y - compliance * F) ** 2)))


FINE_DT_S = 5e-4   # a first-order hold on this grid misses a 6 Hz force by ~3e-5 of its response


def linear_response(k: float, c: float, m: float, t: np.ndarray, f: np.ndarray, x0: float) -> np.ndarray:
    """Displacement of m x'' + c x' + k x = f from (x0, 0): the closed-form free part plus the
    forced part filtered through the oscillator discretized with a first-order hold."""
    w = math.sqrt(k / m)
    zeta = c / (2 * m * w)
    if zeta >= 1.0:
        return np.full(len(t), np.nan)
    wd = w * math.sqrt(1 - zeta ** 2)
    x = x0 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    if np.any(f):
        system = (np.array([[0.0, 1.0], [-k / m, -c / m]]), np.array([[0.0], [1.0 / m]]),
                  np.array([[1.0, 0.0]]), np.array([[0.0]]))
        num, den = ss2tf(*cont2discrete(system, t[1] - t[0], method="foh")[:4])
        x = x + lfilter(num[0], den, f)
    return x


def dynamic_gap(spec: dict, meta: dict, columns: dict) -> float:
    """Best baseline fit of a dynamic record (EA and c0 free), in metres RMS."""
    L, m = meta["tether"]["length_m"], meta["payload_mass_kg"]
    hidden = meta["hidden"]
    t = columns["time"]
    stride = int(round((t[1] - t[0]) / FINE_DT_S))
    fine = np.arange((len(t) - 1) * stride + 1) * (t[1] - t[0]) / stride
    if spec["experiment"] == "forced":
        f = force_function(hidden["input"], hidden["input"]["force_scale_n"])(fine)
    else:
        f = np.zeros(len(fine))
    x0 = meta["initial_displacement_m"]

    def residual(theta):
        x = linear_response(math.exp(theta[0]) / L, math.exp(theta[1]), m, fine, f, x0)
        r = x[::stride] - columns["displacement"]
        return np.where(np.isfinite(r), r, 1.0)

    EA_start = _tangent_at_balance(spec)
    c_start = max(hidden["parameters"]["damping"]["c0"], 1e-3)
    best = math.inf
    for factor in (1.0, 0.97, 1.03):
        fit = least_squares(residual, [math.log(EA_start * factor), math.log(c_start)], diff_step=1e-6,
                            x_scale=[0.01, 0.1], max_nfev=60)
        best = min(best, float(np.sqrt(np.mean(fit.fun ** 2))))
    return best


def _tangent_at_balance(spec: dict) -> float:
    from bench.generator_b.experiments import build_law
    from bench.generator_b.laws import elastic_strain_for

    law = build_law(spec, "elastic")
    return law.tangent(elastic_strain_for(law, spec["payload_mass_kg"] * 9.81))


ROLE_OF = {"nonlinear_stiffness": "elastic", "nonlinear_damping": "damping", "hysteresis": "hysteresis",
           "creep": "creep", "slack": "slack"}


def without_effect(spec: dict, effect: str) -> dict:
    """The generating spec with one effect's law put back to the baseline's (the rest true)."""
    spec = copy.deepcopy(spec)
    role = ROLE_OF[effect]
    if role == "elastic":
        spec["laws"]["elastic"], spec["params"]["elastic"] = "linear", {"EA": _reference_stiffness(spec)}
    elif role == "damping":
        spec["laws"]["damping"] = "viscous"
        spec["params"]["damping"] = {"c0": max(spec["params"]["damping"]["c0"], 1e-3)}
    elif role == "slack":
        spec["laws"]["slack"] = False
    else:
        spec["laws"][role] = None
    return spec


def _reference_stiffness(spec: dict) -> float:
    if "payload_mass_kg" in spec:
        return _tangent_at_balance(spec)
    from bench.generator_b.experiments import build_law, load_schedule
    from bench.generator_b.laws import elastic_strain_for

    top = float(np.max(load_schedule(spec["input"])[1]))
    return top / elastic_strain_for(build_law(spec, "elastic"), top)


def reduced_gap(spec: dict, columns: dict, effect: str) -> float:
    """RMS [m] of the truth without `effect`, its EA (and c0) refitted."""
    from bench.generator_b import dynamic, quasistatic
    from bench.generator_b.experiments import build_law, load_schedule, payload_model

    reduced = without_effect(spec, effect)
    dyn = "payload_mass_kg" in spec
    measured = columns["displacement"] if dyn else columns["elongation"]

    def residual(theta):
        trial = copy.deepcopy(reduced)
        EA = math.exp(theta[0])
        trial["laws"]["elastic"], trial["params"]["elastic"] = _scaled_elastic(reduced, EA)
        if dyn:
            trial["params"]["damping"]["c0"] = math.exp(theta[1])
            force = force_function(spec["input"], spec["input"]["force_scale_n"]) if "force_scale_n" in spec["input"] else None
            x0 = spec["input"].get("x0_m", 0.0)
            x = dynamic.simulate(payload_model(trial), columns["time"], x0, 0.0, force).x
        else:
            t, load = load_schedule(trial["input"])
            x = quasistatic.elongation(trial["tether"]["length_m"], build_law(trial, "elastic"),
                                       build_law(trial, "hysteresis"), build_law(trial, "creep"), t, load)["elongation"]
        r = x - measured
        return np.where(np.isfinite(r), r, 1.0)

    start = [math.log(_reference_stiffness(reduced))]
    if dyn:
        start.append(math.log(reduced["params"]["damping"]["c0"]))
    fit = least_squares(residual, start, diff_step=1e-5, max_nfev=30)
    return float(np.sqrt(np.mean(fit.fun ** 2)))


def _scaled_elastic(spec: dict, EA: float) -> tuple[str, dict]:
    """The spec's elastic law scaled so that its reference stiffness is EA."""
    name, params = spec["laws"]["elastic"], dict(spec["params"]["elastic"])
    scale = EA / _reference_stiffness(spec)
    for key in ("EA", "EA0", "k_toe"):
        if key in params:
            params[key] *= scale
    return name, params


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=48)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--only", default="", help="comma-separated trace names")
    ap.add_argument("--per-effect", action="store_true",
                    help="for traces with 2-3 effects, also the gap of the truth without each one "
                         "(its EA and c0 refitted): how much each effect shows on its own")
    args = ap.parse_args(argv)
    only = set(filter(None, args.only.split(",")))
    rows, per_effect = [], []
    for spec in suite(args.n, args.seed):
        if only and spec["name"] not in only:
            continue
        t0 = time.perf_counter()
        columns, meta = generate(copy.deepcopy(spec))
        spec = dict(spec, input=meta["hidden"]["input"])
        gap = load_test_gap(meta, columns) if "load" in columns else dynamic_gap(spec, meta, columns)
        ratio = gap / spec["noise_sigma"]
        rows.append((spec, ratio))
        print(f"{spec['name']:22s} {','.join(spec['effects']) or '(null)':50s} baseline rms / sigma "
              f"{ratio:9.2f}   ({time.perf_counter() - t0:.1f} s)", flush=True)
        if args.per_effect and len(spec["effects"]) > 1:
            for effect in spec["effects"]:
                own = reduced_gap(spec, columns, effect) / spec["noise_sigma"]
                per_effect.append(own)
                print(f"    without {effect:20s} rms / sigma {own:9.2f}", flush=True)
    nulls = [r for s, r in rows if not s["effects"]]
    effects = [r for s, r in rows if s["effects"]]
    if nulls:
        print(f"nulls: {len(nulls)}, baseline rms / sigma {min(nulls):.2f} .. {max(nulls):.2f}")
    if effects:
        print(f"with effects: {len(effects)}, smallest {min(effects):.2f}, median {np.median(effects):.1f}")
    if per_effect:
        print(f"each effect of a combination on its own: smallest {min(per_effect):.2f}, "
              f"median {np.median(per_effect):.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
