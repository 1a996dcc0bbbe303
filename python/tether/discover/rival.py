"""The rival laws of an effect (hysteresis: Bouc-Wen or the Iwan bank), the wider laws of the
elastic law and creep, and the Iwan bank's last stages (its idle elements restarted, a finer bank)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from ..models import ELASTIC_PARAMETERS, HYSTERESIS_PARAMETERS, IWAN_EPS, IWAN_K, IWAN_K_FIT
from .. import nuisance as NZ
from ..traces import Trace
from .fitting import _heldout, ModelFit
from .judge import (CRITERIA, _law_judged, _shape_heldout_asked, _shape_judged, bic_change, leaves_unexplained,
                    optimum_judged)
from .laws import _law_of, _with_law, EFFECT, RIVAL_LAWS, SHAPE_TERMS, WIDER_LAWS
from .records import Refinement
from .refine import shape_starts
from .scales import _Scales


#: the work cap of the rival law's fits, as a multiple of the search's, where the elastic law's
#: power term was kept (the load rig with Iwan elements and a power term simulates 6 x slower than
#: with the cubic alone: 0.098 s against 0.017 s on 2478 samples)
RESHAPED_RIVAL_CAP_FACTOR = 4.0
#: and where the rival is fitted with its shape terms free (the Iwan bank's eight slip strains
#: beside its eight stiffnesses: as the bank's own last stages get, IWAN_STAGE_CAP_FACTOR)
SHAPED_RIVAL_CAP_FACTOR = 3.0


#: the least work cap of the Iwan bank's last stages (restart, finer bank), as a multiple of the
#: search's
IWAN_STAGE_CAP_FACTOR = 3.0


def _law_converted(params: dict, law: str, rival: dict, L0: float) -> dict:
    """The rival law's terms matched to the fitted law's initial stiffness and largest hysteretic
    force: the Iwan bank's are sum k_i / L0 [N/m] and sum k_i eps_i [N], a classic Bouc-Wen force's
    A and A / (beta + gamma); a bank keeps the rival fit's slip strains and shares, scaled."""
    k = np.array([float(params.get(n, 0.0)) for n in IWAN_K])
    if law == "iwan":
        e = np.array([float(params.get(n, 0.0)) for n in IWAN_EPS])
        A, zs = float(k.sum()) / L0, float(k @ e)
        if not (A > 0 and zs > 0):
            return {}
        return {"bw_A": A, "bw_beta": A / (2 * zs), "bw_gamma": A / (2 * zs)}
    A = float(params.get("bw_A", 0.0))
    kr = np.array([float(rival.get(n, 0.0)) for n in IWAN_K])
    if not (A > 0 and kr.sum() > 0):
        return {}
    return {n: float(v) for n, v in zip(IWAN_K, kr * (A * L0 / kr.sum()))}


def _estimated(trace: Trace, spec, fixed: dict | None = None) -> dict:
    """tether.fit's data-based estimate of ``spec``'s parameters on ``trace`` (``fixed`` held), its
    private entries ('_'...) left out: a start of a rival or wider law, or a rival law's terms where
    its fit in the step that named the effect failed."""
    from ..fit import initial_estimate

    return {k: v for k, v in initial_estimate([trace], spec, fixed=fixed).items() if not k.startswith("_")}


def rival_law(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
              rivals: dict, added: Sequence[str], say: Callable[[str], None], elastic_reshaped: bool = False,
              incumbent_shaped: bool = False, reseed: Callable | None = None, sc=None):
    """An effect's law is chosen in the step that names the effect, beside the effects named so far;
    an effect named after it can change which law fits best (the generator's Iwan hysteresis with
    slack: Bouc-Wen won the hysteresis step, 10.4 x noise in the end, where the Iwan bank with slack
    gets 4.8). Where the final model still misses the record and an effect was named after the
    hysteresis, the hysteresis law is fitted again with its rival in its place, from the rival's
    own fit of the hysteresis step and the final model's other terms; so too where the hysteresis
    was named last but the model still leaves something unexplained (CRITERIA.unexplained_gap): the
    step chose its law from short fits, before the shapes and the nuisance were refitted beside it,
    and a search stops only once every law's other form was tried. The rival is kept when it
    lowers the BIC and does not worsen the held-out prediction (asked where that prediction can
    judge, CRITERIA.shape_heldout_informative, as for the shape terms). Starts: the rival's own fit, with the
    final model's elastic law or its own; the rival matched to the fitted law's stiffness and force;
    tether.fit's data-based estimate of the whole model. ``rivals``: the rival fits' parameters
    of the hysteresis step, by law; where the rival's fit failed there, its terms come from
    tether.fit's data-based estimate instead (a failed short fit is no verdict on a law). ``elastic_reshaped``: the elastic law's shape was refined after
    the hysteresis step (its power term kept): the rival is fitted then too, whatever was named
    last, for the law was chosen beside a cubic that the power term has replaced (the generator's
    power-law tether with Iwan friction: Bouc-Wen won beside the cubic, 2.86 against 2.87 x noise,
    and stopped at 1.73 x with the power term beside it). ``incumbent_shaped``: the law in place
    has its shape terms free; the rival is then fitted with its own widest shape group free, like
    against like (the generator's Iwan friction with slack: Bouc-Wen with its shape at 2.07 x noise
    kept its place against the bank on its grid, 3.80 x). ``reseed(model, held) -> (model, held)``:
    the rival law's reseeding moves, run on the rival's fit where it lowers the BIC and the error
    but predicts the held-out part worse, before the verdict (the law in place had its own stages).
    ``sc``: the scales of ``trace`` where the caller has them (the search's). Returns the model, its
    held-out error and a Refinement or None."""

    effect = "hysteresis"
    law = cur.spec.hysteresis
    laws = RIVAL_LAWS[effect]
    named_last = list(added)[-1:] == [effect]
    still_missing = leaves_unexplained(cur.rms, sigma)
    if (cur.rms <= CRITERIA.within_noise * sigma or law not in laws or effect not in added
            or (named_last and not elastic_reshaped and not still_missing)):
        return cur, cur_held, None
    other = next(x for x in laws if x != law)
    new = replace(cur.spec, hysteresis=other).for_experiment(trace.experiment)
    rival = rivals.get(other) or _estimated(trace, new)
    mine = {**_fitted_nuisance(cur),
            **{k: v for k, v in cur.params.items() if k in new.parameters and k not in HYSTERESIS_PARAMETERS[law]}}
    theirs = {k: v for k, v in rival.items() if k in HYSTERESIS_PARAMETERS[other]}
    their_elastic = {k: v for k, v in rival.items() if k in ELASTIC_PARAMETERS and k in new.parameters}
    starts = [*_own_starts(trace, cur, new, other, mine, sc),
              {**mine, **theirs},
              {**mine, **theirs, **their_elastic},
              {**mine, **theirs, **_law_converted(cur.params, law, theirs, float(trace.length_m))},
              None]
    if elastic_reshaped:
        # tether.fit's estimate beside the power term kept: the rival's terms and the cubic's
        # from the data, the power term's exponent and reference strain held (docs/discovery.md)
        power = {k: float(cur.params[k]) for k in ("pow_F", "pow_eps", "pow_n") if k in cur.params}
        starts.insert(3, _estimated(trace, new, power))
    # (a power term's law simulates several times slower than the cubic's: its fits get the time)
    factor = RESHAPED_RIVAL_CAP_FACTOR if elastic_reshaped else 1.0
    shapes = max(SHAPE_TERMS.get((effect, other), ((),)), key=len) if incumbent_shaped else ()
    if shapes:
        factor *= SHAPED_RIVAL_CAP_FACTOR
    return _law_swapped(trace, part, held_out, cur, cur_held, sigma, fit, new, effect, law, starts,
                        lambda k: k in HYSTERESIS_PARAMETERS[other], say, reseed=reseed, cap_factor=factor,
                        **({"extra": tuple(shapes)} if shapes else {}))


def other_rival_laws(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
                     rivals: dict, say: Callable[[str], None], sc=None):
    """Every effect's law is chosen in the step that names it, beside the effects named so far and
    before the shapes and nuisance are refitted beside it; the hysteresis's rival has a stage of its
    own (rival_law). Where the final model still misses the record, each other named effect whose
    law names a rival (Law.rival: the cubic and bilinear elastic laws, c(x) and dry friction) is
    fitted again with the rival in its place, kept as a rival law is (_law_judged: a lower BIC and
    error, the held-out prediction no worse). Its wider law has the wider-laws stage. Starts
    (_rival_starts): the rival's own fit of the step that named the effect beside the final model's
    other terms, the registry's starts of the rival beside the final model without the effect, and
    for an elastic law the rival that follows the law in place over the strains the record visits.
    ``rivals``: the step fits' parameters, by effect and law. Returns the model, its held-out error
    and a list of Refinements."""
    from .laws import EFFECT
    refinements = []
    for effect in RIVAL_LAWS:
        law = _law_of(cur.spec, effect)
        entry = EFFECT[effect].law(law)
        if (effect == "hysteresis" or effect not in cur.effects or entry is None or entry.rival is None
                or cur.rms <= CRITERIA.within_noise * sigma):
            continue
        rule = EFFECT[effect].law(entry.rival)
        if rule is None or not rule.tried_on(trace.rig):
            continue
        new = _with_law(cur.spec, effect, entry.rival).for_experiment(trace.experiment)
        own = _law_terms(effect, entry.rival)
        starts = _rival_starts(trace, cur, new, effect, rivals.get(effect, {}).get(entry.rival, {}), sc)
        cur, cur_held, r = _law_swapped(trace, part, held_out, cur, cur_held, sigma, fit, new, effect, law, starts,
                                        lambda k, own=own: k in own, say)
        refinements.append(r)
    return cur, cur_held, refinements


def _law_terms(effect: str, law: str) -> tuple:
    """The terms of ``law`` of ``effect`` (the elastic, damping, hysteresis or creep laws'); none for
    an effect without a law (slack, a switch)."""
    from ..models import CREEP_PARAMETERS, DAMPING_PARAMETERS, STIFFNESS_PARAMETERS
    table = {"nonlinear_stiffness": STIFFNESS_PARAMETERS, "nonlinear_damping": DAMPING_PARAMETERS,
             "hysteresis": HYSTERESIS_PARAMETERS, "creep": CREEP_PARAMETERS}.get(effect, {})
    return tuple(table.get(law, ()))


def _rival_starts(trace: Trace, cur: ModelFit, new, effect: str, step_fit: dict, sc=None) -> list:
    """Starts of ``new`` (``cur`` with the rival law of ``effect`` in place): the final model's other
    terms and fitted nuisance beside the rival's terms of its step fit (``step_fit``, where there is
    one), beside the rival matched to the elastic law in place (_elastic_matched), and the registry's
    starts of the rival beside the final model without the effect (None: tether.fit's estimate)."""
    from .laws import EFFECT, _without
    from .scales import _scales
    law, other = _law_of(cur.spec, effect), _law_of(new, effect)
    mine = {**{k: float(v) for k, v in cur.params.items() if k in new.parameters and k not in _law_terms(effect, law)},
            **_fitted_nuisance(cur)}
    starts = [{**mine, **theirs} for theirs in (
        {k: v for k, v in step_fit.items() if k in _law_terms(effect, other)},
        _elastic_matched(trace, cur, other) if effect == "nonlinear_stiffness" else {}) if theirs]
    reduced = _without(cur.spec, effect)
    params = {k: float(v) for k, v in cur.params.items() if k in reduced.parameters}
    if effect == "nonlinear_stiffness":
        params["EA"] = _secant_stiffness(trace, cur)
    base = replace(cur, spec=reduced, params=params)
    for s in EFFECT[effect].law(other).starts(base, new, sc if sc is not None else _scales(trace), trace):
        starts.append(s if s is None else {**s, **_fitted_nuisance(cur)})
    return starts


def _visited_strains(trace: Trace, cur: ModelFit, count: int = 200) -> np.ndarray:
    """``count`` strains spread over those the record visits under ``cur``: the load rig's measured
    elongation over L0; the payload's balance strain (the law's strain at the weight of the fitted
    mass and half the line) plus the measured displacement over L0 (its fitted offset taken off)."""
    from ..fit.elastic import elastic_inverse
    L0 = float(trace.length_m)
    x = np.asarray(trace.measured, float) - float(cur.params.get("offset_measured", 0.0))
    base = 0.0
    if trace.rig == "payload":
        weight = (float(cur.params.get("m", trace.payload_mass_kg)) + 0.5 * float(trace.line_density_kg_m) * L0) \
            * float(trace.gravity_m_s2)
        base = float(elastic_inverse(cur.spec.stiffness, cur.params)(weight))
    return base + np.linspace(float(np.min(x)), float(np.max(x)), count) / L0


def _secant_stiffness(trace: Trace, cur: ModelFit) -> float:
    """The linear law's EA that joins the ends of ``cur``'s elastic law over the strains the record
    visits (the law in place, seen as the linear law a step adds its rival to)."""
    from ..fit.elastic import elastic_tension
    eps = _visited_strains(trace, cur, 2)
    T = elastic_tension(cur.spec.stiffness, cur.params, eps)
    return float((T[1] - T[0]) / (eps[1] - eps[0])) if eps[1] > eps[0] else float(cur.params.get("EA", 0.0))


def _elastic_matched(trace: Trace, cur: ModelFit, law: str) -> dict:
    """The elastic law ``law`` fitted by least squares to the tension of ``cur``'s elastic law over
    the strains the record visits (_visited_strains); {} where it cannot follow it."""
    from ..fit.elastic import elastic_from_curve, elastic_tension
    eps = _visited_strains(trace, cur)
    return elastic_from_curve(law, eps, elastic_tension(cur.spec.stiffness, cur.params, eps)) or {}


def _fitted_nuisance(cur: ModelFit) -> dict:
    """The nuisance values ``cur`` fitted (the mass, the initial state, the offsets): a law put in
    another's place starts from them, not from the record's stated values."""
    return {k: float(v) for k, v in cur.params.items() if k in NZ.NUISANCE}


def _own_starts(trace: Trace, cur: ModelFit, new, law: str, mine: dict, sc=None) -> list[dict]:
    """The registry's starts of ``law`` put into the final model without its hysteresis (``mine``:
    its other terms): a weak force beside that model, from which the fit can only go down (the
    hysteresis step's fit of the rival, without the effects named after it, can start far off:
    the Iwan bank fitted before slack, 26.9 x noise at the end where Bouc-Wen stood at 2.5 x)."""
    from .laws import EFFECT
    from .scales import _scales

    entry = EFFECT["hysteresis"].law(law)
    if entry is None:
        return []
    base = replace(cur, spec=replace(cur.spec, hysteresis="none"), params=dict(mine))
    return [s for s in entry.starts(base, new, sc if sc is not None else _scales(trace), trace) if s is not None]


def _law_swapped(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
                 new, effect: str, law: str, starts: list, reported: Callable[[str], bool],
                 say: Callable[[str], None], reseed: Callable | None = None, **fit_options):
    """``new`` (``cur`` with another law of ``effect`` in ``law``'s place) fitted from ``starts`` and
    judged as a rival law is (_law_judged: a lower BIC, the held-out prediction no worse; the
    held-out fit asked only where the whole record's error falls). Returns the model (``new``'s fit
    where kept, else ``cur``), its held-out error and the Refinement, whose terms are the fit's free
    terms ``reported`` selects. ``fit_options`` go to both fits."""
    other = _law_of(new, effect)
    fm = fit(trace, new, cur.effects, starts, baseline_rms=cur.rms, **fit_options)
    held, bic, terms = float("nan"), float("inf"), ()
    if not fm.ok:
        ok, verdict = False, f"the fit failed: {fm.message}"
    else:
        bic = bic_change(cur, fm, len(trace.time))
        if bic < 0.0 and fm.rms < cur.rms:
            pf = fit(part, new, cur.effects, [fm.params], **fit_options)
            held = _heldout(trace, new, pf.params, held_out) if pf.ok else float("inf")
        ok, verdict = _law_judged(cur.rms, fm.rms, bic, cur_held, held, sigma, law)
        if not ok and reseed is not None and bic < 0.0 and fm.rms < cur.rms:
            fm, held, bic, ok, verdict = _reseeded_rival(cur, cur_held, fm, held, bic, verdict, sigma, law,
                                                         len(trace.time), reseed, say)
        terms = tuple(k for k in fm.free if reported(k))
    r = Refinement(effect, terms, cur.rms, fm.rms if fm.ok else float("inf"), cur_held, held, bic, ok, verdict,
                   {k: float(fm.params[k]) for k in terms}, law=f"{law} -> {other}")
    say(f"  law of {effect}, {law} -> {other}: {'kept' if ok else 'not kept'}: {verdict}")
    return (fm, held, r) if ok else (cur, cur_held, r)


def _reseeded_rival(cur: ModelFit, cur_held: float, fm: ModelFit, held: float, bic: float, verdict: str,
                    sigma: float, law: str, n: int, reseed: Callable, say: Callable[[str], None]):
    """The rival's fit ``fm`` (better on the whole record, worse on the held-out part) after its
    law's reseeding moves, judged again against ``cur``; (model, held, bic, ok, verdict), the
    rival's own where the moves change nothing."""
    say(f"  law of hysteresis, {law} -> {_law_of(fm.spec, 'hysteresis')}: {verdict}; its reseeding moves first")
    fm2, held2 = reseed(fm, held)
    if fm2 is fm:
        return fm, held, bic, False, verdict
    bic2 = bic_change(cur, fm2, n)
    ok2, verdict2 = _law_judged(cur.rms, fm2.rms, bic2, cur_held, held2, sigma, law)
    return fm2, held2, bic2, ok2, verdict2 + " (after its reseeding moves)"


#: an Iwan element carrying less than this share of the bank's stiffness is idle: its stiffness is
#: fitted on a log scale, and once a fit has pushed it towards zero no step brings it back
IWAN_IDLE_SHARE = 0.02


#: the share of the bank an idle element restarts with
IWAN_RESTART_SHARE = 0.05


def _slip_of(k_name: str) -> str:
    """The slip strain's name of an Iwan element named by its stiffness (iw_k3 -> iw_eps3)."""
    return IWAN_EPS[IWAN_K.index(k_name)]


def _gap_midpoints(live: Sequence[float], count: int) -> list[float]:
    """``count`` slip strains, each at the middle of the widest gap left between 0 and the ``live``
    ones, one after the other (a gap split by one is two gaps for the next); in increasing order."""
    points, new = [0.0] + sorted(float(e) for e in live), []
    for _ in range(count):
        cuts = sorted(points + new)
        j = int(np.argmax(np.diff(cuts)))
        new.append(0.5 * (cuts[j] + cuts[j + 1]))
    return sorted(new)


def idle_slip_strains_moved(eps: np.ndarray, idle: np.ndarray, names: Sequence[str] = IWAN_EPS) -> dict:
    """Slip strains for the idle elements of an Iwan bank (``idle`` a mask over ``eps``), at the
    middles of the widest gaps between 0 and the live elements' slip strains (_gap_midpoints).
    Where the fit left an element idle its slip strain did not help there: on the estimate's
    geometric grid the three lowest elements of a forced record with slack sat at 1.3e-4..4.2e-4
    while the live ones spread over 9e-4..8e-3, and restarted where they were they went idle again
    (4.22 -> 6.85 x noise, refused); moved into the gaps the bank reached 1.07 x. ``names``: the
    slip strains' names, in the order of ``eps``; returns {name: new slip strain} for the idle
    ones, in order of strain."""
    new = _gap_midpoints([e for e, i in zip(eps, idle) if not i], int(np.sum(idle)))
    return dict(zip([n for n, i in zip(names, idle) if i], new))


def restart_idle_elements(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float,
                          fit, say: Callable[[str], None]):
    """The Iwan bank's element stiffnesses start from a non-negative least-squares estimate, which
    is sparse, and are fitted on a log scale: an element the estimate or a fit left near zero has
    no sensitivity left and stays there, and the bank ends with two or three elements, a
    polygonal hysteresis loop, where the tether's is smooth (the generator's 12-element bank with
    a damping of the gaussian law ended at 7.47 x noise with three live elements of eight). Where
    the final model still misses the record, the idle elements (below IWAN_IDLE_SHARE of the bank)
    restart at IWAN_RESTART_SHARE each, the bank's total stiffness kept, and the model is fitted
    again, from two starts: the idle elements where the fit left them, and moved into the widest
    gaps between the live ones' slip strains (idle_slip_strains_moved); the better after a few
    iterations is carried on. The same model with the same free terms, kept when its error on the
    whole record is lower. The held-out error of a fit to the first part is recorded beside it.
    Returns the model, its held-out error and a Refinement or None."""
    if cur.spec.hysteresis != "iwan" or cur.rms <= CRITERIA.within_noise * sigma:
        return cur, cur_held, None
    names = [n for n in IWAN_K if n in cur.free]           # the bank's elements (the others absent)
    k = np.array([float(cur.params.get(n, 0.0)) for n in names])
    total = float(k.sum())
    idle = [n for n, v in zip(names, k) if v < IWAN_IDLE_SHARE * total]
    if not total > 0 or not idle:
        return cur, cur_held, None
    k2 = np.where(k < IWAN_IDLE_SHARE * total, IWAN_RESTART_SHARE * total, k)
    k2 *= total / k2.sum()
    in_place = {**cur.params, **{n: float(v) for n, v in zip(names, k2)}}
    eps = np.array([float(cur.params[_slip_of(n)]) for n in names])
    moved = {**in_place, **idle_slip_strains_moved(eps, k < IWAN_IDLE_SHARE * total, [_slip_of(n) for n in names])}
    fm = fit(trace, cur.spec, cur.effects, [in_place, moved], extra=cur.shape)
    where = ("where the fit left them", "moved into the widest gaps between the live elements' slip strains")[
        min(fm.best_start, 1)] if fm.ok else ""
    n_idle = len(idle)
    if not fm.ok or not optimum_judged(cur.rms, fm.rms, sigma)[0]:
        why = f"the fit failed: {fm.message}" if not fm.ok else (
            f"RMS error {cur.rms / sigma:.2f} -> {fm.rms / sigma:.2f} x noise: the bank stays as it was")
        r = Refinement("hysteresis", tuple(idle), cur.rms, fm.rms if fm.ok else float("inf"), cur_held,
                       float("nan"), float("nan"), False, why, restart=True)
        say(f"  {n_idle} idle Iwan element{'s' if n_idle > 1 else ''} restarted: not kept: {why}")
        return cur, cur_held, r
    pf = fit(part, fm.spec, fm.effects, [fm.params], extra=fm.shape)
    held = _heldout(trace, fm.spec, pf.params, held_out) if pf.ok else float("inf")
    bic = bic_change(cur, fm, len(trace.time))
    live = int(np.sum(np.array([fm.params[n] for n in names]) >= IWAN_IDLE_SHARE * total))
    verdict = (f"{where}: "
               f"RMS error {cur.rms / sigma:.2f} -> {fm.rms / sigma:.2f} x noise with the same terms, BIC {bic:+.0f}, "
               f"{live} of {len(names)} elements carry the bank (were {len(names) - n_idle}); held-out "
               f"{cur_held / sigma:.2f} -> {held / sigma:.2f} x noise")
    r = Refinement("hysteresis", tuple(idle), cur.rms, fm.rms, cur_held, held, bic, True, verdict,
                   {n: float(fm.params[n]) for n in names}, restart=True)
    say(f"  {n_idle} idle Iwan element{'s' if n_idle > 1 else ''} restarted: kept: {verdict}")
    return fm, held, r


#: a finer bank splits each live element in two, their slip strains this share below and above its
IWAN_SPLIT = 0.15


def bank_cap_factor(elements: int) -> float:
    """The work caps of a fit that carries an Iwan bank of ``elements`` elements, as a multiple of the
    search's (whose fits carry IWAN_FIT_ELEMENTS): each simulation carries the bank, each Jacobian a
    column per element (docs/discovery.md, "Time")."""
    return max(1.0, elements / len(IWAN_K_FIT))


def reseeded_cap_factor(m: ModelFit) -> float:
    """The work caps of the shape fits beside ``m``'s reseeded Iwan bank (bank_cap_factor of the
    elements ``m`` frees; 1 without a bank)."""
    return bank_cap_factor(sum(1 for k in IWAN_K if k in m.free))


def _finer_spread(k: np.ndarray, e: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A finer bank of ``size`` elements from the bank (stiffnesses ``k``, slip strains ``e``) that
    spreads its friction: each live element (IWAN_IDLE_SHARE of the stiffness or more) split in two
    (half its stiffness each, slip strains IWAN_SPLIT below and above its own), the rest of the slots
    at the middle of the widest gaps between the slip strains at IWAN_RESTART_SHARE of the
    stiffness, the whole scaled back to the bank's stiffness. None where the bank has no room."""
    total = float(k.sum())
    live = k >= IWAN_IDLE_SHARE * total
    if not total > 0 or 2 * int(live.sum()) > size:
        return None
    k2, e2 = _split_in_two(k[live], e[live])
    rest = size - len(k2)
    if rest:
        e2 = np.r_[e2, _gap_midpoints(e2, rest)]
        k2 = np.r_[k2, np.full(rest, IWAN_RESTART_SHARE * total)]
        k2 *= total / k2.sum()
    return k2, e2


def _finer_kept(k: np.ndarray, e: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A finer bank of ``size`` elements from the bank (stiffnesses ``k``, slip strains ``e``) that
    simulates nearly as it does: every element that carries a force kept, those carrying the largest
    slip forces k_i eps_i split in two (half the stiffness each, slip strains IWAN_SPLIT below and
    above its own) as far as the slots go, and any slot left at the middle of the widest gaps
    between the slip strains (_gap_midpoints), each new element carrying IWAN_RESTART_SHARE of the
    bank's slip force. Shares of the bank's stiffness would be ruled by near-rigid elements of tiny
    slip strain, which carry almost no force: measured on a forced record of Iwan friction with
    slack (tuning draw, 2026-11-27), dropping an element of 1 % of the stiffness but 15 % of the
    force and adding two of 5 % of the stiffness each (_finer_spread) started the finer bank at
    280 x noise against the bank's 2.6 x; this start is at 4.1 x. None where the bank has no room."""
    carrying = np.flatnonzero(k > 0)
    force = k * e
    if len(carrying) == 0 or len(carrying) >= size or not float(force.sum()) > 0:
        return None
    by_force = carrying[np.argsort(-force[carrying], kind="stable")]
    split, kept = by_force[:size - len(carrying)], by_force[size - len(carrying):]
    k_split, e_split = _split_in_two(k[split], e[split])
    k2, e2 = np.r_[k[kept], k_split], np.r_[e[kept], e_split]
    rest = size - len(k2)
    if rest:
        new = np.array(_gap_midpoints(e2, rest))
        e2, k2 = np.r_[e2, new], np.r_[k2, IWAN_RESTART_SHARE * float(force.sum()) / new]
    return k2, e2


def _bank_params(k: np.ndarray, e: np.ndarray) -> dict:
    """The bank's parameters, its elements in the order of their slip strains."""
    order = np.argsort(e)
    return {**{n: float(v) for n, v in zip(IWAN_K, k[order])}, **{n: float(v) for n, v in zip(IWAN_EPS, e[order])}}


def _split_in_two(k: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each element (stiffness ``k``, slip strain ``e``) as two of half its stiffness, their slip
    strains IWAN_SPLIT below and above its own."""
    return np.r_[k / 2, k / 2], np.r_[e * (1 - IWAN_SPLIT), e * (1 + IWAN_SPLIT)]


#: the finer bank's fits take the whole record at once, without the engine's horizon stages: their
#: starts come from a model fitted to the whole record, so its phase is already right, and a stage
#: on the record's first part lets the bank's 32 terms settle where the rest of the record is worse
#: off than at the start (docs/reproducibility.md, 2026-12-02)
FINER_BANK_ENGINE = {"horizon_stages": 1}


def finer_banks(params: dict, bank: Sequence[str]) -> list[dict]:
    """The finer banks of IWAN_ELEMENTS elements from the bank of the elements ``bank`` (their
    stiffnesses' names) in ``params``: _finer_spread's and _finer_kept's, as parameters, those with
    room."""
    k = np.array([float(params.get(n, 0.0)) for n in bank])
    e = np.array([float(params[_slip_of(n)]) for n in bank])
    banks = (_finer_spread(k, e, len(IWAN_K)), _finer_kept(k, e, len(IWAN_K)))
    return [_bank_params(k2, e2) for k2, e2 in (b for b in banks if b is not None)]


def finer_bank(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
               say: Callable[[str], None]):
    """The search fits an Iwan bank of IWAN_FIT_ELEMENTS elements; a smooth hysteresis loop (a
    braid's friction spread over many fibres) seen through a record with little noise needs more:
    a bank of eight approximates the generator's twelve-element friction with a force error that
    keeps its forced record (noise 1e-5 m) at 2.9 x noise even when started from the truth, where
    the same record made with eight elements fits to 1.03 x. Where the final model still misses the
    record, the bank is made finer from two starts, one that spreads its friction over new elements
    (_finer_spread: on the generator's twelve-element free vibration it fits to 1.03 x noise
    where the other ends at 1.22 x) and one that simulates nearly as the bank does (_finer_kept:
    where near-rigid elements of tiny slip strain rule the bank's stiffness, the first starts at
    280 x noise), and every element's stiffness and slip strain is fitted. Kept as a shape refinement is: a lower BIC on the whole
    record and no worse a prediction of the held-out part by a fit to the first part (asked where
    that prediction can judge, CRITERIA.shape_heldout_informative). Returns the model, its held-out error and
    a Refinement or None."""
    if cur.spec.hysteresis != "iwan" or cur.rms <= CRITERIA.within_noise * sigma:
        return cur, cur_held, None
    bank = [n for n in IWAN_K if n in cur.free]
    if len(bank) >= len(IWAN_K):
        return cur, cur_held, None
    banks = finer_banks(cur.params, bank)
    if not banks:
        return cur, cur_held, None
    starts = [{**cur.params, **b} for b in banks]
    terms = tuple(n for n in IWAN_K + IWAN_EPS if n not in cur.free)
    extra = tuple(cur.shape) + tuple(n for n in IWAN_K[len(bank):] + IWAN_EPS if n not in cur.shape)
    cap_factor = bank_cap_factor(len(IWAN_K))
    fm = fit(trace, cur.spec, cur.effects, starts, extra=extra, cap_factor=cap_factor, **FINER_BANK_ENGINE)
    n = len(trace.time)
    bic = bic_change(cur, fm, n)
    held = float("nan")
    if not fm.ok:
        ok, verdict = False, f"the fit failed: {fm.message}"
    else:
        if bic < 0.0 and fm.rms < cur.rms and _shape_heldout_asked(cur.rms, cur_held, fm.rms, sigma):
            pf = fit(part, fm.spec, fm.effects, [fm.params], extra=extra, cap_factor=cap_factor, **FINER_BANK_ENGINE)
            held = _heldout(trace, fm.spec, pf.params, held_out) if pf.ok else float("inf")
        ok, verdict = _shape_judged(cur.rms, fm.rms, bic, cur_held, held, sigma,
                                    f"RMS error {cur.rms / sigma:.2f} -> {fm.rms / sigma:.2f} x noise, BIC changes "
                                    f"by {bic:+.1f}: the bank of {len(bank)} stays")
        if ok:
            verdict = f"{len(IWAN_K)} elements for {len(bank)}: {verdict}"
    r = Refinement("hysteresis", terms, cur.rms, fm.rms if fm.ok else float("inf"), cur_held, held, bic, ok, verdict,
                   {t: float(fm.params[t]) for t in IWAN_K + IWAN_EPS} if fm.ok else {}, finer=True)
    say(f"  a finer Iwan bank: {'kept' if ok else 'not kept'}: {verdict}")
    return (fm, held if math.isfinite(held) else cur_held, r) if ok else (cur, cur_held, r)


def _exponential_from_cubic(params: dict, strain: float) -> dict:
    """The exponential law with the cubic's (and power term's) tangent stiffness and its slope at
    ``strain`` (the record's typical strain): exp_eps = k / k', exp_F = k exp_eps exp(-strain / exp_eps);
    {} where the cubic does not stiffen there."""
    from ..fit.elastic import cubic_tension
    h = max(1e-6, 1e-3 * abs(strain))
    F = [float(cubic_tension(params, strain + j * h)) for j in (-1, 0, 1)]
    k, k2 = (F[2] - F[0]) / (2 * h), (F[2] - 2 * F[1] + F[0]) / h ** 2
    if not (k > 0 and k2 > 0):
        return {}
    e = k / k2
    return {"exp_F": k * e * math.exp(-strain / e), "exp_eps": e}


def _wider_law_starts(trace: Trace, cur: ModelFit, new, effect: str, law: str) -> list:
    """Starts of the wider law ``new`` of ``effect`` in place of ``law``: the current model's other
    terms with the new law's terms from the data (tether.fit's estimate, the other terms fixed at the
    current fit's); where the two laws have the same terms (c(.) of the displacement and of the
    amplitude), the fitted values carried over; and, for the exponential law, matched to the cubic's
    stiffness and its slope at the record's typical strain. (tether.fit's estimate of the whole
    model is the first start again but for the other terms, which the current fit has better.)"""
    own, theirs = _law_terms(effect, law), _law_terms(effect, _law_of(new, effect))
    mine = {k: float(v) for k, v in cur.params.items() if k in new.parameters and k not in own}
    estimate = {k: v for k, v in _estimated(trace, new, mine).items() if k in theirs}
    mine.update(_fitted_nuisance(cur))
    starts = [{**mine, **estimate}]
    if set(own) == set(theirs):
        starts.append({**mine, **{k: float(v) for k, v in cur.params.items() if k in own}})
    if effect == "nonlinear_stiffness":
        eps = np.asarray(trace.measured, float) / float(trace.length_m)
        typical = float(np.median(eps)) if trace.rig != "payload" else 0.0
        if trace.rig == "payload":
            from .. import identify_native as idn
            from ..fit.elastic import cubic_inverse
            typical = float(cubic_inverse(cur.params)(idn.payload_masses(trace)[0] * float(trace.gravity_m_s2)))
        matched = _exponential_from_cubic(cur.params, max(typical, 0.0))
        if matched:
            starts.append({**mine, **matched})
    return starts


def wider_law(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
              say: Callable[[str], None], sc: _Scales | None = None):
    """The search names effects with its own laws (the cubic, the Kelvin cells and slip); a tether
    that is not ours may follow another law of the same effect (WIDER_LAWS: an exponential
    stiffness, primary creep as a power or the logarithm of time, c(.) of the swing's amplitude).
    Where the final model still misses the record, each named effect that has a wider law is fitted
    again with it in its place (starts: _wider_law_starts), kept as a rival law is (a lower BIC, the
    held-out prediction no worse: _law_judged); where it is not kept and the wider law has shapes
    the model does not free yet, once more with its first shape group free (refine.shape_starts: a
    damping that saturates with the amplitude needs the table of c(.)). Tried only then, so a record
    the search's own laws explain takes no longer. Returns the model, its held-out error and a list
    of Refinements."""
    refinements = []
    for effect, (law, other) in WIDER_LAWS.items():
        if (cur.rms <= CRITERIA.within_noise * sigma or effect not in cur.effects or _law_of(cur.spec, effect) != law
                or not EFFECT[effect].law(other).tried_on(trace.rig)):
            continue
        new = _with_law(cur.spec, effect, other).for_experiment(trace.experiment)
        starts = _wider_law_starts(trace, cur, new, effect, law)
        reported = (lambda k, free=tuple(cur.free): k not in free)
        cur, cur_held, r = _law_swapped(trace, part, held_out, cur, cur_held, sigma, fit, new, effect, law, starts,
                                        reported, say)
        refinements.append(r)
        shapes = EFFECT[effect].law(other).shapes
        if not r.accepted and shapes and sc is not None and not set(shapes[0]) <= set(cur.shape):
            group = shapes[0]
            shaped = [s for st in starts if st is not None for s in shape_starts(trace, new, st, group, sc)]
            cur, cur_held, r = _law_swapped(trace, part, held_out, cur, cur_held, sigma, fit, new, effect, law,
                                            shaped, reported, say, extra=group)
            refinements.append(r)
    return cur, cur_held, refinements
