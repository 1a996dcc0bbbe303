"""The reproducible draw of a suite: which experiment, which effects, which laws, which numbers.

Magnitudes follow the paper's rigs: braided Kevlar 1.5-2.0 mm, 8-16 m, payloads 2-6 kg, a tangent
EA of 2-6 kN near the working load, creep tests at 40-100 N unloaded to 5 N, load-unload tests with
3-6 kg weights. Every effect is sized against the motion it acts on (a damping ratio, a fraction of
the stiffness, a strain of the record), so that it shows well above the noise.
"""

from __future__ import annotations

import math

import numpy as np

from .experiments import LAWS, REVEALABLE
from .laws import elastic_strain_for

G = 9.81
EFFECT_LAWS = {
    "nonlinear_stiffness": ["exponential", "toe_linear"],
    "hysteresis": ["dahl", "pi_stop"],
    "nonlinear_damping": ["coulomb_viscous", "amplitude"],
    "creep": ["burgers", "findley"],
}
SIZE_WEIGHTS = {1: 0.45, 2: 0.40, 3: 0.15}
NULL_SHARE = 0.2


def suite(n: int = 48, seed: int = 2026) -> list[dict]:
    """n specs: a third free vibration, a third forced, a sixth load-unload, a sixth creep; about a
    fifth of each with no effect at all (the format's baseline)."""
    rng = np.random.default_rng(seed)
    n_fv = n_forced = round(n / 3)
    n_lu = (n - n_fv - n_forced) // 2
    counts = {"free_vibration": n_fv, "forced": n_forced, "load_unload": n_lu,
              "creep": n - n_fv - n_forced - n_lu}
    experiments = [e for e, c in counts.items() for _ in range(c)]
    effect_sets = []
    for exp, c in counts.items():
        effect_sets += _effect_sets(rng, exp, c)
    order = rng.permutation(len(experiments))
    specs = []
    for idx, k in enumerate(order):
        spec = draw_spec(rng, experiments[k], effect_sets[k])
        spec["name"] = f"b{idx:02d}_{experiments[k]}"
        spec["suite_seed"] = seed
        specs.append(spec)
    return specs


def _effect_sets(rng, experiment: str, count: int) -> list[list[str]]:
    allowed = REVEALABLE[experiment]
    n_null = round(count * NULL_SHARE)
    sets = [[] for _ in range(n_null)]
    sizes, weights = list(SIZE_WEIGHTS), np.array(list(SIZE_WEIGHTS.values()))
    for _ in range(count - n_null):
        size = min(int(rng.choice(sizes, p=weights / weights.sum())), len(allowed))
        sets.append(sorted(str(e) for e in rng.choice(allowed, size=size, replace=False)))
    return [sets[i] for i in rng.permutation(count)]


def draw_spec(rng, experiment: str, effects: list[str]) -> dict:
    """One spec with its laws and numbers."""
    laws = {"elastic": "linear", "damping": "viscous", "hysteresis": None, "creep": None,
            "slack": "slack" in effects}
    for effect, role in (("nonlinear_stiffness", "elastic"), ("nonlinear_damping", "damping"),
                         ("hysteresis", "hysteresis"), ("creep", "creep")):
        if effect in effects:
            laws[role] = str(rng.choice(EFFECT_LAWS[effect]))
    spec = {"experiment": experiment, "effects": list(effects), "laws": laws, "params": {},
            "tether": {"length_m": round(float(rng.uniform(8.0, 16.0)), 1),
                       "diameter_mm": float(rng.choice([1.5, 1.8, 2.0]))},
            "noise_seed": int(rng.integers(2**31))}
    if experiment in ("free_vibration", "forced"):
        _draw_dynamic(rng, spec)
    else:
        _draw_load_test(rng, spec)
    return spec


def _u(rng, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _log_u(rng, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


# ---------------------------------------------------------------------------------------------
# dynamic tests


def _draw_dynamic(rng, spec: dict) -> None:
    L, laws = spec["tether"]["length_m"], spec["laws"]
    m = round(_u(rng, 2.0, 6.0), 2)
    EA_b = _u(rng, 2000.0, 6000.0)
    spec.update(payload_mass_kg=m, gravity_m_s2=G)
    eps_lin = m * G / EA_b
    u_lin = eps_lin * L
    if laws["slack"]:
        strain_span = None                            # the motion spans 0 .. beyond balance
    else:
        amplitude = min(_u(rng, 0.35, 0.7) * u_lin, 0.2)
        strain_span = 2 * amplitude / L
    forced = spec["experiment"] == "forced"
    spec["params"]["elastic"] = _dynamic_elastic(rng, laws["elastic"], EA_b, m * G, strain_span, eps_lin, forced)
    elastic = LAWS[laws["elastic"]](**spec["params"]["elastic"])
    u_b = L * elastic_strain_for(elastic, m * G)
    if laws["slack"]:
        amplitude = _u(rng, 1.15, 1.6) * u_b
    k = EA_b / L
    omega = math.sqrt(k / m)
    _draw_dynamic_input(rng, spec, amplitude, omega)
    spec["params"]["damping"] = _dynamic_damping(rng, laws["damping"], m, omega, k, amplitude, forced,
                                                 light=bool(laws["hysteresis"] or laws["damping"] != "viscous"))
    if laws["hysteresis"]:
        spec["params"]["hysteresis"] = _dynamic_hysteresis(rng, laws["hysteresis"], k, L, amplitude, EA_b)
    spec["noise_sigma"] = min(_log_u(rng, 3e-5, 2e-4), amplitude / 300.0)


def _dynamic_elastic(rng, name: str, EA_b: float, weight: float, strain_span, eps_lin: float,
                     forced: bool) -> dict:
    """Elastic law whose tangent near balance is about EA_b and whose nonlinearity shows across
    the strains the motion visits (strain_span; None for a slack record, which spans 0..2 eps).
    A forced record reaches its largest strains only at its peaks, so it gets a stronger law."""
    if name == "linear":
        return {"EA": EA_b}
    span = strain_span if strain_span is not None else 2.0 * eps_lin
    if name == "exponential":
        ratio = _u(rng, 1.8, 3.0) if forced else _u(rng, 1.4, 2.2)
        eps_c = max(span / math.log(ratio), 1.3 * weight / EA_b)
        return {"EA0": EA_b - weight / eps_c, "eps_c": eps_c}
    ratio = _u(rng, 0.25, 0.55)
    if strain_span is None:
        eps_t = _u(rng, 0.3, 0.6) * eps_lin
    else:   # balance above the toe, the corner a fraction beta of the half span below it
        eps_t = (eps_lin - _u(rng, 0.2, 0.6) * strain_span / 2) / ratio
    return {"k_toe": ratio * EA_b, "EA": EA_b, "eps_t": eps_t, "width": _u(rng, 0.1, 0.25) * eps_t}


def _dynamic_damping(rng, name: str, m: float, omega: float, k: float, amplitude: float, forced: bool,
                     light: bool) -> dict:
    critical = 2.0 * m * omega
    c0 = (_u(rng, 0.002, 0.006) if light else _u(rng, 0.004, 0.02)) * critical
    if name == "viscous":
        return {"c0": c0}
    if name == "coulomb_viscous":
        return {"c0": c0, "F_c": _u(rng, 0.004, 0.01) * math.pi * k * amplitude / 2,
                "v_s": _u(rng, 0.02, 0.06) * omega * amplitude}
    # the damping must change over the amplitudes the record visits: a forced record spends most
    # of its time below its peak, a free one decays through them
    c1 = _u(rng, 0.04, 0.08) if forced else _u(rng, 0.02, 0.05)
    A_d = (_u(rng, 0.5, 1.2) if forced else _u(rng, 0.25, 0.6)) * amplitude
    return {"c0": c0, "c1": c1 * critical, "A_d": A_d,
            "omega": omega}


def _dynamic_hysteresis(rng, name: str, k: float, L: float, amplitude: float, EA_b: float) -> dict:
    if name == "dahl":
        F_sat = _u(rng, 0.006, 0.015) * math.pi * k * amplitude / 2
        return {"k": F_sat * L / (_u(rng, 0.15, 0.5) * amplitude), "F_sat": F_sat,
                "asym": _u(rng, -0.4, 0.4)}
    return {"stiffness": _u(rng, 0.06, 0.2) * EA_b, "r_max": _u(rng, 0.3, 1.0) * amplitude / L,
            "alpha": _u(rng, 0.5, 2.5), "count": int(rng.integers(12, 25))}


def _draw_dynamic_input(rng, spec: dict, amplitude: float, omega: float) -> None:
    fs = int(rng.choice([100, 200, 250, 500, 1000], p=[0.25, 0.3, 0.15, 0.2, 0.1]))
    f_n = omega / (2 * math.pi)
    slack = spec["laws"]["slack"]
    if spec["experiment"] == "free_vibration":
        spec["record"] = {"fs_hz": fs, "duration_s": round(_u(rng, 10.0, 30.0), 1)}
        upward = rng.random() < (0.7 if slack else 0.5)
        x0 = -amplitude if upward else amplitude
        spec["input"] = {"x0_m": round(x0, 5)}
        return
    duration = round(_u(rng, 20.0, 40.0), 1)
    spec["record"] = {"fs_hz": fs, "duration_s": duration}
    target = {"kind": "peak_up" if slack else "peak_abs", "value": amplitude}
    if rng.random() < 0.6:
        n_lines = int(rng.integers(8, 21))
        freqs = sorted(float(f) for f in rng.uniform(0.4, 2.0, n_lines) * f_n)
        spec["input"] = {"kind": "multisine", "frequencies_hz": freqs,
                         "phases_rad": [float(p) for p in rng.uniform(0, 2 * math.pi, n_lines)],
                         "fade_in_s": 1.0, "target": target}
    else:
        spec["input"] = {"kind": "sweep", "f_start_hz": 0.4 * f_n, "f_end_hz": 2.0 * f_n,
                         "sweep_s": duration, "fade_in_s": 1.0, "target": target}


# ---------------------------------------------------------------------------------------------
# load-controlled tests


def _draw_load_test(rng, spec: dict) -> None:
    laws, creep_test = spec["laws"], spec["experiment"] == "creep"
    EA = _u(rng, 2000.0, 6000.0)
    if creep_test:
        F0, F1 = 5.0, round(_u(rng, 40.0, 100.0), 1)
        spec["input"] = _creep_schedule(rng, F0, F1)
    else:
        F0, F1 = round(_u(rng, 2.0, 5.0), 2), float(rng.choice([3, 4, 5, 6])) * G
        spec["input"] = _load_unload_schedule(rng, F0, F1)
    eps_max = F1 / EA
    spec["params"]["elastic"] = _load_elastic(rng, laws["elastic"], EA, F1, eps_max)
    if laws["hysteresis"]:
        spec["params"]["hysteresis"] = _load_hysteresis(rng, laws["hysteresis"], EA, F1, eps_max)
    if laws["creep"]:
        spec["params"]["creep"] = _creep_law(rng, laws["creep"], F1, spec["input"], creep_test)
    spec["noise_sigma"] = _log_u(rng, 1e-5, 5e-5)


def _load_elastic(rng, name: str, EA: float, F1: float, eps_max: float) -> dict:
    if name == "linear":
        return {"EA": EA}
    if name == "exponential":
        eps_c = eps_max / math.log(_u(rng, 1.5, 3.0))
        return {"EA0": F1 / (eps_c * math.expm1(eps_max / eps_c)), "eps_c": eps_c}
    eps_t = _u(rng, 0.25, 0.5) * eps_max
    return {"k_toe": _u(rng, 0.25, 0.55) * EA, "EA": EA, "eps_t": eps_t, "width": _u(rng, 0.1, 0.3) * eps_t}


def _load_hysteresis(rng, name: str, EA: float, F1: float, eps_max: float) -> dict:
    if name == "dahl":
        F_sat = _u(rng, 0.03, 0.08) * F1
        return {"k": F_sat / (_u(rng, 0.1, 0.3) * eps_max), "F_sat": F_sat, "asym": _u(rng, -0.4, 0.4)}
    return {"stiffness": _u(rng, 0.1, 0.3) * EA, "r_max": _u(rng, 0.1, 0.4) * eps_max,
            "alpha": _u(rng, 0.5, 2.5), "count": int(rng.integers(12, 25))}


def _creep_law(rng, name: str, F1: float, schedule: dict, creep_test: bool) -> dict:
    """Creep sized by the strain it adds at the top load over the test's time scale."""
    hold = schedule["loaded_hold_s"] if creep_test else 300.0
    if name == "burgers":
        recoverable = _u(rng, 1.5e-4, 5e-4) if creep_test else _u(rng, 1e-4, 3e-4)
        flow = _u(rng, 1e-4, 4e-4) if creep_test else _u(rng, 0.5e-4, 1.5e-4)
        tau = _u(rng, 900.0, 3600.0) if creep_test else _u(rng, 30.0, 200.0)
        return {"K": F1 / recoverable, "tau": tau, "eta": F1 * hold / flow}
    n = _u(rng, 0.15, 0.35) if creep_test else _u(rng, 0.2, 0.4)
    F_s = _u(rng, 0.5, 1.5) * F1
    total = _u(rng, 3e-4, 8e-4) if creep_test else _u(rng, 1.5e-4, 4e-4)
    g = F_s * math.sinh(F1 / F_s)
    return {"b": total / (g * hold ** n), "n": n, "F_s": F_s,
            "preload_age": _u(rng, 600.0, 3600.0)}


def _creep_schedule(rng, F0: float, F1: float) -> dict:
    """Hang the weight (a short ramp, sampled each second), hold 1.5-3 h, unload to 5 N, hold 1-2 h;
    sometimes in two steps up."""
    ramp, dt_hold = _u(rng, 10.0, 60.0), float(rng.choice([10.0, 20.0, 30.0]))
    up = [{"load_n": F1, "duration_s": round(ramp), "dt_s": 1.0}]
    if rng.random() < 0.4:
        half = round(F1 / 2, 1)
        up = [{"load_n": half, "duration_s": round(ramp / 2), "dt_s": 1.0},
              {"load_n": half, "duration_s": 1800.0, "dt_s": dt_hold},
              {"load_n": F1, "duration_s": round(ramp / 2), "dt_s": 1.0}]
    hold = round(_u(rng, 1.5, 3.0) * 3600 / dt_hold) * dt_hold
    rest = round(_u(rng, 1.0, 2.0) * 3600 / dt_hold) * dt_hold
    segments = up + [{"load_n": F1, "duration_s": hold, "dt_s": dt_hold},
                     {"load_n": F0, "duration_s": round(ramp), "dt_s": 1.0},
                     {"load_n": F0, "duration_s": rest, "dt_s": dt_hold}]
    return {"initial_load_n": F0, "segments": segments, "loaded_hold_s": hold}


def _load_unload_schedule(rng, F0: float, F1: float) -> dict:
    """Up to the weight, hold, down to a middle load, back up (a minor loop), down, hold."""
    dt = float(rng.choice([0.5, 1.0, 2.0]))
    rate = _u(rng, 0.2, 1.0)
    mid, top2 = _u(rng, 0.3, 0.6) * F1, _u(rng, 0.7, 0.9) * F1

    def ramp(a, b):
        return {"load_n": round(b, 3), "duration_s": max(dt, round(abs(b - a) / rate / dt) * dt), "dt_s": dt}

    hold1 = round(_u(rng, 60.0, 240.0) / dt) * dt
    hold2 = round(_u(rng, 60.0, 240.0) / dt) * dt
    return {"initial_load_n": F0, "segments": [
        ramp(F0, F1), {"load_n": round(F1, 3), "duration_s": hold1, "dt_s": dt},
        ramp(F1, mid), ramp(mid, top2), ramp(top2, F0),
        {"load_n": F0, "duration_s": hold2, "dt_s": dt}]}
