"""From a spec (a JSON-able dict drawn by draw.py) to the columns and metadata of one trace."""

from __future__ import annotations

import copy
import math

import numpy as np
from scipy.optimize import brentq

from . import dynamic, quasistatic
from .laws import (AmplitudeDamping, BurgersCreep, CoulombViscousDamping, DahlHysteresis,
                   ExponentialElastic, FindleyCreep, LinearElastic, StopBankHysteresis,
                   ToeLinearElastic, ViscousDamping, elastic_strain_for)

GENERATOR = "generator_b/1"

LAWS = {
    "linear": LinearElastic, "exponential": ExponentialElastic, "toe_linear": ToeLinearElastic,
    "viscous": ViscousDamping, "coulomb_viscous": CoulombViscousDamping, "amplitude": AmplitudeDamping,
    "dahl": DahlHysteresis, "pi_stop": StopBankHysteresis,
    "burgers": BurgersCreep, "findley": FindleyCreep,
}

REVEALABLE = {
    "free_vibration": ["nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"],
    "forced": ["nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"],
    "load_unload": ["nonlinear_stiffness", "hysteresis", "creep"],
    "creep": ["creep", "nonlinear_stiffness"],
}

CALIBRATION_TOLERANCE = 0.01    # in log(force scale)
CALIBRATION_ROUNDS = 12


def build_law(spec: dict, role: str):
    """The law object of one role (elastic, damping, hysteresis, creep), or None."""
    name = spec["laws"].get(role)
    return None if name is None else LAWS[name](**spec["params"][role])


def generate(spec: dict) -> tuple[dict, dict]:
    """(columns, metadata) of the trace a spec describes, noise included (the spec is not changed)."""
    spec = copy.deepcopy(spec)
    if spec["experiment"] in ("free_vibration", "forced"):
        columns, diagnostics, extra_meta = _dynamic(spec)
        measured = "displacement"
    else:
        columns, diagnostics, extra_meta = _load_test(spec)
        measured = "elongation"
    rng = np.random.default_rng(spec["noise_seed"])
    columns[measured] = columns[measured] + spec["noise_sigma"] * rng.standard_normal(len(columns["time"]))
    return columns, _metadata(spec, extra_meta, diagnostics)


def _metadata(spec: dict, extra: dict, diagnostics: dict) -> dict:
    meta = {"format": "tether-trace/1", "experiment": spec["experiment"], "tether": dict(spec["tether"])}
    meta.update(extra)
    meta["description"] = f"synthetic {spec['experiment']} test (generator B); the truth is under 'hidden'"
    meta["hidden"] = {
        "generator": GENERATOR,
        "effects": sorted(spec["effects"]),
        "revealable": REVEALABLE[spec["experiment"]],
        "laws": spec["laws"],
        "parameters": spec["params"],
        "input": spec["input"],
        "record": spec.get("record"),
        "noise_sigma": spec["noise_sigma"],
        "noise_seed": spec["noise_seed"],
        "diagnostics": diagnostics,
        "suite_seed": spec.get("suite_seed"),
    }
    return meta


# ---------------------------------------------------------------------------------------------
# dynamic tests


def payload_model(spec: dict) -> dynamic.PayloadModel:
    elastic = build_law(spec, "elastic")
    mass, g = spec["payload_mass_kg"], spec["gravity_m_s2"]
    u_b = spec["tether"]["length_m"] * elastic_strain_for(elastic, mass * g)
    return dynamic.PayloadModel(length_m=spec["tether"]["length_m"], mass_kg=mass, gravity=g,
                                elastic=elastic, damping=build_law(spec, "damping"),
                                hysteresis=build_law(spec, "hysteresis"),
                                slack=bool(spec["laws"]["slack"]), u_balance=u_b)


def force_function(inp: dict, scale: float):
    """The external force [N] of a forced test as a function of time (float or array); it fades
    in over `fade_in_s` with a sin^2 ramp so that it starts smoothly from rest."""
    fade = inp["fade_in_s"]
    if inp["kind"] == "multisine":
        freqs = np.asarray(inp["frequencies_hz"], float)
        phases = np.asarray(inp["phases_rad"], float)
        norm = scale / math.sqrt(len(freqs))

        def shape(t):
            return norm * np.cos(2 * np.pi * np.multiply.outer(t, freqs) + phases).sum(axis=-1)
    else:
        fa, fb, T = inp["f_start_hz"], inp["f_end_hz"], inp["sweep_s"]

        def shape(t):
            return scale * np.sin(2 * np.pi * (fa * t + 0.5 * (fb - fa) * t * t / T))

    def force(t):
        t = np.asarray(t, float)
        ramp = np.where(t >= fade, 1.0, np.sin(0.5 * np.pi * np.clip(t, 0.0, fade) / fade) ** 2)
        return ramp * shape(t)
    return force


def sample_times(record: dict) -> np.ndarray:
    n = int(round(record["duration_s"] * record["fs_hz"]))
    return np.arange(n + 1) / record["fs_hz"]


def _dynamic(spec: dict):
    model = payload_model(spec)
    t = sample_times(spec["record"])
    inp = spec["input"]
    if spec["experiment"] == "free_vibration":
        res = dynamic.simulate(model, t, inp["x0_m"], 0.0)
        columns = {"time": t, "displacement": res.x}
        extra = {"payload_mass_kg": spec["payload_mass_kg"], "gravity_m_s2": spec["gravity_m_s2"],
                 "initial_displacement_m": inp["x0_m"], "initial_velocity_m_s": 0.0}
    else:
        if "force_scale_n" in inp:    # a spec written out after calibration keeps its force
            scale = inp["force_scale_n"]
            res = dynamic.simulate(model, t, 0.0, 0.0, force_function(inp, scale))
        else:
            scale, res = _calibrated_force(model, t, inp)
        inp["force_scale_n"] = scale
        inp["target"]["reached"] = _excursion(res, inp["target"])
        force = force_function(inp, scale)
        columns = {"time": t, "force": force(t), "displacement": res.x}
        extra = {"payload_mass_kg": spec["payload_mass_kg"], "gravity_m_s2": spec["gravity_m_s2"],
                 "initial_displacement_m": 0.0, "initial_velocity_m_s": 0.0}
    _check_dynamic(spec, model, res)
    diagnostics = {"u_balance_m": model.u_balance, "slack_time_s": res.slack_time_s,
                   "slack_events": len(res.events), "starts_slack": res.starts_slack,
                   "min_strain": float(np.min(res.x + model.u_balance) / model.length_m),
                   "max_abs_displacement_m": float(np.max(np.abs(res.x)))}
    return columns, diagnostics, extra


def _excursion(res: dynamic.DynamicResult, target: dict) -> float:
    return float(np.max(-res.x)) if target["kind"] == "peak_up" else float(np.max(np.abs(res.x)))


def _calibrated_force(model, t, inp):
    """Scale the force until the response reaches its target excursion: bracket the scale by
    factors of 3, then Brent's method on log(excursion / target) in log(scale), to 1 %."""
    runs = {}

    def gap(log_scale: float) -> float:
        if log_scale not in runs:
            runs[log_scale] = dynamic.simulate(model, t, 0.0, 0.0, force_function(inp, math.exp(log_scale)))
        res = runs[log_scale]
        return math.log(max(_excursion(res, inp["target"]), 1e-12) / inp["target"]["value"])

    lo = hi = 0.0
    g_lo = g_hi = gap(0.0)
    step = math.log(3.0) * (-1.0 if g_lo > 0 else 1.0)
    for _ in range(CALIBRATION_ROUNDS):
        if g_lo * g_hi <= 0.0 and lo != hi:
            break
        lo, g_lo = hi, g_hi
        hi = hi + step
        g_hi = gap(hi)
    else:
        raise GenerationError(f"force scale for {inp['target']} not bracketed between e^{lo:.2f} and e^{hi:.2f} N")
    best = brentq(gap, min(lo, hi), max(lo, hi), xtol=CALIBRATION_TOLERANCE) if g_hi != 0.0 else hi
    if best not in runs:
        gap(best)
    return math.exp(best), runs[best]


def _check_dynamic(spec: dict, model, res) -> None:
    """Slack must act when it is hidden, and the tether stay taut when it is not."""
    name = spec["name"]
    if model.slack and res.slack_time_s <= 0.0:
        raise GenerationError(f"{name}: slack is hidden but the tether never goes slack")
    if not model.slack and res.min_tension_candidate <= 0.0:
        raise GenerationError(f"{name}: no slack hidden but the tension reaches {res.min_tension_candidate:.3g} N")


class GenerationError(RuntimeError):
    """A drawn spec does not make the trace it promises."""


# ---------------------------------------------------------------------------------------------
# load-controlled tests


def load_schedule(inp: dict) -> tuple[np.ndarray, np.ndarray]:
    """Times and loads of a schedule of segments: each ramps (or holds) to `load_n` over
    `duration_s`, sampled every `dt_s`; corners fall on samples."""
    times, loads = [0.0], [inp["initial_load_n"]]
    for seg in inp["segments"]:
        n = max(1, int(round(seg["duration_s"] / seg["dt_s"])))
        t0, f0 = times[-1], loads[-1]
        for j in range(1, n + 1):
            times.append(t0 + seg["dt_s"] * j)
            loads.append(f0 + (seg["load_n"] - f0) * j / n)
    return np.array(times), np.array(loads)


def _load_test(spec: dict):
    t, load = load_schedule(spec["input"])
    out = quasistatic.elongation(spec["tether"]["length_m"], build_law(spec, "elastic"),
                                 build_law(spec, "hysteresis"), build_law(spec, "creep"), t, load)
    columns = {"time": t, "load": load, "elongation": out["elongation"]}
    diagnostics = {"max_creep_elongation_m": float(spec["tether"]["length_m"] * np.ptp(out["creep_strain"])),
                   "max_elastic_strain": float(np.max(out["elastic_strain"]))}
    return columns, diagnostics, {}
