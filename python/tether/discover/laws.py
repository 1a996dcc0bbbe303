"""What an effect and a law are, in one place: the effects each experiment can reveal, the models
that add an effect (one law each, hysteresis several), the shape terms of each law, the terms a fit
frees and their floors. EFFECTS is the registry of issue 25; the tables are views of it."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from ..models import C_OF_MAGNITUDE, IWAN_EPS, IWAN_EPS_FIT, IWAN_K, ModelSpec
from ..traces import EXPERIMENTS, Trace
from . import starts as S
from .scales import _Scales


@dataclass(frozen=True)
class Law:
    """One law of an effect as the search uses it: ``name`` is its value in the ModelSpec field of
    the effect; ``rigs`` the rigs whose records try it when the effect is added (None: every rig);
    ``shapes`` the groups of shape terms refine_shapes may free from the final model (the search
    for effects keeps them at the classic law's values: they change a law's shape, not which
    effects the record shows); ``rival`` the law fitted again in its place at the end (rival_law
    for the hysteresis, other_rival_laws for the others), whose tie with it in a step forks the
    rival branch;
    ``wider`` the law fitted in its place where the final model still misses the record
    (wider_law); ``added`` false for a law reached only as another's rival or wider law;
    ``starts`` the starts of a model that adds the law (base fit, new spec, scales, trace -> a list
    of parameter dicts, None for tether.fit's data-based estimate; see starts.candidate_starts),
    ``starts_from`` those of a model that puts it in another law's place, as (that law, starts);
    ``reseed`` the moves that reseed the law's fitted terms where the final model still misses the
    record, as (function of rival.py, what it does: the stage's words); ``loop_terms`` the terms
    that open a hysteresis law's loops (at zero the law is elastic: judge._loops_open);
    ``campaigns`` false for a law a campaign of several records does not try yet (docs/discovery.md);
    ``model_tolerance`` true for a law whose fits keep the model's own integration tolerance in the
    search (fitting.search_rtol): a force with corners the integrator does not locate, whose
    finite-difference Jacobian a looser tolerance blurs.
    A switch without a law (slack) has one law, named as its effect, for its starts."""

    name: str
    starts: Callable
    rigs: tuple | None = None
    shapes: tuple = ()
    rival: str | None = None
    wider: str | None = None
    added: bool = True
    starts_from: tuple = ()
    reseed: tuple = ()
    loop_terms: tuple = ()
    campaigns: bool = True
    model_tolerance: bool = False

    def tried_on(self, rig: str) -> bool:
        """Does a record of this rig try the law (``rigs``: None, every rig)?"""
        return self.rigs is None or rig in self.rigs


@dataclass(frozen=True)
class Effect:
    """One effect of the trace format's vocabulary: ``law_field`` the ModelSpec field that holds its
    law and ``absent`` that field's value without the effect (slack: a switch, no law), ``switch``
    a ModelSpec flag the effect sets (creep), ``laws`` in the order a step tries them, ``unrevealed``
    why each experiment that cannot reveal it cannot, ``leads`` the experiments built to show it,
    whose search tries it first."""

    name: str
    law_field: str | None
    absent: object
    laws: tuple
    unrevealed: dict
    switch: str | None = None
    leads: tuple = ()

    def law(self, name: str | None) -> Law | None:
        """The entry of the law ``name``; None where the registry has none of that name (the linear
        law of a model whose nonlinear stiffness is Kawabata's branches)."""
        return next((law for law in self.laws if law.name == name), None)

    def law_in(self, spec: ModelSpec) -> str | None:
        """The law of this effect in ``spec``, None where ``spec`` lacks the effect (a switch-only
        effect's law is named as the effect)."""
        if self.switch and not getattr(spec, self.switch):
            return None
        if self.law_field is None:
            return self.name
        law = getattr(spec, self.law_field)
        return law if self.switch or law != self.absent else None


_QUASI_STATIC = ("load", "element")
_HOURS = "creep acts over minutes to hours under a held load: it cannot show in this record"
_NEVER_COMPRESSED = ("the tether is never pushed towards compression, where slack would act")
#: the table of c(.): its knots, the shape group of both laws of a coefficient c0 + c(a) (SHAPE_TERMS),
#: also tried as the law of a nonlinear-damping candidate
DAMPING_TABLE = ("c_table_1", "c_table_2", "c_table_3", "c_table_4", "c_table_5", "c_table_6")

#: the registry of effects and their laws (issue 25): adding a law or an effect is one entry here
#: (plus the C law and its variables); the tables below are its views
EFFECTS = (
    Effect("nonlinear_stiffness", "stiffness", "linear", (
        # the cubic's power term: a stiffness growing from zero as a fractional power of the strain,
        # which the cubic misses near eps = 0 (a load test of the generator's power-law tether with
        # Iwan friction stopped at 2.05 x noise with the cubic)
        Law("cubic", S.cubic_starts, shapes=(("pow_F", "pow_n"),), wider="exponential", rival="bilinear"),
        # in a load test the exponential law is a candidate too: a Bouc-Wen force with beta = 0 and
        # gamma < 0 is that law in disguise (dz/dx = A + |gamma| z both ways: z = (A/|gamma|)
        # (exp(|gamma| x) - 1)), and with one parameter fewer it would name hysteresis for a
        # stiffness the cubic misses (an exponential tether's load test: hysteresis named at 1.01 x
        # noise, bench/wider_laws_discovery.py)
        Law("exponential", S.estimate_start, rigs=_QUASI_STATIC),
        # a braid's toe: soft while its yarns straighten, then stiff; the cubic follows a corner
        # only where it is gentle (generator B's toe-linear free vibration with dry friction:
        # 2.46 x noise with the cubic and its power term)
        Law("bilinear", S.bilinear_starts, campaigns=False, rival="cubic")),
        {}),
    Effect("hysteresis", "hysteresis", "none", (
        Law("boucwen", S.boucwen_starts, shapes=(("bw_n",), ("bw_b2", "bw_b3", "bw_b4", "bw_b5", "bw_b6"),
                                                 ("bw_n", "bw_b2", "bw_b3", "bw_b4", "bw_b5", "bw_b6")),
            rival="iwan", starts_from=(("kawabata", S.boucwen_from_kawabata_starts),),
            # the direction-dependent terms of psi: at zero, dz/dx depends on z alone and z on x alone
            loop_terms=("bw_beta", "bw_b2", "bw_b4")),
        # Bouc-Wen's tangent stiffness approaches zero exponentially, inter-fibre friction's falls
        # to zero at a finite strain: on records of the latter Bouc-Wen left 3.4-10 x noise
        # (bench/hysteresis_law_gap.py). Its shape: the slip strains off the fit's grid (a load test
        # of twelve elements slipping between 4e-4 and 8e-3: 3.7 x noise on the grid, 1.2 x free)
        Law("iwan", S.iwan_starts, shapes=(IWAN_EPS_FIT,), rival="boucwen",
            reseed=(("restart_idle_elements", "the idle Iwan elements were restarted"),
                    ("finer_bank", "the Iwan bank was made finer")),
            # each element's slip a corner (docs/speed.md, sessions 65-66)
            model_tolerance=True),
        # the paper's loading and unloading branches, which replace the elastic law (their loading
        # curve is a power law)
        Law("kawabata", S.estimate_start, rigs=_QUASI_STATIC)),
        {}),
    Effect("nonlinear_damping", "damping", "viscous", (
        # c(x) beyond the polynomial: its tabulated part, knots spread over the displacements seen
        Law("displacement", S.damping_starts, shapes=(DAMPING_TABLE,), rival="coulomb", wider="amplitude"),
        # the same c(.) read at the swing's amplitude: a forced record that sweeps through its
        # resonance holds one amplitude over cycles in which |x| runs from 0 to it and back, and
        # c(|x|) cannot follow a damping of the amplitude there (generator B's forced sweep with a
        # saturating c(A): 3.24 x noise with c(x))
        Law("amplitude", S.damping_starts, rigs=("payload",), shapes=(DAMPING_TABLE,), added=False),
        # dry friction beside the viscous part: a damping that falls with amplitude, where c(x) and
        # the drag grow with it
        Law("coulomb", S.coulomb_starts, rival="displacement")),
        {"load_unload": "a load test is quasi-static (no inertia, speeds near zero): damping, linear or not, "
                        "does not act in it",
         "creep": "a creep test holds its loads for hours and changes them between two samples: damping acts on "
                  "no sample"}),
    Effect("creep", "creep_law", "kelvin_slip", (
        Law("kelvin_slip", S.creep_starts, wider="primary"),
        Law("primary", S.creep_starts, added=False)),
        {"free_vibration": "a free vibration lasts seconds, and " + _HOURS,
         "forced": "a forced vibration lasts seconds, and " + _HOURS},
        switch="creep", leads=("creep",)),
    Effect("slack", None, None, (Law("slack", S.slack_starts),),
           {"load_unload": "the load of a load test is never below zero: " + _NEVER_COMPRESSED,
            "creep": "the load of a creep test is never below zero: " + _NEVER_COMPRESSED},
           switch="slack"),
)

EFFECT = {e.name: e for e in EFFECTS}


def _search_order(experiment: str) -> tuple[str, ...]:
    revealed = [e for e in EFFECTS if experiment not in e.unrevealed]
    return tuple(e.name for e in revealed if experiment in e.leads) + tuple(
        e.name for e in revealed if experiment not in e.leads)


#: candidate effects per experiment (what the experiment can reveal), in the order they are tried
CANDIDATES = {x: _search_order(x) for x in EXPERIMENTS}


#: why an experiment cannot reveal each effect of the vocabulary it has no candidate for
#: (CANDIDATES and this table together cover every effect of every experiment)
NOT_REVEALED = {x: {e.name: e.unrevealed[x] for e in EFFECTS if x in e.unrevealed}
                for x in EXPERIMENTS if any(x in e.unrevealed for e in EFFECTS)}


#: shape terms of a named effect's law that the last stage may free (see refine_shapes), per effect
#: and law: each entry one group tried from the final model
SHAPE_TERMS = {(e.name, law.name): law.shapes for e in EFFECTS for law in e.laws if law.shapes}


#: terms a shape refinement sets but does not fit
SHAPE_HELD = ("c_table_dx", "pow_eps")


#: terms a shape group replaces: held at 0 while it is fitted and after it is kept (the table of
#: c(x) and the drag both stand for a damping growing with amplitude; freed together the fit of a
#: Gaussian c(x) stopped at 2.0 x noise and its held-out prediction at 39 x; the table spans
#: c1 |x| + c2 x^2 over the record's range: beside it c2 wandered (to 240-320 N s/m^3 against
#: knots that fell to match), and a fit of the record's first part went with it)
SHAPE_REPLACES = {"c_table_1": ("c_drag", "c1", "c2")}


#: terms a fit that does not free them holds at its start's value, not at the FMU's default: the
#: table's knot spacing, the terms a shape group replaces (their 0 is not every default: c1's is
#: 25 N s/m^2) and every shape term (e.g. the table's knots a part of the record does not reach)
HELD_AT_START = tuple(dict.fromkeys(
    SHAPE_HELD + tuple(r for rs in SHAPE_REPLACES.values() for r in rs)
    + tuple(k for groups in SHAPE_TERMS.values() for g in groups for k in g) + IWAN_EPS))


def _replaced(group: Sequence[str]) -> tuple:
    return tuple(r for g in group for r in SHAPE_REPLACES.get(g, ()))


#: the ModelSpec field that holds each effect's law (slack has none)
LAW_FIELD = {e.name: e.law_field for e in EFFECTS if e.law_field}


def _law_of(spec: ModelSpec, effect: str) -> str | None:
    return getattr(spec, LAW_FIELD[effect]) if effect in LAW_FIELD else None


def _with_law(spec: ModelSpec, effect: str, law: str) -> ModelSpec:
    """``spec`` with ``law`` as the law of ``effect``."""
    return replace(spec, **{LAW_FIELD[effect]: law})


def added_law(old: ModelSpec, new: ModelSpec) -> tuple[Law, str | None] | None:
    """The law ``new`` adds to ``old`` (a law that ``old`` lacks, or an effect ``old`` lacks; an
    effect behind a switch only where the switch comes on) and the law of its effect that ``old``
    had (None: none). Where several are added (Kawabata's branches replaced by a cubic law under a
    Bouc-Wen force, _kawabata_split), the one whose ``starts_from`` names the law ``old`` had, else
    the first in the registry's order; None where ``new`` adds no law."""
    added = []
    for e in EFFECTS:
        was, now = e.law_in(old), e.law_in(new)
        if now is not None and now != was and (was is None or not e.switch) and e.law(now) is not None:
            added.append((e.law(now), was))
    return next((a for a in added if a[1] in dict(a[0].starts_from)), added[0] if added else None)


def keeps_model_tolerance(spec: ModelSpec) -> bool:
    """Does a law of ``spec`` keep the model's own integration tolerance (Law.model_tolerance)?"""
    return any(law is not None and law.model_tolerance for law in (e.law(e.law_in(spec)) for e in EFFECTS))


def free_parameters(spec: ModelSpec, experiment: str) -> list[str]:
    """What a discovery fit frees: the elastic law (EA; a1 a2 a3; Kawabata's LT RT F_ref and, in
    load tests, the residual strain), the damping in the payload rig (c0; c1 c2), Bouc-Wen's A beta
    gamma, the Iwan element stiffnesses (iw_k1..8, on the estimate's grid of slip strains), and the
    creep compliances, time constants and slip (creep_J1..3, creep_tau1..3, slip_capacity0,
    slip_rate; KELVIN_TIMES, CREEP_SHAPE). Unlike
    tether.fit's defaults, a creep test frees the cubic too: two load levels leave one direction of
    it undetermined, but discovery asks only whether the law lowers the error."""
    from ..fit.parameters import CREEP_FREE_BY_LAW, law_free_parameters

    spec = spec.for_experiment(experiment)
    names = law_free_parameters(spec)
    if spec.rig == "payload" and spec.damping in C_OF_MAGNITUDE:
        names.append("c_drag")   # nonlinear damping through the displacement or through the speed
    if spec.creep:
        shape = CREEP_SHAPE[spec.creep_law] if experiment == "creep" else ()
        names += list(CREEP_FREE_BY_LAW[spec.creep_law] + KELVIN_TIMES + shape)
    return names


#: the creep terms discovery frees beyond tether.fit's CREEP_FREE_BY_LAW: the Kelvin cells' time
#: constants in every record (a load-unload test of minutes shows cells of seconds to minutes, not
#: the hours the FMU's defaults hold them at), and in a creep test (hours of holds) the slip's shape
#: beside them, by creep law
KELVIN_TIMES = ("creep_tau1", "creep_tau2", "creep_tau3")
CREEP_SHAPE = {"kelvin_slip": ("slip_knee", "slip_regen_tau", "slip_limit", "slip_load_half"),
               "primary": ()}


def _floor(name: str, sc: _Scales) -> float:
    """Smallest |start| of a linearly scaled parameter (the engine scales it by its start)."""
    return {"a2": 1e-3 * sc.ea / sc.eps, "a3": 1e-3 * sc.ea / sc.eps ** 2,
            "bw_beta": 1e-2 / sc.amp, "bw_gamma": 1e-2 / sc.amp}.get(name, 0.0)


_POSITIVE = ("EA", "a1", "exp_F", "exp_eps", "toe_EA", "toe_eps", "toe_width", "primary_J", "primary_tau", "c0", "c1", "c2", "c_drag", "c_coulomb",
             "coulomb_v", "bw_A",
             "kaw_F_ref", "creep_J1", "creep_J2", "creep_J3", "slip_capacity0", "slip_rate", "creep_tau1", "creep_tau2", "creep_tau3", "slip_knee", "slip_regen_tau",
             "slip_limit", "slip_load_half", *IWAN_K)


def sampled_branches(trace: Trace, min_samples: int = 3) -> bool:
    """Load tests: does the record hold samples on a loading path and on an unloading path over a
    common range of load (between 5 % and 95 % of the largest)? Only then can it tell hysteresis
    from a nonlinear elastic law. A creep test that changes its weights within one sample
    interval samples only the held levels; a Masing-type hysteresis returns to the same strain at
    every revisit of a level, so there it is a single-valued load-strain relation, exactly what
    nonlinear stiffness gives."""
    T = np.asarray(trace.input, float)
    if len(T) < 3:
        return False
    top = float(np.max(np.abs(T)))
    if not top > 0:
        return False
    d_in, d_out = np.diff(T)[:-1], np.diff(T)[1:]          # the steps into and out of each inner sample
    inner = T[1:-1]
    mid = (inner > 0.05 * top) & (inner < 0.95 * top)
    tol = 1e-9 * top
    up = inner[mid & (d_in > tol) & (d_out > tol)]
    down = inner[mid & (d_in < -tol) & (d_out < -tol)]
    if len(up) < min_samples or len(down) < min_samples:
        return False
    lo, hi = max(up.min(), down.min()), min(up.max(), down.max())
    return int(np.sum((up >= lo) & (up <= hi))) >= min_samples and int(np.sum((down >= lo) & (down <= hi))) >= min_samples


def candidates(trace: Trace) -> tuple[str, ...]:
    """The effects a record of this experiment can reveal (CANDIDATES), less hysteresis in a
    load test that samples no loading and unloading paths (sampled_branches)."""
    c = CANDIDATES[trace.experiment]
    if trace.rig != "payload" and not sampled_branches(trace):
        c = tuple(e for e in c if e != "hysteresis")
    return c


def unrevealed(trace: Trace, effect: str) -> str | None:
    """Why a record of this experiment cannot reveal ``effect`` (NOT_REVEALED; hysteresis in a load
    test that samples no loading and unloading paths, see sampled_branches), or None where it can:
    where ``effect`` is one of candidates(trace)."""
    if effect in candidates(trace):
        return None
    if effect in CANDIDATES[trace.experiment]:
        return ("the load test samples no loading and unloading paths over a common range of load (its weights "
                "change between two samples): there a hysteresis is a single-valued load-strain relation, which "
                "nonlinear stiffness fits as well")
    return NOT_REVEALED[trace.experiment][effect]


def _models_for(spec: ModelSpec, effect: str, trace: Trace) -> list[ModelSpec]:
    """The models that add ``effect`` to ``spec``: one per law of the effect (EFFECTS) that the
    record's rig tries, in the registry's order; none where the model has the effect already, but
    for nonlinear stiffness beside Kawabata's branches (_kawabata_split)."""
    e = EFFECT[effect]
    if effect in spec.effects:
        return _kawabata_split(spec, effect, trace)
    if e.law_field is None:
        return [replace(spec, **{e.switch: True})]
    return [replace(spec, **{e.law_field: law.name, **({e.switch: True} if e.switch else {})})
            for law in _laws_tried(e, trace)]


def _laws_tried(effect: Effect, trace: Trace) -> list[Law]:
    """The laws of ``effect`` that a step adding it tries on ``trace``'s rig."""
    return [law for law in effect.laws if law.added and law.tried_on(trace.rig)]


def tried_in_campaigns(effect: str, spec: ModelSpec) -> bool:
    """Does a campaign try the model ``spec`` as a candidate of ``effect`` (Law.campaigns)?"""
    law = EFFECT[effect].law(EFFECT[effect].law_in(spec))
    return law is None or law.campaigns


def _kawabata_split(spec: ModelSpec, effect: str, trace: Trace) -> list[ModelSpec]:
    """Kawabata's power-law branches carry the elastic law (spec.effects counts them as nonlinear
    stiffness too); the stiffness named beside them is each elastic law the rig tries under a
    Bouc-Wen force, the models that carry the effect by name."""
    if effect == "nonlinear_stiffness" and spec.hysteresis == "kawabata":
        return [replace(spec, stiffness=law.name, hysteresis="boucwen")
                for law in _laws_tried(EFFECT[effect], trace)]
    return []


def takes_damping_table(spec: ModelSpec) -> bool:
    """Is the damping law of ``spec`` one whose shapes include the table of c(x) (c(x), not the
    Coulomb friction)?"""
    return DAMPING_TABLE in SHAPE_TERMS.get(("nonlinear_damping", _law_of(spec, "nonlinear_damping")), ())


def _without(spec: ModelSpec, effect: str) -> ModelSpec:
    """``spec`` without ``effect``: its switch off, or its law field at the law-free value."""
    e = EFFECT[effect]
    return replace(spec, **({e.switch: False} if e.switch else {e.law_field: e.absent}))


#: the laws of one effect that stand in for each other: the law that won an effect's step is fitted
#: again at the end with its rival in its place (rival.rival_law, rival.other_rival_laws)
RIVAL_LAWS = {e.name: tuple(law.name for law in e.laws if law.rival) for e in EFFECTS
              if any(law.rival for law in e.laws)}


#: the terms that open each hysteresis law's loops (Law.loop_terms), by law
LOOP_TERMS = {law.name: law.loop_terms for e in EFFECTS for law in e.laws if law.loop_terms}


#: laws beyond the search's own, by effect (the search's law, the wider law): fitted in the named
#: law's place only where the final model still misses the record (rival.wider_law), so a record
#: the search's laws explain takes no longer
WIDER_LAWS = {e.name: (law.name, law.wider) for e in EFFECTS for law in e.laws if law.wider}
