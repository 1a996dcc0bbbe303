"""The parameters of a fit: which ones the data of an experiment determine (the free ones by
default), which names a fit accepts, and each one's bounds, start and scale (log or linear)."""

from __future__ import annotations

import math
from typing import Iterable

from .. import identify_native as idn
from .. import nuisance as NZ
from ..models import C_OF_MAGNITUDE, IWAN_K, IWAN_K_FIT, ModelSpec, TRACE_PARAMETERS, SWITCHES, parse_model
from .result import FitError

#: fitted on a log scale (one sign; the engine's steps are relative)
LOG_SCALED = {"EA", "a1", "exp_F", "exp_eps", "toe_EA", "toe_eps", "toe_width", "c_coulomb", "coulomb_v", "primary_J", "primary_tau", "c0", "bw_A",
              "kaw_F_ref", "kaw_eps_ref", "creep_J1", "creep_J2", "creep_J3",
              "creep_tau1", "creep_tau2", "creep_tau3", "slip_capacity0", "slip_rate", "slip_knee",
              "slip_load_half", "slip_load_exponent", "slip_regen_tau", "slip_limit", *IWAN_K}
#: the elastic law and the damping's size (viscous, and a Coulomb friction where the law has one): the first stage
FIRST_STAGE = {"EA", "a1", "a2", "a3", "exp_F", "exp_eps", "toe_EA", "toe_eps", "toe_width", "c0", "c_coulomb", "kaw_LT", "kaw_RT", "kaw_F_ref", "kaw_residual", "kaw_eps_ref"}
#: the creep terms a fit frees by default, by creep law: the Kelvin compliances and the slip, or the
#: primary creep's compliance, onset time and exponent of time
CREEP_FREE_BY_LAW = {"kelvin_slip": ("creep_J1", "creep_J2", "creep_J3", "slip_capacity0", "slip_rate"),
                     "primary": ("creep_J1", "creep_J2", "creep_J3", "primary_J", "primary_tau", "primary_n")}


def model_spec(model) -> ModelSpec:
    """The ModelSpec of a model string (a ModelSpec as it is)."""
    return parse_model(model) if isinstance(model, str) else model


def default_free_parameters(spec, experiment: str) -> list[str]:
    """The parameters the data of ``experiment`` can determine for ``spec``.

    Elastic law: ``EA``; cubic ``a1 a2 a3``; exponential ``exp_F exp_eps``; bilinear ``EA toe_EA toe_eps toe_width``; Kawabata ``kaw_LT kaw_RT kaw_F_ref`` plus the residual
    strain ``kaw_residual`` where the load returns to zero (load tests; ``kaw_eps_ref`` stays fixed:
    the virgin curve through (eps_ref, F_ref) is one curve, a point on it is one number).
    Damping (payload rig only; quasi-static load tests do not see it): ``c0``, plus ``c1 c2`` for
    displacement-dependent damping. Bouc-Wen: ``bw_A bw_beta bw_gamma`` (the force scale is fixed by
    the law; ``bw_n`` stays at its value and the shape terms ``bw_b2..b6`` at 0). Iwan: the element
    stiffnesses ``iw_k1..8`` (their slip strains stay on the grid the estimate chose, see
    iwan_slip_grid; elements 9..16 stay absent). Creep (creep tests
    only; seconds of vibration do not see it): the Kelvin compliances ``creep_J1..3`` (time
    constants fixed at their values, spanning minutes to days) and the slip ``slip_capacity0``,
    ``slip_rate`` (primary creep: ``primary_J primary_tau primary_n`` in the slip's place); a creep test holds two load levels, which determine ``EA`` but not a cubic or
    Kawabata law (held at its values: fit it on a load test and pass it with ``fixed``).
    """
    spec = model_spec(spec).for_experiment(experiment)
    # two load levels cannot determine a three-coefficient law: fit it on a load test
    many = experiment == "creep" and (spec.stiffness != "linear" or spec.hysteresis == "kawabata")
    names = law_free_parameters(spec, elastic=not many)
    if spec.creep and experiment == "creep":
        names += CREEP_FREE_BY_LAW[spec.creep_law]
    return names


def law_free_parameters(spec: ModelSpec, elastic: bool = True) -> list[str]:
    """The elastic law's (unless ``elastic`` is false), the damping's and Bouc-Wen's free
    parameters of ``spec`` (already set to its experiment's rig), as default_free_parameters
    describes them; creep is left to the caller."""
    payload = spec.rig == "payload"
    names: list[str] = []
    if not elastic:
        pass
    elif spec.hysteresis == "kawabata":
        names += ["kaw_LT", "kaw_RT", "kaw_F_ref"] + ([] if payload else ["kaw_residual"])
    elif spec.stiffness == "cubic":
        names += ["a1", "a2", "a3"]
    elif spec.stiffness == "exponential":
        names += ["exp_F", "exp_eps"]
    elif spec.stiffness == "bilinear":
        names += ["EA", "toe_EA", "toe_eps", "toe_width"]
    else:
        names += ["EA"]
    if payload:
        names += ["c0"] + (["c1", "c2"] if spec.damping in C_OF_MAGNITUDE else
                           {"coulomb": ["c_coulomb", "coulomb_v"]}.get(spec.damping, []))
    if spec.hysteresis == "boucwen":
        names += ["bw_A", "bw_beta", "bw_gamma"]
    if spec.hysteresis == "iwan":
        names += list(IWAN_K_FIT)
    return names


def fmu_defaults() -> dict:
    """name -> the FMU's start value, for every parameter of the FMU."""
    return {n: idn.parameter_start(n) for n in idn.parameter_names(kind=0)}


def fmu_bounds() -> dict:
    """name -> (min, max) of the FMU's parameters (None where unbounded)."""
    try:
        from ..fmu import model_description
        d = model_description()
        return {n: (v.min, v.max) for n, v in d.parameters.items()}
    except Exception:  # noqa: BLE001 - without the FMU: no bounds beyond the engine's
        return {}


def check_names(names: Iterable[str], spec: ModelSpec, what: str) -> list[str]:
    """``names`` as a list, each a parameter of ``spec`` or a nuisance parameter, none twice; else
    a FitError that says which name is wrong and why (``what``: what the names are, for it)."""
    known = set(idn.parameter_names(kind=0))
    out = []
    for n in names:
        if n in NZ.NUISANCE:
            if n in out:
                raise FitError(f"{what} '{n}' given twice")
            why = NZ.law_refusal(n, spec)
            if why:
                raise FitError(f"{what} '{n}': not used by the model '{spec.canonical}': {why}")
            out.append(n)
            continue
        if n in SWITCHES:
            raise FitError(f"{what} '{n}': a structural switch, chosen by the model string, not a parameter")
        if n in TRACE_PARAMETERS:
            raise FitError(f"{what} '{n}': set by each trace's metadata (L0 and g are not fitted; m, x0, v0 are "
                           "nuisance parameters, docs/nuisance.md)")
        if n not in known:
            raise FitError(f"{what} '{n}': not a parameter of the FMU; the model '{spec.canonical}' has "
                           f"{', '.join(spec.parameters)}")
        if n not in spec.parameters:
            raise FitError(f"{what} '{n}': not used by the model '{spec.canonical}'; its parameters are "
                           f"{', '.join(spec.parameters)}")
        if n in out:
            raise FitError(f"{what} '{n}' given twice")
        out.append(n)
    return out


#: physical ranges a fit keeps to beyond the FMU's own limits: a creep cell of compliance 1e40 1/N
#: and time constant 1e160 s is a limit of the law, not a tether (fits of long creep records
#: wander there when two cells trade off); a slip knee below 1e-7 strain is the law's sharp switch,
#: whose kink at an exhausted capacity stops the integrator (docs/campaign-discovery.md, session 44)
FIT_RANGES = {"creep_tau1": (1.0, 1e7), "creep_tau2": (1.0, 1e7), "creep_tau3": (1.0, 1e7),
              "creep_J1": (0.0, 1e-3), "creep_J2": (0.0, 1e-3), "creep_J3": (0.0, 1e-3),
              "slip_regen_tau": (1.0, 1e7), "slip_knee": (1e-7, 1.0),
              # a toe's corner narrower than 1e-5 strain is a kink no record resolves: a load test
              # without a toe drove toe_width to 2e-30 and every simulation crawled through it
              "toe_width": (1e-5, 0.1), "toe_eps": (1e-5, 0.5)}


#: a Coulomb friction's smoothing velocity, as a share of the payload's speed scale (its amplitude
#: times its angular frequency): a sign sharper than the low end is one no sampled swing shows, and
#: the integrator crawls through it; above the high end tanh(v / coulomb_v) is straight over the
#: whole swing, a viscous damping c_coulomb / coulomb_v, along which the two run off together
#: (docs/discovery.md, "Dry friction")
COULOMB_V_SHARE_RANGE = (1e-3, 10.0)


def bounds_and_start(name: str, start: float, limits: dict, scales: dict) -> tuple[float, float, float, str]:
    """(low, high, start, "log" | "linear") of a free parameter: the FMU's ``limits`` (fmu_bounds)
    narrowed by FIT_RANGES, the Coulomb smoothing's range and the Iwan cap, the start moved inside
    and above zero where it is log-scaled (``scales``: the estimate's '_' keys)."""
    lo, hi = limits.get(name, (None, None))
    lo = -math.inf if lo is None else float(lo)
    hi = math.inf if hi is None else float(hi)
    if name in FIT_RANGES:
        lo, hi = max(lo, FIT_RANGES[name][0]), min(hi, FIT_RANGES[name][1])
    speed = float(scales.get("_amp", 0.0)) * float(scales.get("_omega", 0.0)) if name == "coulomb_v" else 0.0
    if speed > 0 and math.isfinite(speed):
        # widened to hold the start: a fit carried on from another fit of the record starts where that
        # one ended, and the speed scale read off a record's part or a campaign's first record differs
        held = start if start > 0 and math.isfinite(start) else speed * COULOMB_V_SHARE_RANGE[0]
        lo = max(lo, min(COULOMB_V_SHARE_RANGE[0] * speed, held))
        hi = min(hi, max(COULOMB_V_SHARE_RANGE[1] * speed, held))
    if name in IWAN_K and scales.get("_iw_cap"):
        # an element the estimate left near zero has a tiny log-sensitivity: a trial step may
        # throw it far out, where the tether turns stiff and the simulation crawls (a free
        # vibration fit spent 25 s on one iteration so)
        hi = min(hi, float(scales["_iw_cap"]))
    if name in LOG_SCALED:
        lo = max(lo, 0.0)
        if not start > 0:
            start = _positive_floor(name, scales)
        return lo, hi, min(max(start, lo), hi), "log"
    s = min(max(start, lo), hi)
    return lo, hi, s, "linear"


#: the smallest viscous damping a start gives the payload, as a damping ratio
C0_FLOOR_RATIO = 0.002


def c0_floor(k: float, m: float) -> float:
    """The viscous damping of the damping ratio C0_FLOOR_RATIO, for stiffness k [N/m] and mass m [kg]."""
    return 2 * C0_FLOOR_RATIO * math.sqrt(k * m)


def _positive_floor(name: str, scales: dict) -> float:
    """A small positive start for a log-scaled parameter the estimate put at or below zero."""
    k = scales.get("_k_lin")
    m = scales.get("_m")
    if name == "c0" and k and m:
        return c0_floor(k, m)
    if name == "bw_A" and k:
        return 0.05 * k
    d = idn.parameter_start(name)
    return d if d > 0 else 1e-6

