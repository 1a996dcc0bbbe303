"""Starting points: of a model with one more effect (warm from the current fit), of a law's shape
terms, and the equation-error starts (the damping table, the Kelvin cells of a creep test)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..models import ELASTIC_FORCES, ModelSpec
from ..traces import Trace
from .scales import _Scales

if TYPE_CHECKING:   # (the registry, laws.EFFECTS, names the starts below: this module imports none of it)
    from .fitting import ModelFit


#: knots of the FMU's damping table c_table_1..6
DAMPING_TABLE_KNOTS = 6


def _shape_start(params: dict, group: Sequence[str], sc: _Scales) -> dict:
    """The final model's values, with the terms of ``group`` at a start the engine can scale: the
    damping table's knots spread evenly over the record's displacements (the last at the largest;
    a quarter of it apart left the two outer knots unvisited and the inner ones too coarse: a
    saturating damping fitted to 6.0 x noise that way, 1.9 x with the knots over the range), its
    values those of the terms it replaces (c1 |x| + c2 x^2 and the drag), so that it starts at the
    current model."""
    from .laws import _replaced
    p = dict(params)
    p.update({r: 0.0 for r in _replaced(group)})
    if any(g.startswith("c_table_") for g in group):
        dx = p["c_table_dx"] = sc.amp / DAMPING_TABLE_KNOTS
        c1, c2 = float(params.get("c1", 0.0)), float(params.get("c2", 0.0))
        # a drag c_drag |v| at amplitude x damps a cycle as a c(x) of c_drag (8 / 3 pi) omega x
        cd = float(params.get("c_drag", 0.0)) * 8.0 / (3.0 * math.pi) * sc.omega
        floor = 0.01 * abs(float(params.get("c0", 1.0))) or 1e-3
        for j in range(1, DAMPING_TABLE_KNOTS + 1):
            # the terms it replaces, at the knots: the start is the current model, nearly
            x = j * dx
            p[f"c_table_{j}"] = max(c1 * x + c2 * x * x + cd * x, floor * j)
    if "pow_F" in group:
        p.update(_power_term_start(params, sc))
    return p


#: the power term's start: its exponent, and its share of the elastic law's tension at the
#: largest strain of the record
POWER_START_N, POWER_START_SHARE = 1.5, 0.5


def _power_term_start(params: dict, sc: _Scales) -> dict:
    """The cubic law with a power term of exponent POWER_START_N carrying POWER_START_SHARE of the
    tension at the record's largest strain (its reference strain pow_eps), the cubic's
    coefficients refitted by least squares so that the law stays what it was over [0, pow_eps]
    (a power term of no tension has no slope in its exponent: the fit could not start it)."""
    from ..fit.elastic import cubic_tension

    e_ref = sc.eps + (sc.amp / sc.L0 if sc.rig == "payload" else 0.0)
    e = np.linspace(0.0, e_ref, 41)[1:]
    F = cubic_tension(params, e)
    pf = POWER_START_SHARE * float(F[-1])
    if not (e_ref > 0 and pf > 0):
        return {}
    rest = F - pf * (e / e_ref) ** POWER_START_N
    coef = np.linalg.lstsq(np.column_stack([e, e ** 2, e ** 3]), rest, rcond=None)[0]
    a1 = float(coef[0]) if coef[0] > 0 else 1e-3 * float(params.get("a1", sc.ea))
    return {"pow_F": pf, "pow_eps": float(e_ref), "pow_n": POWER_START_N, "a1": a1, "a2": float(coef[1]),
            "a3": float(coef[2])}


def _damping_table_start(trace: Trace, spec: ModelSpec, params: dict, dx: float) -> dict | None:
    """The damping table (knots ``dx`` apart) and c0 from the equation error of the payload rig,
    linear in them: T - m g = f - m x'' = restoring(x) + z + (c0 + table(|x|)) x', with x,
    x', x'' smoothed from the record, the restoring force a polynomial fitted alongside and z the
    current Bouc-Wen force along the measured path; the table through the hat functions of the
    linear interpolant, near enough the FMU's cubic one for a start. A start of the right shape for
    a damping the polynomial c0 + c1|x| + c2 x^2 does not follow (from a flat start, a saturating
    c(x) of a free vibration fitted to 1.9 x noise in one run and to 4.9 x in another; from this
    one the table lands within 4 % of the generator's c(x) at every knot). None where the record
    is not a payload record."""
    from .. import identify_native as idn
    from ..fit.equation_error import damping_magnitude, restoring_columns, scaled_lstsq, taut_for_sure
    from ..fit.kinematics import dominant_frequency, kinematics

    if trace.rig != "payload" or not dx > 0:
        return None
    K = kinematics(trace, dominant_frequency(np.asarray(trace.time, float), np.asarray(trace.measured, float)))
    m, g = float(trace.payload_mass_kg), float(trace.gravity_m_s2)
    keep = K.use.copy()
    k = float(params.get("EA", params.get("a1", 0.0))) / float(trace.length_m)
    if spec.slack and g > 0 and k > 0:
        keep &= taut_for_sure(K.x, m, g, k)
    rhs = K.f - m * K.a
    if spec.hysteresis == "boucwen" and all(n in params for n in ("bw_A", "bw_beta", "bw_gamma")):
        rhs = rhs - idn.bouc_wen_path(K.x, float(params["bw_A"]), float(params["bw_beta"]), float(params["bw_gamma"]),
                                      K.periodic)
    swing_rate = math.sqrt(k / m) if spec.damping == "amplitude" and k > 0 else 0.0
    s = damping_magnitude(K.x, K.v, swing_rate) / dx
    hats = [np.clip(1.0 - np.abs(s - j), 0.0, None) for j in range(1, DAMPING_TABLE_KNOTS)]
    hats.append(np.clip(s - (DAMPING_TABLE_KNOTS - 1), 0.0, 1.0))      # the last knot: held beyond
    cols = [K.v] + [h * K.v for h in hats] + restoring_columns(K.x, spec.stiffness == "cubic")
    A = np.column_stack(cols)[keep]
    if A.shape[0] <= 2 * A.shape[1]:
        return None
    coef = scaled_lstsq(A, rhs[keep])
    if not np.all(np.isfinite(coef)):
        return None
    p = {"c0": float(coef[0]) if coef[0] > 0 else float(params.get("c0", 0.0)), "c_table_dx": dx}
    p.update({f"c_table_{j}": float(coef[j]) for j in range(1, DAMPING_TABLE_KNOTS + 1)})
    return p


#: how many retardation times the Kelvin-cell start of a creep test chooses among
RETARDATION_GRID = 13


def retardation_grid(t: np.ndarray, hold: float) -> np.ndarray:
    """The retardation times the creep start chooses among: log-spaced from the sample interval
    (at least 1 s) to ten times the longest hold."""
    dt = float(np.median(np.diff(t)))
    return np.geomspace(max(dt, 1.0), 10.0 * hold, RETARDATION_GRID)


def _retardation_times_start(trace: Trace, spec: ModelSpec, params: dict, sc: _Scales) -> dict | None:
    """The three Kelvin cells of a creep test from the equation error, linear in their compliances
    once their retardation times are chosen: eps - eps_elastic(T) = c T + sum_k J_k kelvin(T, tau_k)
    + S slip(T), by non-negative least squares (c of either sign) for every three times of a
    log-spaced grid, the best three kept. A creep law other than Kelvin cells (a power law of time,
    fast right after every step) sends fits from fixed times to different local minima, some far
    from the best (a Findley record: 1.83 x noise from the fixed starts, 1.19 x from this one).
    None where the record is not a creep test."""
    from itertools import combinations

    from ..fit.creep_start import kelvin_response, slip_response
    from ..fit.elastic import elastic_inverse
    from ..fit.equation_error import scaled_nnls

    if trace.experiment != "creep" or not sc.hold > 0:
        return None
    t = np.asarray(trace.time, float)
    T = np.asarray(trace.input, float)
    if not T.max() > 0:
        return None
    eps = np.asarray(trace.measured, float) / float(trace.length_m)
    ea = float(params.get("EA", sc.ea))
    elastic = elastic_inverse(spec.stiffness, {**params, "EA": ea})(T)
    slip_tau = float(params.get("slip_regen_tau", 3600.0))
    grid = retardation_grid(t, sc.hold)
    kelvin = [kelvin_response(t, T, tau) for tau in grid]
    fixed = [T, -T, slip_response(t, T, slip_tau)]
    b = eps - elastic
    best = None
    for idx in combinations(range(len(grid)), 3):
        coef, res = scaled_nnls(np.column_stack(fixed + [kelvin[i] for i in idx]), b)
        if best is None or res < best[0]:
            best = (res, idx, coef)
    _, idx, coef = best
    J = coef[3:]
    if not np.all(np.isfinite(coef)) or not J.max() > 0:
        return None
    out = {f"creep_tau{k + 1}": float(grid[i]) for k, i in enumerate(idx)}
    out.update({f"creep_J{k + 1}": float(max(j, 1e-3 * J.max())) for k, j in enumerate(J)})
    slip = max(float(coef[2]), 1e-9)
    out.update(slip_capacity0=slip, slip_rate=slip / slip_tau)
    c = float(coef[0] - coef[1])
    if spec.stiffness == "linear" and 1.0 / ea + c > 0:
        out["EA"] = 1.0 / (1.0 / ea + c)
    return out


def _boucwen_start(sc: _Scales, share: float, z_share: float) -> dict:
    """Bouc-Wen: initial stiffness ``share`` of k, saturation force ``z_share`` of the force scale."""
    A = share * sc.k
    zs = max(z_share * sc.force, 1e-9)
    return {"bw_A": A, "bw_beta": A / (2 * zs), "bw_gamma": A / (2 * zs)}


def _scale_elastic(p: dict, factor: float) -> dict:
    q = dict(p)
    for n in ELASTIC_FORCES:
        if n in q:
            q[n] = q[n] * factor
    return q


#: a weak hysteretic force put beside the base model (Bouc-Wen's, the Iwan bank's): this share of
#: the record's stiffness, the base's elastic law scaled by WEAK_ELASTIC to make room for it
WEAK_SHARE = 0.03
WEAK_ELASTIC = 0.97


def _beside(base: ModelFit) -> dict:
    """The base model's values with its elastic law scaled by WEAK_ELASTIC: the start a weak force
    is added to."""
    return _scale_elastic(dict(base.params), WEAK_ELASTIC)


def candidate_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None = None) -> list[dict | None]:
    """Starting points for ``new`` (``base`` plus one effect): the starts of the law it adds, in the
    registry (laws.EFFECTS: a law's ``starts``, or its ``starts_from`` the law the model had; the
    base fit's values where it adds none). Each is warm from the base fit, with the new terms at a
    few data-scaled values; None adds tether.fit's own data-based estimate; with the ``trace``,
    equation-error starts where there is one (the Kelvin cells of a creep test).
    Where ``base`` already has effects, the data-based estimate of the whole new model is always
    among the starts: the base fit's terms have taken up what the new effect explains (an Iwan
    bank fitted alone dissipates what a damping does), and warm starts keep them there."""
    from .laws import added_law
    added = added_law(base.spec, new)
    if added is None:
        starts = [dict(base.params)]
    else:
        law, was = added
        starts = dict(law.starts_from).get(was, law.starts)(base, new, sc, trace)
    if base.effects and None not in starts:
        starts.append(None)
    return starts


def estimate_start(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """tether.fit's data-based estimate alone: Kawabata's energies, the exponential law's fit of the
    load-elongation curve, the Iwan bank's element stiffnesses on a grid of slip strains by
    non-negative least squares along the measured path."""
    return [None]


def boucwen_from_kawabata_starts(base: ModelFit, new: ModelSpec, sc: _Scales,
                                 trace: Trace | None) -> list[dict | None]:
    """An elastic law under a Bouc-Wen force in place of Kawabata's branches: the data-based
    estimate, and the law near a linear one of the record's stiffness under a force of a tenth of it."""
    from ..fit.elastic import near_linear_law

    w = near_linear_law(new.stiffness, sc.ea, sc.eps)
    w.update(_boucwen_start(sc, 0.1, 0.3))
    return [None, w]


def iwan_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """As Bouc-Wen's: first a weak bank next to the base model (a thirtieth of the stiffness, its
    slip strains up to the record's strain amplitude), from which the fit can only go down from
    the base model's error; then tether.fit's equation-error estimate, which misreads a record that
    goes slack while the model cannot (45 times the base model's error on a tuning record)."""
    from ..fit.iwan_bank import iwan_params, iwan_slip_grid
    from ..models import IWAN_FIT_ELEMENTS

    w = _beside(base)
    w.update(iwan_params(iwan_slip_grid(sc.amp / sc.L0),
                         np.full(IWAN_FIT_ELEMENTS, WEAK_SHARE * sc.ea / IWAN_FIT_ELEMENTS)))
    return [w, None]


def cubic_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """The cubic law at the base's linear stiffness; and the data-based estimate where no hysteresis
    is named."""
    w = dict(base.params)
    w.update(a1=w.get("EA", sc.ea), a2=0.0, a3=0.0)
    return [w] + ([None] if new.hysteresis == "none" else [])


def bilinear_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """The data-based estimate (the corner on a grid, the slopes by least squares along the
    restoring force or the load curve); and the base's stiffness with a short soft toe (half the
    stiffness up to a tenth of the record's strain), near the linear law."""
    from ..fit.elastic import near_linear_law

    w = dict(base.params)
    w.update(near_linear_law("bilinear", w.get("EA", sc.ea), sc.eps))
    return [None, w]


def _viscous_reference(base: ModelFit, sc: _Scales) -> float:
    """The base's c0, at least the fit's floor (fit.parameters.c0_floor): where a hysteresis law has
    taken over the damping, c0 falls towards zero, and starts scaled by it would give the damping
    nothing the fit can grow from (its terms are scaled by their starts; docs/discovery.md)."""
    from ..fit.parameters import c0_floor
    c0 = float(base.params.get("c0", 1.0))
    if sc.omega > 0:
        c0 = max(c0, c0_floor(sc.k, sc.k / sc.omega ** 2))
    return c0


def damping_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """c(x) growing with |x| or x^2, or a drag c_drag |v| growing with the speed amp * omega: four
    starts from the base's c0 (_viscous_reference), one with each leading, one with all small."""
    warm = base.params
    c0 = _viscous_reference(base, sc)
    speed = sc.amp * (sc.omega if sc.omega > 0 else 1.0)
    starts: list[dict | None] = []
    for r1, r2, rd in ((1e-2, 1e-3, 1e-2), (1.0, 1e-3, 1e-2), (1e-3, 1.0, 1e-2), (1e-3, 1e-3, 1.0)):
        w = dict(warm)
        w.update(c0=c0 * (1.0 - 0.3 * max(r1, r2, rd)), c1=r1 * c0 / sc.amp, c2=r2 * c0 / sc.amp ** 2)
        if "c_drag" in new.parameters:
            w["c_drag"] = rd * c0 / speed
        starts.append(w)
    return starts


#: the shares of the base model's viscous damping that the Coulomb starts hand to dry friction
COULOMB_SHARES = (0.1, 0.5)


def coulomb_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """Viscous plus dry friction from the base's c0 (_viscous_reference), a share (COULOMB_SHARES)
    of it handed to the friction (fit.payload_start.coulomb_start), at the record's amplitude and
    sample interval."""
    from ..fit.payload_start import coulomb_start
    c0 = _viscous_reference(base, sc)
    t = trace.time if trace is not None else ()
    omega = sc.omega if sc.omega > 0 else 1.0
    return [{**base.params, **coulomb_start(c0, omega, sc.amp, t, share)} for share in COULOMB_SHARES]


def boucwen_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """First a start next to the base model (a weak, barely saturating force): the fit can only go
    down from the base model's error (starts far from it, e.g. a strong force that saturates early,
    send lightly damped fits of a forced record into slow, useless regions); then tether.fit's
    equation-error estimate."""
    w = _beside(base)
    w.update(_boucwen_start(sc, WEAK_SHARE, 0.5))
    return [w, None]


def creep_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """The default Kelvin cells and slip at full and at 1 % size; retardation times a decade apart up
    to the longest hold (a creep law other than Kelvin cells, a power law of time, fast right after
    each step, is followed over the decades the record samples; the fixed times start too slow for
    it); the data-based estimate; the retardation times of the equation error (with the trace)."""
    warm = base.params
    starts: list[dict | None] = []
    for f in (1.0, 0.01):
        w = dict(warm)
        w.update(creep_J1=1e-6 * f, creep_J2=2.5e-6 * f, creep_J3=1.5e-6 * f, slip_capacity0=4e-4 * f,
                 slip_rate=1.5e-7, creep_tau1=1800.0, creep_tau2=5400.0, creep_tau3=172800.0,
                 slip_knee=4e-5, slip_regen_tau=3600.0, slip_limit=1.0667e-3, slip_load_half=40.0)
        starts.append(w)
    if sc.hold > 0:
        w = dict(starts[0])
        w.update(zip(("creep_tau1", "creep_tau2", "creep_tau3"),
                     (min(max(f * sc.hold, 1.0), 1e7) for f in (0.01, 0.1, 1.0))))
        starts.append(w)
    starts.append(None)
    if trace is not None:
        ee = _retardation_times_start(trace, base.spec, dict(warm), sc)
        if ee is not None:
            w = dict(starts[0])
            w.update(ee)
            starts.append(w)
    return starts


def slack_starts(base: ModelFit, new: ModelSpec, sc: _Scales, trace: Trace | None) -> list[dict | None]:
    """The base's values; where its stiffness is linear, also with EA from the record; and the
    data-based estimate of the whole model (a law and nuisance values fitted to a record that goes
    slack, by a model that cannot, are bent to stand in for it)."""
    starts: list[dict | None] = [dict(base.params)]
    if base.spec.stiffness == "linear":
        w = dict(base.params)
        w.update(EA=sc.ea)
        starts.append(w)
    return starts + [None]


def _damping_table_starts(trace: Trace, fm: "ModelFit", sc: _Scales) -> list:
    """Starts of the damping table from a polynomial damping fit: the table at the polynomial's
    values, and the table of the equation error (_damping_table_start)."""
    from .laws import DAMPING_TABLE
    flat = _shape_start(fm.params, DAMPING_TABLE, sc)
    ee = _damping_table_start(trace, fm.spec, fm.params, flat["c_table_dx"])
    return [flat] if ee is None else [flat, {**flat, **ee}]


def _reduced_starts(cur: ModelFit, reduced: ModelSpec, sc: _Scales) -> list:
    """Starts for ``cur`` without one of its effects: its own values (terms of the removed effect
    dropped), and tether.fit's data-based estimate."""
    p = {k: v for k, v in cur.params.items() if k in reduced.parameters}
    if cur.spec.stiffness != "linear" and reduced.stiffness == "linear":
        p["EA"] = sc.ea
    return [p, None]


def kept_shape(cur: ModelFit, reduced: ModelSpec) -> dict:
    """The fit's ``extra`` and ``held`` for ``reduced``, ``cur`` without one of its effects: the shape
    terms ``cur`` frees beyond its laws (a kept refinement's: the table of c(x)) that ``reduced``
    still has, free, and the terms they replace, held. Refitted without the effect, the other laws
    keep their shapes, or an effect that made up for a law's old shape is judged against that shape
    (docs/discovery.md, "The re-test's model keeps the other laws' shapes")."""
    from .laws import _replaced
    shape = tuple(k for k in cur.shape if k in reduced.parameters)
    return {"extra": shape, "held": _replaced(shape)}
