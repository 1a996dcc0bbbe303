"""Campaigns of the project's generator (hidden_effects): several records of ONE tether (issue 29).

A tether is one draw of hidden_effects' material parameters (its stiffness, its elastic law, its
Iwan friction, its creep) and one set of hidden material effects; each record is an experiment on
that tether, generated with the material parameters given as overrides, so every record carries
the same law. A record is generated with the tether's effects that act in its experiment (creep
is not simulated in the dynamic ones; slack is a condition of the free vibration, released from
high enough to go slack). The records keep their own noise, rate and experiment parameters.

campaign(seed) draws the tether's effects and writes the three records of the acceptance: a free
vibration, a load-unload test and a creep test, small (hundreds to ~2,000 samples each).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import hidden_effects as he

#: the material parameters of hidden_effects._draw_params a tether shares between its records
MATERIAL = ("EA_N", "stiffness_law", "stiff_alpha", "stiff_eps_r_factor", "stiff_eps_r_load", "stiff_p",
            "hyst_n", "hyst_eta", "hyst_slip_N", "hyst_beta", "damping_law", "damp_gain", "damp_xc_factor", "zeta",
            "creep_kernel", "creep_e1h", "creep_n", "creep_tau_s", "plastic_e10h", "plastic_q", "plastic_r",
            "length_m", "diameter_mm")

#: what acts in each experiment of the campaign (hidden_effects refuses creep in dynamic records)
ACTS_IN = {"free_vibration": ("nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"),
           "load_unload": ("nonlinear_stiffness", "hysteresis", "creep"),
           "creep": ("nonlinear_stiffness", "hysteresis", "creep")}

#: the small records of the campaign: rates and programs that keep each to hundreds to ~2,000 samples
SMALL = {"free_vibration": {"rate": 100.0, "duration_s": 8.0},
         "load_unload": {"rate": 5.0},
         "creep": {"rate": 0.1, "creep_program": [[100.0, 2.0], [5.0, 1.5]]}}

#: the effect sets a campaign draws from (campaign(seed)): material effects split over the
#: experiments (slack shows only in the free vibration, creep only in the load tests, hysteresis
#: and the elastic law in all)
EFFECT_SETS = ({"creep", "slack"}, {"creep", "hysteresis"}, {"slack", "hysteresis"},
               {"creep", "slack", "hysteresis"}, {"nonlinear_stiffness", "creep"},
               {"nonlinear_stiffness", "slack", "creep"})


def tether_material(seed: int) -> dict:
    """One tether's material parameters: hidden_effects' draw for a free vibration (whose EA keeps
    the static stretch above the noise), shared by every record of the campaign."""
    P = he._draw_params("free_vibration", np.random.default_rng(np.random.SeedSequence(int(seed)).spawn(3)[0]))
    return {k: P[k] for k in MATERIAL}


def reference_strain(P: dict) -> float:
    """The strain scale of the tether's nonlinear elastic law, the same in every record: the load
    tests' (hidden_effects: eps_r of the logcosh law, eps_ref = 0.01 of the power law). Left to each
    experiment, a payload record's law scaled with its own static strain, so that the records of a
    campaign were of tethers whose laws differed (docs/campaign-discovery.md, 2026-11-28)."""
    return float(P["stiff_eps_r_load"]) if P["stiffness_law"] == "logcosh" else 0.01


#: the tests' records: lower rates and shorter programs than SMALL (tens to hundreds of samples),
#: which keep a campaign's discovery within a minute of CPU
TINY = {"free_vibration": {"rate": 50.0, "duration_s": 6.0},
        "load_unload": {"rate": 2.0},
        "creep": {"rate": 0.05, "creep_program": [[100.0, 2.0], [5.0, 1.5]]}}


def record(experiment: str, tether_effects, material: dict, seed: int, sizes: dict | None = None, **overrides):
    """One record of the tether: its experiment with the tether's effects that act in it, at the
    rate and program ``sizes`` gives it (default SMALL); its elastic law's strain scale the
    tether's (reference_strain), unless the material or the overrides set it."""
    effects = {e for e in tether_effects if e in ACTS_IN[experiment]}
    kw = {**(SMALL if sizes is None else sizes)[experiment], **material, **overrides}
    kw.setdefault("stiff_ref_strain", reference_strain(kw))
    return he.generate(experiment, effects, seed, **kw)


def campaign(seed: int, effects=None, experiments=("free_vibration", "load_unload", "creep"), sizes: dict | None = None,
             **material_changes):
    """(records, tether effects, material) of one campaign: the effects drawn from EFFECT_SETS by
    ``seed`` unless given; ``sizes``: the records' rates and programs (default SMALL);
    ``material_changes`` alter the tether's material (e.g. EA_N)."""
    rng = np.random.default_rng(int(seed) + 7919)
    if effects is None:
        effects = EFFECT_SETS[int(rng.integers(len(EFFECT_SETS)))]
    material = {**tether_material(seed), **material_changes}
    recs = [record(x, effects, material, 1000 * int(seed) + i, sizes) for i, x in enumerate(experiments)]
    return recs, set(effects), material


def hidden_union(records) -> set:
    """The effects the campaign's records reveal between them (each record's hidden 'revealed')."""
    out = set()
    for r in records:
        out |= set(r.revealed)
    return out


def write_campaign(records, folder: Path, prefix: str = "rec") -> list[Path]:
    """Each record written as folder/PREFIX_i_EXPERIMENT.csv/.json; their stems."""
    stems = []
    for i, r in enumerate(records):
        stem = f"{prefix}{i}_{r.experiment}"
        r.write(folder, stem)
        stems.append(Path(folder) / stem)
    return stems
