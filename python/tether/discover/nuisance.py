"""The record's nuisance parameters in a discovery (issue 30; tether.nuisance, docs/nuisance.md,
docs/nuisance-discovery.md): which a record frees from the start model on, their data-based starts,
and their account in OUT.json and the terminal."""

from __future__ import annotations

import copy
import math
from typing import Sequence

import numpy as np

from .. import nuisance as NZ
from ..models import ModelSpec
from ..traces import Trace
from .fitting import ModelFit


#: why a discovery run without its nuisance parameters kept each of them
NOT_ASKED = "the discovery ran without nuisance parameters (--no-nuisance)"


def nuisance_parameters(trace: Trace) -> list[str]:
    """The nuisance parameters every discovery fit of ``trace`` frees, from the start model on, so
    that no effect is credited with what they explain: the offset of the measured column on every
    record; on a forced record that is not periodic the initial state x0, v0 (a record cut out of a
    longer run starts in motion), and where the record starts in motion (tether.nuisance.starts_in_motion)
    the Iwan bank's memory of that run (last_reversal_beyond, freed only in models with the bank:
    fitting.fit_model); the effective mass m within its band (the trace's
    mass_uncertainty_rel, set from --mass-band; 0 = exact, not freed), or the force gain instead
    where force_gain_known is false (m and the gain are one nuisance in two forms); on a free
    vibration x0 (its release point, read off a column that carries the offset) but not m, which a
    free vibration cannot determine (nuisance_not_freed). On the load rig not offset_input: for a
    linear law it trades one for one against offset_measured (docs/nuisance-discovery.md)."""
    names = ["offset_measured"]
    periodic = bool(trace.periodic_samples)
    if trace.rig == "payload" and not periodic:
        names += ["x0", "v0"] if trace.experiment == "forced" else ["x0"]
        if trace.experiment == "forced" and NZ.starts_in_motion(trace):
            names.append("last_reversal_beyond")
    if trace.rig == "load":
        names += list(NZ.LOAD_STATE)
    form = NZ.mass_form(trace)
    if form:
        names.append(form)
    return [n for n in names if NZ.refusal(trace, n, names) is None]


def nuisance_not_freed(trace: Trace) -> dict:
    """name -> why discovery keeps it at the record's value, for the nuisance parameters of the
    record's rig that nuisance_parameters leaves out."""
    freed = nuisance_parameters(trace)
    out = {}
    for n in (("m", "x0", "v0", "last_reversal_beyond", "input_gain") if trace.rig == "payload" else ()) + ("offset_input",):
        if n in freed or (n == "input_gain" and trace.force_gain_known) or (n == "offset_input" and trace.input is None):
            continue
        why = NZ.refusal(trace, n, freed)
        if why is None and n == "offset_input":
            why = ("for a linear law it trades one for one against offset_measured (a constant offset of the input "
                   "shifts the response by a constant), so discovery frees offset_measured only")
        if why is None and n == "input_gain":
            why = "the force gain is known (force_gain_known); the effective mass m is freed instead"
        if why is None and n == "v0":
            why = "a free vibration is released at rest"
        if why is None and n == "last_reversal_beyond":
            why = ("the record starts at rest (its initial velocity is within "
                   f"{NZ.MOTION_STANDARD_ERRORS:g} standard errors of zero): the Iwan bank starts unloaded, as the "
                   "record's first displacement leaves it" if trace.experiment == "forced" else
                   "a free vibration is released from a monotone pull, which leaves the Iwan bank as the model starts it")
        if why is not None:
            out[n] = why
    return out


def _record_nuisance(trace: Trace) -> list[str]:
    """The nuisance parameters that apply to the record: those discovery frees and those it keeps."""
    return nuisance_parameters(trace) + list(nuisance_not_freed(trace))


def nuisance_section(trace: Trace, fit: ModelFit, freed: bool = True) -> dict:
    """The report's account of the nuisance parameters of the final model: per freed parameter the
    record's value (the start), the fitted value, its 95 % interval, the change in units of the
    interval's width and whether the interval leaves the record's value out (moved); the mass band;
    what was kept at the record's value and why (``freed`` false: the discovery ran without them,
    and each is kept)."""
    start = NZ.stated_values(trace)
    params = {}
    for n, v in fit.nuisance.items():
        s = start.get(n, 0.0)
        lo, hi = fit.intervals.get(n, (math.nan, math.nan))
        width = hi - lo
        # a zero-width interval is the engine's answer where the final fit's Jacobian is rank
        # deficient (an idle Iwan element's column is zero): no interval, not a sharp one; nor is
        # one that leaves out its own value (held-out eval record 20: an Iwan model's final fit)
        known = math.isfinite(width) and width > 0 and lo <= v <= hi
        d = v - s
        params[n] = {"start": s, "value": v, "interval": [lo, hi] if known else None,
                     "change": d, "change_relative": d / s if s else None,
                     "change_interval_widths": d / width if known else None,
                     "moved": bool(not lo <= s <= hi) if known else None}
    band = NZ.mass_band_rel(trace) if trace.rig == "payload" else None
    kept = nuisance_not_freed(trace) if freed else {n: NOT_ASKED for n in _record_nuisance(trace)}
    if freed:
        kept.update({n: f"at its default: {why}" for n in nuisance_parameters(trace)
                     if (why := NZ.law_refusal(n, fit.spec)) is not None})
    return {"parameters": params, "not_freed": kept,
            "mass_band_rel": band,
            "mass_band_kg": ([float(trace.payload_mass_kg) * (1 - band), float(trace.payload_mass_kg) * (1 + band)]
                             if band is not None else None)}


def nuisance_lines(section: dict) -> list[str]:
    """The terminal's lines for nuisance_section: one per freed parameter, one for what was kept."""
    lines = []
    for n, v in section["parameters"].items():
        rel = f" ({100 * v['change_relative']:+.1f} %)" if v["change_relative"] is not None else ""
        iv = f" [{v['interval'][0]:.5g}, {v['interval'][1]:.5g}]" if v["interval"] else ""
        widths = f", {v['change_interval_widths']:+.1f} interval widths" if v["change_interval_widths"] is not None else ""
        lines.append(f"nuisance {n}: {v['start']:.5g} -> {v['value']:.5g}{iv}, change {v['change']:+.3g}{rel}{widths}"
                     + (": moved" if v["moved"] else "" if v["interval"] else " (no interval: the final fit's "
                                                                            "Jacobian is rank deficient)"))
    if section["not_freed"]:
        lines.append("kept at the record's value: " + "; ".join(f"{n} ({why})" for n, why in section["not_freed"].items()))
    return lines


def baked(trace: Trace, nz: dict) -> Trace:
    """``trace`` with its nuisance values ``nz`` made part of the record: the offset taken off the
    measured column, the input's gain and offset applied, the mass and initial state in its
    metadata. A joint fit of baked records holds each record's nuisance at its own values (the
    engine's parameters are shared by all experiments of a fit)."""
    out = copy.copy(trace)
    out.measured = np.asarray(trace.measured, float) - float(nz.get("offset_measured", 0.0))
    if trace.input is not None and ("input_gain" in nz or "offset_input" in nz):
        out.input = float(nz.get("input_gain", 1.0)) * np.asarray(trace.input, float) + float(nz.get("offset_input", 0.0))
    if "m" in nz:
        out.payload_mass_kg = float(nz["m"])
    if "x0" in nz:
        out.initial_displacement_m = float(nz["x0"])
    if "v0" in nz:
        out.initial_velocity_m_s = float(nz["v0"])
    return out


def data_start(trace: Trace, spec: ModelSpec, nz: dict) -> dict | None:
    """tether.fit's data-based estimate of ``spec`` read off the record as its nuisance values
    ``nz`` describe it (baked: the offset off the measured column, the mass in the equation of
    motion), with ``nz`` the nuisance parameters' starts; None without nuisance values (the
    estimate of the record as given). Read off the record as given, a mass 23 % off leaned on the
    stiffness and damping: a forced record's cubic with drag fitted from there stopped at 156 x noise,
    from the baked estimate at 6.6 x (the generator's own laws: 1.0 x)."""
    from ..fit import initial_estimate

    if not nz:
        return None
    est = initial_estimate([baked(trace, nz)], spec)
    return {**{k: float(v) for k, v in est.items() if not k.startswith("_")}, **{k: float(v) for k, v in nz.items()}}


#: a forced record's equation error reads its mass (and the law's start) only where the linear
#: equation explains this share of the variance of what it fits: on nonlinear, slack or coarsely
#: sampled records the mass column takes up what the law lacks (docs/nuisance-discovery.md, 2026-12-05)
MASS_ESTIMATE_MIN_R2 = 0.9


def _explained(A: np.ndarray, coef: np.ndarray, b: np.ndarray) -> float:
    """The share of the variance of ``b`` that ``A coef`` explains (R^2)."""
    r = b - A @ coef
    total = float(np.sum((b - b.mean()) ** 2))
    return 1.0 - float(r @ r) / total if total > 0 else 0.0


def nuisance_start(trace: Trace, names: Sequence[str]) -> dict:
    """Data-based starts of the nuisance parameters for the start model: the equation error of
    the payload rig, m a + c v + k x = f + k o (o the offset of the measured column), solved by
    least squares on the record's kinematics with an intercept (and, where m is freed on a forced
    record, the acceleration's column: m itself), so neither an offset nor a mass 10-30 % off the
    trace's leans on the stiffness and damping the start model begins from. Where the mass is freed
    and that equation explains less than MASS_ESTIMATE_MIN_R2 of the force, what the record states
    (NZ.stated_values): a search then also reads each candidate's data-based start off the record as
    stated, not only as the current model's nuisance values bent to its law. The load rig: the
    elongation at the smallest loads, extrapolated along them to zero load."""
    from ..fit.equation_error import scaled_lstsq
    from ..fit.kinematics import dominant_frequency, kinematics

    out = {}
    if "offset_measured" not in names:
        return out
    y = np.asarray(trace.measured, float)
    if trace.rig == "load":
        load = np.asarray(trace.input, float)
        lo = load <= np.quantile(load, 0.2)
        if lo.sum() >= 3 and np.ptp(load[lo]) > 0:
            c = np.polyfit(load[lo], y[lo], 1)
            out["offset_measured"] = float(c[1])
        return out
    t = np.asarray(trace.time, float)
    try:
        K = kinematics(trace, dominant_frequency(t, y))
    except (ValueError, np.linalg.LinAlgError, ZeroDivisionError):
        return out
    use = K.use
    f = K.f
    m = float(trace.payload_mass_kg)
    free_m = "m" in names and trace.input is not None
    cols = ([K.a[use]] if free_m else []) + [K.v[use], K.x[use], np.ones(int(use.sum()))]
    rhs = f[use] - (0.0 if free_m else m * K.a[use])
    A = np.column_stack(cols)
    coef = scaled_lstsq(A, rhs)
    k = float(coef[-2])
    if free_m and _explained(A, coef, rhs) < MASS_ESTIMATE_MIN_R2:
        stated = NZ.stated_values(trace)
        return {n: stated[n] for n in names if n in stated and n in ("offset_measured", "m", "x0", "v0")}
    if not k > 0:
        return out
    out["offset_measured"] = float(-coef[-1] / k)
    if free_m and coef[0] > 0:
        lo, hi = NZ.mass_bounds(trace)
        out["m"] = float(min(max(coef[0], lo), hi))
    c = float(coef[-3])
    out["EA"] = k * float(trace.length_m)
    if c > 0:
        out["c0"] = c
    if "x0" in names:
        out["x0"] = float(y[0]) - out["offset_measured"]
    return out
