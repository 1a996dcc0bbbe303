"""tether discover (issue 5), the CI subset.

The traces come from python_tests/hidden_effects.py, a generator with its own laws and integrator
(power-law stiffness, Iwan hysteresis, ... not the FMU's equations), so discovery is tested against
model-form mismatch; the truth is the generator's ``hidden.revealed`` list, which discovery does
not read. The full acceptance run (48 traces, confusion table, the Bouc-Wen benchmark) is
bench/discovery_eval.py: it takes tens of minutes, too long for CI.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import hidden_effects as he
from discovery_outputs import read_strict_json, rerun_rms
from tether import discover as D
from tether import models
from tether.discover import document, fitting, judge, refine, rival, samples, scales, search, starts
from tether.discover.nuisance import nuisance_start
from tether.traces import read_trace

FIELDS = ("added_effects", "rmse_initial", "rmse_final", "noise_estimate", "steps", "final_params")
STEP_FIELDS = ("effect", "where", "evidence", "rmse_before", "rmse_after")


def _write(tmp_path, stem, experiment, effects, seed, **kw):
    tr = he.generate(experiment, effects, seed, **kw)
    tr.write(tmp_path, stem)
    return tmp_path / stem, tr


def _discover_cli(run_cli, stem, tmp_path, *extra):
    out = tmp_path / f"{Path(stem).name}.discovery.json"
    status, stdout, stderr = run_cli("discover", stem, "--json", out, *extra)
    assert status == 0, stderr
    return read_strict_json(out), stdout, stderr


def _record_and_part(stem):
    """A record read back, its noise estimate and scales, the part held-out tests fit and the
    samples they hold out (samples.heldout_split)."""
    tr = read_trace(stem)
    part, held_out = samples.heldout_split(tr, judge.CRITERIA.fit_part)
    return tr, D.estimate_noise(tr).sigma, scales._scales(tr), part, held_out, scales._scales(part)


# ---------------------------------------------------------------------------------------------
# the noise estimate, against the sigma the noise was drawn with
@pytest.mark.parametrize("sigma", [1e-5, 1e-4, 1e-3])
@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_noise_estimate_recovers_the_drawn_sigma(sigma, jitter):
    rng = np.random.default_rng(int(1e6 * sigma) + int(10 * jitter))
    n = 4000
    t = np.arange(n) * 0.005
    t[1:-1] += jitter * 0.005 * rng.uniform(-0.5, 0.5, n - 2)
    # a smooth decaying oscillation of 0.1 m, 50 samples per period
    smooth = 0.1 * np.exp(-0.1 * t) * np.cos(2 * np.pi * 4 * t) + 0.02 * np.sin(2 * np.pi * 0.7 * t)
    y = smooth + rng.normal(0.0, sigma, n)

    class _T:
        time = t
        measured = y
        periodic_samples = None

    est = D.estimate_noise(_T())
    assert est.sigma == pytest.approx(sigma, rel=0.08)


# ---------------------------------------------------------------------------------------------
# the verdicts: what earns its parameters
def test_verdict_accepts_a_gap_closed_to_the_noise_and_refuses_a_bic_rise():
    s = 1.0
    ok, why = judge.full_data_verdict(s, rms_before=5.0, rms_after=1.02, bic_change=-500.0)
    assert ok, why
    ok, why = judge.full_data_verdict(s, rms_before=5.0, rms_after=1.02, bic_change=+3.0)
    assert not ok and "BIC" in why
    # a gap that barely moves does not earn anything, however low the BIC
    ok, why = judge.full_data_verdict(s, rms_before=5.0, rms_after=4.5, bic_change=-50.0)
    assert not ok and "gap" in why
    # within the noise before: nothing to gain
    ok, _ = judge.full_data_verdict(s, rms_before=1.0, rms_after=0.99, bic_change=-1.0)
    assert not ok
    assert judge._gap(math.sqrt(2.0), 1.0) == pytest.approx(1.0)


# ---------------------------------------------------------------------------------------------
# null traces: the baseline is the truth, nothing may be named
@pytest.mark.parametrize("experiment,seed,kw", [
    ("free_vibration", 101, dict(noise=1e-4, rate=200.0)),
    ("forced", 102, dict(noise=1e-5, rate=200.0)),
    ("load_unload", 103, dict(noise=5e-5, rate=10.0, jitter=0.3)),
    ("creep", 104, dict(noise=2e-5, rate=0.2)),
])
def test_null_traces_name_nothing(tmp_path, run_cli, experiment, seed, kw):
    stem, tr = _write(tmp_path, f"null_{experiment}", experiment, set(), seed, **kw)
    doc, out, _ = _discover_cli(run_cli, stem, tmp_path)
    assert doc["added_effects"] == [] and doc["steps"] == []
    assert doc["final_params"]["model"] == "linear"
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    assert doc["noise_estimate"] == pytest.approx(sigma, rel=0.15)
    assert doc["rmse_final"] == doc["rmse_initial"] <= 1.2 * sigma
    assert "no effect is missing" in out


# ---------------------------------------------------------------------------------------------
# effects hidden one at a time, in each kind of experiment
@pytest.mark.parametrize("experiment,effects,seed,kw", [
    ("load_unload", {"nonlinear_stiffness"}, 7, dict(noise=5e-5, rate=5.0, stiffness_law="logcosh")),
    ("forced", {"slack"}, 18, dict(noise=1e-4, rate=100.0, duration_s=10.0)),
    # logarithmic creep: the model's three Kelvin cells follow it to the noise. A Findley power law
    # (infinitely fast right after a load step) they follow to 1.1-1.2 x noise from the equation-
    # error start of their retardation times (bench/discovery_eval.py, traces 07 and 41; the start
    # itself is tested below, test_the_creep_start_finds_the_kelvin_cells_of_a_record)
    ("creep", {"creep"}, 9, dict(noise=5e-5, rate=0.05, creep_kernel="log")),
])
def test_a_hidden_effect_is_named_and_the_gap_closes(tmp_path, run_cli, experiment, effects, seed, kw):
    stem, tr = _write(tmp_path, f"{experiment}_hidden", experiment, effects, seed, **kw)
    doc, _, _ = _discover_cli(run_cli, stem, tmp_path)
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    assert set(doc["added_effects"]) == set(tr.revealed), doc["added_effects"]
    assert doc["rmse_initial"] > 3 * sigma            # the linear baseline misses it plainly ...
    assert doc["rmse_final"] <= 1.5 * sigma           # ... the discovered model is at the noise


def test_drag_damping_and_slack_are_named_and_the_drag_is_measured(tmp_path, run_cli):
    """A free vibration released from above the slack point with velocity-quadratic drag (the
    generator's F = c0 u' + c_q |u'| u', integrated by its own RK4): discovery names nonlinear
    damping and slack, ends at the noise, and its drag and viscous coefficients are the
    generator's (c(x) alone left such records at 3-13 x noise, with slack missed)."""
    spec = dict(he.suite_specs(48))["30_free_vibration_nldamp+slack"]
    kw = dict(spec)
    stem, tr = _write(tmp_path, "drag_slack", kw.pop("experiment"), kw.pop("effects"), kw.pop("seed"), **kw)
    hidden = tr.meta["hidden"]
    assert hidden["laws"]["damping"] == "drag"
    doc, _, _ = _discover_cli(run_cli, stem, tmp_path)
    sigma = hidden["noise_sigma_m"]
    assert set(doc["added_effects"]) == {"nonlinear_damping", "slack"}, doc["added_effects"]
    assert doc["rmse_final"] <= 1.5 * sigma
    p = doc["parameters"]
    print(f"FIGURE drag: c_drag {p['c_drag']:.4g} (generator {hidden['derived']['damp_cq_N_s2_m2']:.4g}), "
          f"c0 {p['c0']:.4g} (generator {hidden['derived']['c0_N_s_m']:.4g}), rmse_final "
          f"{doc['rmse_final'] / sigma:.2f} x noise")
    assert p["c_drag"] == pytest.approx(hidden["derived"]["damp_cq_N_s2_m2"], rel=0.05)
    assert p["c0"] == pytest.approx(hidden["derived"]["c0_N_s_m"], rel=0.05)


def test_shape_refinement_follows_a_damping_that_levels_off(tmp_path, run_cli):
    """The generator's damping rises with |x| and levels off (a Gaussian step, not the paper's
    polynomial). Discovery names nonlinear_damping; the polynomial leaves the record above the
    noise; the tabulated part of c(x), freed at the end, brings it to the noise without changing
    the name; the JSON records the refinement and, as a --params file, reruns the refined model
    through the FMU at the same error."""
    spec = dict(he.suite_specs(48))["47_forced_nldamp"]
    kw = dict(spec)
    stem, tr = _write(tmp_path, "forced_levels_off", kw.pop("experiment"), kw.pop("effects"), kw.pop("seed"), **kw)
    assert tr.meta["hidden"]["laws"]["damping"] == "gauss"
    doc, out, _ = _discover_cli(run_cli, stem, tmp_path)
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    assert doc["added_effects"] == ["nonlinear_damping"]
    polynomial = doc["steps"][-1]["rmse_after"]
    kept = [r for r in doc["refinements"] if r["accepted"]]
    assert len(kept) == 1 and kept[0]["effect"] == "nonlinear_damping", doc["refinements"]
    # (the refinement starts from the step's polynomial or a refit of it that is no worse)
    assert kept[0]["rmse_before"] <= polynomial * (1 + 1e-9) and kept[0]["rmse_before"] > 2.0 * sigma
    # (the final fit polishes the kept model at the model's own integration tolerance, the search's
    # at a looser one: within a hundredth of its figure, no worse)
    assert doc["rmse_final"] <= kept[0]["rmse_after"] * 1.01 and doc["rmse_final"] <= 1.5 * sigma
    assert doc["shape_refined"] == kept[0]["parameters"] and doc["parameters"]["c_table_dx"] > 0
    assert "shape of nonlinear_damping refined" in out
    rerun = rerun_rms(run_cli, tmp_path, stem, tmp_path / "forced_levels_off.discovery.json", tr.measured)
    assert rerun == pytest.approx(doc["rmse_final"], rel=1e-3)


def test_a_hysteresis_law_chosen_before_slack_gives_way_to_its_rival(tmp_path, capsys):
    """The eval's forced record with the generator's Iwan friction and slack (seed 30), 10 s at
    100 Hz (the figures here at 200 Hz; at 100 Hz the test prints its own): without slack the two
    hysteresis laws tie (Bouc-Wen 23.1, Iwan 23.2 x noise) and Bouc-Wen may win the step; slack
    then brings it to 6.2 x. rival_law fits the final model again with the Iwan bank in Bouc-Wen's
    place, and the law the generator used wins on the whole record and on the held-out part
    (whichever effect was named last, since the model still leaves something unexplained); where
    the step's own fit of the bank failed, the rival from the data-based estimate is kept only
    where it wins. A model within the unexplained gap whose hysteresis was named last is left alone."""
    from tether.models import parse_model

    stem, gen = _write(tmp_path, "forced_iwan_slack", "forced", {"hysteresis", "slack"}, 30, noise=1e-4,
                       rate=100.0, duration_s=10.0)
    assert gen.meta["hidden"]["laws"]["hysteresis"] == "iwan"
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    lin = D.fit_model(tr, parse_model("linear", "forced"), (), [None], sc)
    iwan = D.fit_model(tr, parse_model("linear+iwan", "forced"), ("hysteresis",), [None], sc)
    bw_spec = parse_model("linear+boucwen", "forced")
    bw = D.fit_model(tr, bw_spec, ("hysteresis",), starts.candidate_starts(lin, bw_spec, sc), sc)
    spec = parse_model("linear+boucwen+slack", "forced")
    cur = D.fit_model(tr, spec, ("hysteresis", "slack"), [dict(bw.params)], sc)
    cur_part = D.fit_model(part, spec, cur.effects, [cur.params], sc_part)
    held = fitting._heldout(tr, spec, cur_part.params, held_out)

    def fit(t, sp, eff, starts, baseline_rms=None, cap_factor=1.0):
        return D.fit_model(t, sp, eff, starts, sc_part if t is part else sc, baseline_rms=baseline_rms)

    lines = []
    new, new_held, rec = rival.rival_law(tr, part, held_out, cur, held, sigma, fit, {"iwan": dict(iwan.params)},
                                     ["slack", "hysteresis"], lines.append)
    with capsys.disabled():
        print(f"\nFIGURE rival law, forced Iwan + slack: Bouc-Wen + slack {cur.rms / sigma:.2f} x noise "
              f"(held-out {held / sigma:.2f}) -> {new.model} {new.rms / sigma:.2f} (held-out {new_held / sigma:.2f})")
    assert rec is not None and rec.accepted and rec.law == "boucwen -> iwan", lines
    assert new.spec.hysteresis == "iwan" and new.spec.slack
    assert new.rms < 0.6 * cur.rms and new_held < 0.7 * held
    # where the Iwan bank's fit failed in the hysteresis step, the rival starts from tether.fit's
    # data-based estimate of its terms; it is kept only where it wins, else the model stays as it
    # was. (It won at 5.70 x noise until 2026-12-06; with the search's fits at SEARCH_RTOL the
    # quick round of its starts stops at 6.46 against Bouc-Wen's 6.11, though one start, carried
    # to convergence, reaches 2.98: docs/speed.md, session 66.)
    est, est_held, est_rec = rival.rival_law(tr, part, held_out, cur, held, sigma, fit, {}, ["slack", "hysteresis"],
                                             lines.append)
    assert est_rec is not None and est_rec.law == "boucwen -> iwan", lines
    with capsys.disabled():
        print(f"FIGURE rival law without the step's fit of the bank: {est.model} {est.rms / sigma:.2f} x noise "
              f"(held-out {est_held / sigma:.2f}), the rival {est_rec.rms_after / sigma:.2f}")
    if est_rec.accepted:
        assert est.spec.hysteresis == "iwan" and est.rms == est_rec.rms_after < cur.rms
    else:
        assert est is cur and est_held == held
    # a model within the unexplained gap (1.3 x noise: gap 0.83 sigma) with no effect named after
    # its hysteresis is left alone
    near = replace(cur, rms=1.3 * sigma)
    same, _, none = rival.rival_law(tr, part, held_out, near, held, sigma, fit, {"iwan": dict(iwan.params)},
                                ["slack", "hysteresis"], lines.append)
    assert same is near and none is None


def test_a_power_law_stiffness_is_followed_by_the_power_term_and_brings_back_the_rival_law(tmp_path, capsys):
    """Eval record 14: a load test of the generator's power-law tether (F = EA e_r (e/e_r)^1.41,
    zero stiffness at zero strain) with its 12-element Iwan friction (seed 15). With the cubic the
    two hysteresis laws tie and Bouc-Wen may win, leaving 2 x noise. The power term, a shape of the
    cubic law, is kept on the whole record and on the held-out part (the search's shape stage, from
    the model its steps end with); with it in place rival_law fits the Iwan bank in Bouc-Wen's
    place (even though hysteresis was named last), and the model comes within 1.5 x the
    generator's noise, its exponent near the generator's. (Until 2026-12-04 the test refined the
    power term beside Bouc-Wen with its own shape terms free, a state the search does not reach
    first: there, with the held-out part split by the load's stretches, the power term gains 14 %
    on the record and loses 3 % on the held-out part.)"""
    from tether.models import parse_model

    stem, gen = _write(tmp_path, "lu_power_iwan", "load_unload", {"nonlinear_stiffness", "hysteresis"}, 15,
                       noise=2e-4, rate=5.0, stiffness_law="power")
    hidden = gen.meta["hidden"]
    assert hidden["laws"]["elastic"] == "power" and hidden["laws"]["hysteresis"] == "iwan"
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    spec = parse_model("cubic+boucwen", "load_unload")
    effects = ("nonlinear_stiffness", "hysteresis")
    cur = D.fit_model(tr, spec, effects, [None], sc)
    iwan = D.fit_model(tr, parse_model("cubic+iwan", "load_unload"), effects, [None], sc)
    held = fitting._heldout(tr, spec, D.fit_model(part, spec, effects, [cur.params], sc_part).params, held_out)

    def fit(t, sp, eff, starts, extra=(), own_thread=False, baseline_rms=None, cap_factor=1.0):
        return D.fit_model(t, sp, eff, starts, sc_part if t is part else sc, extra=extra, baseline_rms=baseline_rms)

    lines = []
    powered, powered_held, refs = refine.refine_shapes(tr, part, held_out, cur, held, sigma, fit, sc, lines.append,
                                                  skip={"hysteresis"})
    assert [r.parameters for r in refs] == [("pow_F", "pow_n")], lines
    assert refs[0].accepted, lines
    if math.isnan(powered_held):     # not asked: the power term more than halves the gap; measured here
        part_fit = fit(part, powered.spec, powered.effects, [powered.params], extra=powered.shape)
        powered_held = fitting._heldout(tr, powered.spec, part_fit.params, held_out)
    assert powered.rms < cur.rms and powered_held <= held
    new, new_held, rec = rival.rival_law(tr, part, held_out, powered, powered_held, sigma, fit, {"iwan": dict(iwan.params)},
                                     list(effects), lines.append, elastic_reshaped=True)
    noise = hidden["noise_sigma_m"]
    with capsys.disabled():
        print(f"\nFIGURE power term, load test power law + Iwan: cubic + Bouc-Wen {cur.rms / noise:.2f}"
              f" x noise (held-out {held / noise:.2f}), with the power term {powered.rms / noise:.2f} "
              f"(held-out {powered_held / noise:.2f}, n = {powered.params['pow_n']:.3f}), the Iwan bank in "
              f"Bouc-Wen's place {new.rms / noise:.2f} (held-out {new_held / noise:.2f}); generator's exponent "
              f"{gen.meta['hidden']['params']['stiff_p']}")
    assert rec is not None and rec.accepted and rec.law == "boucwen -> iwan", lines
    assert new.rms <= 1.5 * noise and new_held <= 1.5 * noise
    assert new.params["pow_F"] > 0 and abs(new.params["pow_n"] - hidden["params"]["stiff_p"]) < 0.25
    # without the power term kept, a hysteresis named last is left alone where the model is within
    # the unexplained gap (1.3 x noise)
    near = replace(cur, rms=1.3 * sigma)
    same, _, none = rival.rival_law(tr, part, held_out, near, held, sigma, fit, {"iwan": dict(iwan.params)},
                                list(effects), lines.append)
    assert same is near and none is None


def test_a_shape_that_halves_the_gap_is_kept_without_asking_the_held_out_part(tmp_path, monkeypatch):
    """A shape of a named law is asked the held-out test only where it does not at least halve the
    gap above the noise (CRITERIA.shape_gap_shrink): a fit of the first part drifts along the law's
    flat directions (the Iwan bank's slip strains on a free vibration: 1 % gained on the part, the
    held-out error 1.3 -> 11.7 x noise), so the test compared drifts. The fits here are the current
    model's own values with a stated error, and every held-out prediction is made worse than the
    model's: a shape that halves the gap is kept and no fit of the first part is asked; one that
    does not is refused on the held-out part."""
    stem, _ = _write(tmp_path, "fv_iwan", "free_vibration", {"hysteresis"}, 27, noise=1e-4, rate=100.0)
    tr, sigma, sc, part, held_out, _ = _record_and_part(stem)
    spec = models.parse_model("linear+iwan", tr.experiment)
    cur = replace(D.fit_model(tr, spec, ("hysteresis",), [None], sc, max_iterations=2), rms=6.0 * sigma)
    held = 9.0 * sigma
    monkeypatch.setattr(refine, "_heldout", lambda *a: 4.0 * held)
    for rms, kept in ((2.9, True), (3.5, False)):
        asked = []

        def fit(t, sp, eff, starts, extra=(), own_thread=False):
            asked.append(t is part)
            return replace(cur, rms=rms * sigma, free=list(cur.free) + list(extra), shape=tuple(extra))

        new, new_held, refs = refine.refine_shapes(tr, part, held_out, cur, held, sigma, fit, sc, lambda s: None)
        assert [r.accepted for r in refs] == [kept], [r.verdict for r in refs]
        assert (new.rms == rms * sigma) is kept and any(asked) is not kept
        assert "held-out test not asked" in refs[0].verdict if kept else "held-out part gets worse" in refs[0].verdict


def test_idle_iwan_elements_restart_where_the_fit_left_them(tmp_path):
    """The Iwan bank's stiffnesses are fitted on a log scale: an element a fit pushed to zero stays
    there. The generator's free vibration with its 12-element Iwan friction (seed 27), fitted from
    tether.fit's estimate, is the reference; the same model fitted from a start with all but two
    elements at 1e-9 of the bank stays far above it. restart_idle_elements brings the idle ones
    back and the refit reaches the reference's error (a second route to the same optimum), with
    most of the bank carrying load; a model without the bank is left alone."""
    from tether.models import IWAN_K, parse_model

    stem, gen = _write(tmp_path, "fv_iwan", "free_vibration", {"hysteresis"}, 27, noise=1e-5, rate=200.0,
                       duration_s=10.0)
    assert gen.meta["hidden"]["laws"]["hysteresis"] == "iwan"
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    spec = parse_model("linear+iwan", "free_vibration")
    ref = D.fit_model(tr, spec, ("hysteresis",), [None], sc)
    k = np.array([ref.params[n] for n in IWAN_K])
    two = set(np.argsort(k)[-2:])
    start = {**ref.params, **{n: 1e-9 * k.sum() for i, n in enumerate(IWAN_K) if i not in two}}
    idle = D.fit_model(tr, spec, ("hysteresis",), [start], sc)
    assert idle.rms > 1.5 * ref.rms, (idle.rms / sigma, ref.rms / sigma)

    def fit(t, sp, eff, starts, extra=()):
        return D.fit_model(t, sp, eff, starts, sc_part if t is part else sc, extra=extra)

    lines = []
    new, held, rec = rival.restart_idle_elements(tr, part, held_out, idle, float("inf"), sigma, fit, lines.append)
    assert rec is not None and rec.accepted and rec.restart, lines
    assert new.rms <= 1.05 * ref.rms, (new.rms / sigma, ref.rms / sigma)
    live = [n for n in IWAN_K if new.params[n] >= rival.IWAN_IDLE_SHARE * k.sum()]
    assert len(live) >= 5, new.params
    assert math.isfinite(held)
    bw_spec = parse_model("linear+boucwen", "free_vibration")
    bw = D.fit_model(tr, bw_spec, ("hysteresis",), [None], sc)
    same, _, none = rival.restart_idle_elements(tr, part, held_out, bw, float("inf"), sigma, fit, lines.append)
    assert same is bw and none is None


def test_idle_elements_move_into_the_widest_gaps_of_the_slip_strains():
    """Live slip strains 1, 2, 4, 8 and 9 (x 1e-3) leave gaps of 1, 1, 2, 4 and 1 above 0: the first
    idle element splits 4..8 at 6; then 2..4, 4..6 and 6..8 tie and the lowest, 2..4, is split at
    3; then 4..6 at 5. The idle elements take the new strains in order of strain, the live ones
    keep theirs, and a bank with nothing idle moves nothing."""
    from tether.models import IWAN_EPS

    eps = np.array([1e-4, 1e-3, 2e-4, 2e-3, 3e-4, 4e-3, 8e-3, 9e-3])
    idle = np.array([True, False, True, False, True, False, False, False])
    moved = rival.idle_slip_strains_moved(eps, idle)
    assert sorted(moved) == [IWAN_EPS[0], IWAN_EPS[2], IWAN_EPS[4]]
    assert [moved[IWAN_EPS[i]] for i in (0, 2, 4)] == pytest.approx([3e-3, 5e-3, 6e-3], rel=1e-12)
    assert rival.idle_slip_strains_moved(eps, np.zeros(8, bool)) == {}


def test_idle_iwan_elements_below_the_live_ones_move_into_their_gaps(tmp_path):
    """The generator's forced record with Iwan friction and slack (seed 30, 10 s at 100 Hz), the
    Iwan bank fitted from tether.fit's estimate: the lowest elements of the geometric grid
    (slip strains 1.4e-4..8e-4) go idle and the bank stays at 5.2 x noise. Restarted where they sat
    they go idle again (the fit from that start alone gains nothing); moved into the gaps between
    the live elements' slip strains they carry load, and the restart brings the same model within
    1.5 x noise (measured 1.43 at 200 Hz), the moved start winning."""
    from tether.models import IWAN_EPS, IWAN_K, parse_model

    stem, gen = _write(tmp_path, "forced_iwan_slack", "forced", {"hysteresis", "slack"}, 30, noise=1e-4,
                       rate=100.0, duration_s=10.0)
    assert gen.meta["hidden"]["laws"]["hysteresis"] == "iwan"
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    spec = parse_model("linear+iwan+slack", "forced")
    est = D.fit_model(tr, spec, ("hysteresis", "slack"), [None], sc)
    k = np.array([est.params[n] for n in IWAN_K])
    eps = np.array([est.params[n] for n in IWAN_EPS])
    idle = k < rival.IWAN_IDLE_SHARE * k.sum()
    assert idle.sum() >= 3 and eps[idle].max() < eps[~idle].max(), (k, eps)
    assert est.rms > 3.0 * sigma, est.rms / sigma

    def fit(t, sp, eff, starts, extra=()):
        return D.fit_model(t, sp, eff, starts, sc_part if t is part else sc, extra=extra)

    lines = []
    new, held, rec = rival.restart_idle_elements(tr, part, held_out, est, float("inf"), sigma, fit, lines.append)
    assert rec is not None and rec.accepted and "moved into the widest gaps" in rec.verdict, lines
    assert new.rms < 1.5 * sigma, new.rms / sigma
    assert math.isfinite(held)
    k2 = np.where(idle, rival.IWAN_RESTART_SHARE * k.sum(), k)
    k2 *= k.sum() / k2.sum()
    in_place = D.fit_model(tr, spec, ("hysteresis", "slack"), [{**est.params, **dict(zip(IWAN_K, map(float, k2)))}],
                           sc)
    assert in_place.rms > 2.0 * new.rms, (in_place.rms / sigma, new.rms / sigma)


def test_a_bank_with_an_element_a_fit_switched_off_is_a_start_the_next_fit_accepts(tmp_path):
    """A fit can switch an Iwan element off: its stiffness and slip strain both at 0, which the model
    accepts. Handed on as a start (a held-out test of the fit, a refit), the stiffness is log-scaled
    and cannot start at 0: it is left to tether.fit's estimate, and so is its slip strain, for a
    positive stiffness with a slip strain of 0 is no model (a tuning campaign's finer bank, 3.82 ->
    2.20 x noise, was refused so: "iw_eps9 = 0 with iw_k9 = 1e-06 N: expected a positive slip
    strain", its held-out error infinite)."""
    from tether.models import IWAN_EPS, IWAN_K, parse_model

    stem, _ = _write(tmp_path, "fv_iwan", "free_vibration", {"hysteresis"}, 27, noise=1e-5, rate=200.0,
                     duration_s=4.0)
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    spec = parse_model("linear+iwan", "free_vibration")
    est = D.fit_model(tr, spec, ("hysteresis",), [None], sc)
    bank = [n for n in IWAN_K if n in est.free]
    start = {**est.params, **rival.finer_banks(est.params, bank)[0]}
    start.update({IWAN_K[8]: 0.0, IWAN_EPS[8]: 0.0})                  # element 9 switched off
    refit = D.fit_model(tr, spec, ("hysteresis",), [start], sc, extra=IWAN_K + IWAN_EPS)
    assert refit.ok, refit.message
    assert refit.rms < 1.5 * est.rms, (refit.rms / sigma, est.rms / sigma)


def test_a_finer_iwan_bank_follows_friction_spread_over_more_elements(tmp_path):
    """The generator's free vibration (seed 27, noise 1e-5 m) has twelve Jenkins elements; the
    search fits eight. From tether.fit's estimate and the idle elements' restart the bank of eight
    stays above the noise (measured 1.45-1.48 x); finer_bank splits it into sixteen and fits every
    stiffness and slip strain, which takes the model near the noise, as the generator's own twelve
    elements would. Where the fit of sixteen stopped depended on the last bits of the BLAS kernel
    (1.05 x, 1.21 x and 9.95 x on three machines while its fits ran through the engine's horizon
    stages; on the whole record at once, 1.03 x with Haswell's kernel and with SkylakeX's:
    docs/reproducibility.md), so the bound keeps a margin, and the gap above the noise must shrink
    by a quarter at least. A bank already using every element is left alone."""
    from tether.models import IWAN_EPS, IWAN_K, parse_model

    stem, gen = _write(tmp_path, "fv_iwan", "free_vibration", {"hysteresis"}, 27, noise=1e-5, rate=200.0,
                       duration_s=10.0)
    assert gen.meta["hidden"]["params"]["hyst_n"] == 12
    tr, sigma, sc, part, held_out, sc_part = _record_and_part(stem)
    spec = parse_model("linear+iwan", "free_vibration")

    def fit(t, sp, eff, starts, extra=(), cap_factor=1.0, **engine):      # no work cap here to scale
        return D.fit_model(t, sp, eff, starts, sc_part if t is part else sc, extra=extra, **engine)

    est = D.fit_model(tr, spec, ("hysteresis",), [None], sc)
    held = fitting._heldout(tr, spec, fit(part, spec, est.effects, [est.params]).params, held_out)
    eight, held8, _ = rival.restart_idle_elements(tr, part, held_out, est, held, sigma, fit, lambda s: None)
    assert sum(n in eight.free for n in IWAN_K) == 8
    assert eight.rms > 1.3 * sigma, eight.rms / sigma
    lines = []
    new, new_held, rec = rival.finer_bank(tr, part, held_out, eight, held8, sigma, fit, lines.append)
    assert rec is not None and rec.accepted and rec.finer, lines
    assert all(n in new.free for n in IWAN_K + IWAN_EPS)

    def gap(rms):                                   # above the noise, in sigma
        return math.sqrt(max(rms ** 2 - sigma ** 2, 0.0)) / sigma

    assert new.rms < 1.3 * sigma and gap(new.rms) < 0.75 * gap(eight.rms), (new.rms / sigma, eight.rms / sigma)
    live = [n for n in IWAN_K if new.params[n] >= rival.IWAN_IDLE_SHARE * sum(new.params[k] for k in IWAN_K)]
    assert len(live) > 8, new.params
    # (judged against half the noise, so that it is not left alone for being within the noise)
    same, _, none = rival.finer_bank(tr, part, held_out, new, new_held, 0.5 * sigma, fit, lines.append)
    assert same is new and none is None


def test_the_report_names_what_each_last_stage_did():
    """The report's table of the last stages labels a rival law, a restart and a finer bank, and
    shows a shape group's terms alone."""
    from tether.discover_report import _refinement_terms

    row = {"parameters": ["iw_k1", "iw_k3"], "law": "", "restart": False, "finer": False}
    assert _refinement_terms(row) == "iw_k1 iw_k3"
    assert _refinement_terms({**row, "law": "boucwen -> iwan"}) == "law boucwen -> iwan: iw_k1 iw_k3"
    assert _refinement_terms({**row, "restart": True}) == "idle elements restarted: iw_k1 iw_k3"
    assert _refinement_terms({**row, "finer": True}).startswith("finer bank, 2 terms added: ")


def test_a_slack_fit_that_never_goes_slack_is_kept_as_a_refit_of_the_model(tmp_path):
    """Slack adds no parameter: a slack candidate whose tether never goes slack is the current model
    with other values. Where its fit is the better one, _refit_without_slack returns it as the
    current model (slack off, the same prediction); where slack acts, or the fit is no better,
    nothing. The fits here are set by hand on the generator's free vibration without slack (the
    current model's EA 3 % off) and with it (the truth's EA: its tether goes slack)."""
    from tether.models import parse_model

    def model_fit(tr, spec, params):
        y = D.predict(tr, spec, params)
        rms = float(np.sqrt(np.mean((y - tr.measured) ** 2)))
        return D.ModelFit(spec=spec.for_experiment(tr.experiment), effects=tuple(spec.effects), params=params,
                          free=["EA", "c0"], rms=rms, predicted=y)

    def slack_result(fm):
        return D.CandidateResult(effect="slack", model=fm.model, added_parameters=0, rms=fm.rms,
                                 heldout_rms=float("nan"), bic_change=0.0, signature=0.0, signature_text="", fit=fm)

    stem, gen = _write(tmp_path, "fv", "free_vibration", set(), 5, noise=1e-5, rate=200.0, duration_s=5.0)
    tr, sigma, *_ = _record_and_part(stem)
    d = gen.meta["hidden"]["derived"]
    truth = {"EA": d["k_lin_N_m"] * tr.length_m, "c0": d["c0_N_s_m"]}
    lin, with_slack = parse_model("linear", "free_vibration"), parse_model("linear+slack", "free_vibration")
    cur = model_fit(tr, lin, {**truth, "EA": 1.03 * truth["EA"]})
    cand = model_fit(tr, with_slack, dict(truth))
    assert cand.rms < 2.0 * sigma < cur.rms
    refit = search._refit_without_slack(tr, cur, [slack_result(cand)], sigma)
    assert refit is not None and refit.spec == cur.spec and not refit.spec.slack
    assert refit.params["EA"] == truth["EA"] and refit.rms == pytest.approx(cand.rms, rel=1e-6)
    # no better than the current model: nothing
    assert search._refit_without_slack(tr, cand, [slack_result(model_fit(tr, with_slack, cur.params))], sigma) is None
    # a tether that goes slack: the slack fit is another model
    stem2, gen2 = _write(tmp_path, "fv_slack", "free_vibration", {"slack"}, 5, noise=1e-5, rate=200.0,
                         duration_s=5.0)
    tr2, sigma2, *_ = _record_and_part(stem2)
    d2 = gen2.meta["hidden"]["derived"]
    truth2 = {"EA": d2["k_lin_N_m"] * tr2.length_m, "c0": d2["c0_N_s_m"]}
    cur2 = model_fit(tr2, lin, {**truth2, "EA": 1.03 * truth2["EA"]})
    cand2 = model_fit(tr2, with_slack, dict(truth2))
    assert cand2.rms < cur2.rms
    assert search._refit_without_slack(tr2, cur2, [slack_result(cand2)], sigma2) is None


def _table_named(doc: dict, step: dict, progress: str) -> bool:
    """The damping was named with the table of c(x): its step's winner was the table candidate, or the
    table was kept as the damping law's shape afterwards (a refinement of nonlinear_damping with its
    knots), and the final parameters hold it."""
    in_step = "c_table_1" in step["model_after"] and "(table of c(x))" in progress
    as_shape = any(r["effect"] == "nonlinear_damping" and r["accepted"] and "c_table_1" in r["parameters"]
                   for r in doc["refinements"])
    return (in_step or as_shape) and doc["parameters"].get("c_table_dx", 0.0) > 0


def test_a_polynomial_damping_refused_on_the_held_out_part_gives_way_to_the_table(tmp_path, run_cli):
    """A forced sweep with Iwan hysteresis and a Gaussian c(x) that levels off (the generator's
    laws; at 100 Hz, docs/test-suite-time.md). Once a hysteresis law is in, the polynomial c(x)
    beside it closed much of the whole record's gap but, fitted to the first 60 %, its x^2 term ran
    on past the displacements seen there and predicted the rest too poorly: the damping went unnamed
    (2.3 x noise). The table of c(x), whose unseen knots the part fit holds, is fitted and tested in
    its place, in the step or as the damping law's shape afterwards; both hidden effects are named,
    the model ends within 1.5 x the generator's noise and its JSON reruns through the FMU at its
    error (docs/discovery.md has the figures by date). Since 2026-12-05 (e324839) Bouc-Wen wins the
    first step and the polynomial passes in the second (held-out 2.30 x against 3.64 x): the table
    comes in as its shape, at 1.30 x. Until 2026-12-06 a second test ran the same record from
    --start linear+boucwen; it had come to take the same path (docs/test-suite-time.md)."""
    stem, tr = _write(tmp_path, "forced_hyst_gauss", "forced", {"hysteresis", "nonlinear_damping"}, 1011,
                      rate=100.0, duration_s=10.0, damping_law="gauss")
    hidden = tr.meta["hidden"]
    assert hidden["laws"]["damping"] == "gauss" and hidden["laws"]["hysteresis"] == "iwan"
    assert set(tr.revealed) == {"hysteresis", "nonlinear_damping"}
    doc, out, progress = _discover_cli(run_cli, stem, tmp_path)
    sigma = hidden["noise_sigma_m"]
    assert sorted(doc["added_effects"]) == ["hysteresis", "nonlinear_damping"], doc["added_effects"]
    step = next(s for s in doc["steps"] if s["effect"] == "nonlinear_damping")
    assert _table_named(doc, step, progress), step["model_after"]
    assert doc["parameters"]["c1"] == 0.0
    if "c_table_1" in step["model_after"]:       # the table in the step: the polynomial refused held out
        poly = [c for c in step["candidates"] if c["effect"] == "nonlinear_damping" and "c_table" not in c["model"]]
        assert poly and not poly[0]["accepted"] and "held-out" in poly[0]["verdict"], poly
    print(f"FIGURE Iwan + Gaussian damping from the linear start: rmse_final {doc['rmse_final'] / sigma:.2f} x noise")
    assert doc["rmse_final"] <= 1.5 * sigma
    if "c_table_1" in step["model_after"]:
        # the refined model misses by less than the noise itself (gap below sigma): no second search
        assert "searching again" not in progress, doc["rmse_final"] / sigma
    rerun = rerun_rms(run_cli, tmp_path, stem, tmp_path / "forced_hyst_gauss.discovery.json", tr.measured)
    assert rerun == pytest.approx(doc["rmse_final"], rel=1e-3)


def test_a_start_model_with_an_effect_names_only_what_it_lacks(tmp_path, run_cli):
    """--start names the model the search starts from: a free vibration released above its slack
    point, started from linear+slack, is at its noise from the start (measured 0.94 x) and names
    nothing; the linear model misses the same record far above its noise (measured: tether fit
    1,468 x, the linear start of a discovery 1,208 x; that discovery names slack, 0.94 x)."""
    from tether.fit import fit_traces

    stem, tr = _write(tmp_path, "fv_slack", "free_vibration", {"slack"}, 5, noise=1e-5, rate=200.0, duration_s=5.0)
    assert tr.meta["hidden"]["derived"]["slack_events"] > 0
    doc, out, _ = _discover_cli(run_cli, stem, tmp_path, "--start", "linear+slack")
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    assert doc["start_model"] == "linear+slack"
    assert doc["added_effects"] == [] and doc["rmse_initial"] == doc["rmse_final"] <= 1.5 * sigma, doc["rmse_final"]
    assert fit_traces([read_trace(stem)], "linear", n_starts=4).rms > 10 * sigma


@pytest.mark.parametrize("effects, acts", [((), False), (("slack",), True)])
def test_slack_is_credited_only_where_it_acts(tmp_path, effects, acts):
    """Slack adds no parameter, so a refit with it can win on the optimizer's luck alone. With the
    generator's own stiffness and damping, a free vibration that never goes slack simulates the
    same with slack on and off (the tether is stretched throughout): slack must be refused there,
    and kept on a release from above the slack point (the generator's slack traces)."""
    from tether.models import parse_model

    stem, tr = _write(tmp_path, "fv", "free_vibration", effects, 5, noise=1e-4, rate=200.0)
    trace = read_trace(stem)
    derived = tr.meta["hidden"]["derived"]
    params = {"EA": derived["k_lin_N_m"] * trace.length_m, "c0": derived["c0_N_s_m"]}
    with_slack = parse_model("linear+slack").for_experiment(trace.experiment)
    fm = D.ModelFit(spec=with_slack, effects=("slack",), params=params, free=["EA", "c0"], rms=1e-4,
                    predicted=D.predict(trace, with_slack, params))
    ok, verdict = judge._slack_acts(trace, parse_model("linear"), fm, 1e-4, "earns")
    print(f"FIGURE slack {'released above the slack point' if acts else 'never slack'}: {ok}, {verdict}")
    assert ok is acts
    assert verdict == "earns" if acts else "slack never acts" in verdict


@pytest.mark.parametrize("terms, loops", [({"bw_beta": 1e-3, "bw_gamma": -1.3}, False),
                                           ({"bw_gamma": -1.0, "bw_b3": 0.5, "bw_b5": 0.3, "bw_b6": 0.2}, False),
                                           ({"bw_beta": 15.0, "bw_gamma": 5.0}, True),
                                           ({"bw_b4": 2.0, "bw_gamma": 10.0}, True),
                                           ({"bw_b2": 5.0, "bw_gamma": 10.0}, True)])
def test_hysteresis_is_credited_only_where_its_loops_open(tmp_path, terms, loops):
    """Bouc-Wen's rate dz/dt = xdot (A - |z|^n psi): where psi's direction-dependent terms (beta on
    sgn(xdot z), b2 on sgn(x xdot), b4 on sgn(xdot)) vanish, dz/dx depends on z alone, z is a
    function of x and the force an elastic curve with no loop. A forced record simulated with such a
    force (a stiffening curve: gamma < 0, or the direction-free b3, b5, b6) must not credit
    hysteresis, however well the law fits; one whose force opens loops through any of the three
    terms must."""
    from tether.models import parse_model

    stem, tr = _write(tmp_path, "forced", "forced", (), 7, noise=1e-5, rate=200.0)
    trace = read_trace(stem)
    derived = tr.meta["hidden"]["derived"]
    spec = parse_model("linear+boucwen").for_experiment(trace.experiment)
    params = {"EA": derived["k_lin_N_m"] * trace.length_m, "c0": derived["c0_N_s_m"], "bw_A": 60.0,
              "bw_beta": 0.0, "bw_gamma": 0.0, **terms}
    truth = D.predict(trace, spec, params)
    trace = replace(trace, measured=truth + np.random.default_rng(7).normal(0.0, 1e-5, truth.size))
    fm = D.ModelFit(spec=spec, effects=("hysteresis",), params=params, rms=float(np.sqrt(np.mean(
        (truth - trace.measured) ** 2))), free=["EA", "c0", "bw_A", "bw_beta", "bw_gamma"], predicted=truth)
    ok, verdict = judge.acts_as_itself(trace, parse_model("linear"), fm, 1e-5, "hysteresis", "earns")
    print(f"FIGURE Bouc-Wen {terms}: credited {ok}: {verdict}")
    assert ok is loops
    assert verdict == "earns" if loops else "loops do not earn their place" in verdict


def test_a_part_fit_holds_the_table_knots_beyond_its_reach():
    """The first part of a record reaching 0.05 m cannot see the knots of a table 0.02 m apart past
    0.05 m (knots 3-6); those stay at the whole record's values in the part's fit."""

    class _Part:
        rig = "payload"
        measured = 0.05 * np.sin(np.linspace(0.0, 20.0, 500))

    knots = tuple(f"c_table_{j}" for j in range(1, 7))
    assert refine._knots_unseen(_Part, knots + ("bw_n",), [{"c_table_dx": 0.02}]) == knots[2:]
    assert refine._knots_unseen(_Part, ("bw_n",), [{"c_table_dx": 0.02}]) == ()


def test_the_json_and_the_report_asked_for_are_written_and_agree(tmp_path, run_cli):
    """`tether discover STEM --json OUT --report DIR` on a free vibration with a hidden nonlinear
    stiffness: the effect named, the JSON with the contract's fields and its steps, the report
    page with its plots, and the page's figures the JSON's. (The bundled record's whole story, its
    steps and its JSON as a --params file, is test_demo's: the demo discovers that record.)"""
    stem, tr = _write(tmp_path, "t", "free_vibration", {"nonlinear_stiffness"}, 3, noise=1e-4, rate=100.0,
                      duration_s=5.0)
    report = tmp_path / "report"
    doc, out, err = _discover_cli(run_cli, stem, tmp_path, "--report", report)
    assert doc["added_effects"] == ["nonlinear_stiffness"], doc["added_effects"]
    for f in FIELDS:
        assert f in doc, f
    for s in doc["steps"]:
        for f in STEP_FIELDS:
            assert f in s, f
    assert doc["rmse_final"] <= 1.5 * tr.meta["hidden"]["noise_sigma_m"] < doc["rmse_initial"]
    assert "added nonlinear_stiffness" in err and "discovered: nonlinear_stiffness" in out
    page = (report / "index.html").read_text()
    for img in ("models.png", "gap.png"):
        assert img in page and (report / img).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"{doc['rmse_final'] / doc['noise_estimate']:.2f}" in page


# ---------------------------------------------------------------------------------------------
# bad input: a clear error, exit 2, nothing written
def test_missing_trace_and_bad_outputs_exit_2_and_write_nothing(tmp_path, run_cli):
    out = tmp_path / "d.json"
    status, _, err = run_cli("discover", tmp_path / "nope", "--json", out)
    assert status == 2 and "nope" in err and not out.exists()
    stem, _ = _write(tmp_path, "t", "free_vibration", set(), 1, noise=1e-4, rate=100.0)
    status, _, err = run_cli("discover", stem, "--json", tmp_path)
    assert status == 2 and "--json" in err
    status, _, err = run_cli("discover", stem, "--json", out, "--start", "linear+wobble")
    assert status == 2 and "wobble" in err and not out.exists()
    for bad in ("0", "-5", "nan", "soon"):
        status, _, err = run_cli("discover", stem, "--json", out, "--budget", bad)
        assert status == 2 and "--budget" in err and bad in err and not out.exists(), (bad, err)


def test_a_spent_budget_adds_nothing_unjudged_and_says_so(tmp_path, run_cli):
    # a hidden effect the linear baseline misses by far (>= 4.7 x noise on the suite); with a
    # budget spent before the first step the run still ends in order: the baseline is the
    # result, nothing is named, and the account and the record say why
    stem, tr = _write(tmp_path, "t", "free_vibration", {"nonlinear_stiffness"}, 5, noise=1e-4, rate=100.0)
    doc, stdout, _ = _discover_cli(run_cli, stem, tmp_path, "--budget", "1e-6")
    assert doc["added_effects"] == [] and doc["final_model"] == "linear"
    assert doc["rmse_final"] == doc["rmse_initial"] > 3 * doc["noise_estimate"]
    assert "time budget" in doc["stop_reason"] and "--budget" in doc["stop_reason"]
    assert "time budget" in stdout


def test_a_step_cut_short_by_the_budget_is_not_taken(tmp_path, monkeypatch):
    # a clock that jumps past the budget while the first candidate is fitted: that step is not
    # judged to the end, so even the effect that would win it (the hidden one) is not added
    import time as real_time
    import types

    stem, _ = _write(tmp_path, "t", "free_vibration", {"nonlinear_stiffness"}, 5, noise=1e-4, rate=100.0)
    clock = {"offset": 0.0}
    shifted = types.SimpleNamespace(perf_counter=lambda: real_time.perf_counter() + clock["offset"],
                                    process_time=real_time.process_time)
    # the clocks of the search (its budget) and of the fits (their deadline), where they are read
    monkeypatch.setattr(search, "time", shifted)
    monkeypatch.setattr(fitting, "time", shifted)
    original = search.fit_model

    def fit_model(trace, spec, effects, *a, **kw):
        r = original(trace, spec, effects, *a, **kw)
        if "nonlinear_stiffness" in effects:
            clock["offset"] += 1e4
        return r

    monkeypatch.setattr(search, "fit_model", fit_model)
    d = D.discover(read_trace(stem), budget=600.0)
    assert d.added_effects == [] and d.final.model == "linear"
    assert "while the candidates of step 1" in d.stop_reason
    assert d.steps[0].candidates and all(not c.accepted and "time budget" in c.verdict for c in d.steps[0].candidates)
    # the same record with time enough names it (the cut above is the budget's doing)
    monkeypatch.setattr(search, "fit_model", original)
    clock["offset"] = 0.0
    assert D.discover(read_trace(stem), budget=600.0).added_effects == ["nonlinear_stiffness"]


def test_noise_free_record_is_refused_with_a_reason(tmp_path, run_cli, write_trace):
    # a payload at rest at its balance, recorded exactly: no noise, so no scale to judge a gap by
    t = np.arange(0.0, 5.0, 0.01)
    stem = write_trace("still", {"format": "tether-trace/1", "experiment": "free_vibration",
                                 "tether": {"length_m": 10.0}, "payload_mass_kg": 3.0},
                       {"time": t, "displacement": np.zeros_like(t)})
    out = tmp_path / "d.json"
    status, _, err = run_cli("discover", stem, "--json", out)
    assert status == 1 and "no noise" in err and "still" in err and not out.exists()


def test_the_creep_start_finds_the_kelvin_cells_of_a_record():
    """A creep record of three Kelvin cells whose retardation times lie on the start's grid, strain
    by the closed-form response to a tension linear between samples (not the start's own recursion):
    the equation-error start picks those three times and their compliances, and the stiffness."""
    t = np.arange(0.0, 36000.0 + 1.0, 10.0)
    T = np.where(t < 10.0, 0.0, np.where(t < 14400.0, 100.0, 5.0))
    EA, L = 3500.0, 12.0
    hold = float(np.max(np.diff(t[np.r_[0, np.flatnonzero(np.diff(T)) + 1, len(t) - 1]])))
    grid = starts.retardation_grid(t, hold)
    taus, J = grid[[3, 7, 11]], np.array([1e-6, 3e-6, 5e-6])
    eps = T / EA
    for tau, j in zip(taus, J):
        e = np.zeros_like(t)
        for i in range(1, len(t)):
            h = t[i] - t[i - 1]
            a, b = j * T[i - 1], j * (T[i] - T[i - 1]) / h      # J T(s) = a + b s over the interval
            e[i] = a + b * (h - tau) + (e[i - 1] - a + b * tau) * math.exp(-h / tau)
        eps = eps + e

    class _Creep:
        experiment = "creep"
        time, input, measured, length_m = t, T, eps * L, L

    class _Sc:
        ea = 3000.0

    _Sc.hold = hold
    from tether.models import parse_model

    st = starts._retardation_times_start(_Creep, parse_model("linear+creep"), {"EA": 3000.0}, _Sc)
    assert [st[f"creep_tau{k}"] for k in (1, 2, 3)] == pytest.approx(list(taus), rel=1e-12)
    assert [st[f"creep_J{k}"] for k in (1, 2, 3)] == pytest.approx(list(J), rel=5e-3)
    assert st["EA"] == pytest.approx(EA, rel=1e-4)


def test_a_named_slack_is_shown_with_the_balance_of_the_slack_model(tmp_path):
    """Where the model before the step puts the balance so low that the record never seems to go
    slack (a law bent to mimic the slack), the evidence of a slack named next does not stop at
    "nothing shows a slack tether": it adds what the slack model sees, the share of samples below
    zero elongation counted here from the generator's own balance stretch and the record."""
    from tether.models import parse_model

    stem, gen = _write(tmp_path, "fv_slack", "free_vibration", {"slack"}, 17, noise=1e-5, rate=200.0)
    ub = gen.meta["hidden"]["derived"]["balance_elongation_m"]
    sigma = gen.meta["hidden"]["noise_sigma_m"]
    tr = read_trace(stem)
    n = len(tr.time)
    m, g, L = tr.payload_mass_kg, tr.gravity_m_s2, tr.length_m

    def model(spec, ea):
        return D.ModelFit(spec=parse_model(spec, "free_vibration"), effects=(), params={"EA": ea, "c0": 1.0},
                          free=["EA", "c0"], rms=1.0, predicted=np.zeros(n))

    # a stiffness so low that the balance lies below every measured point
    soft = model("linear", 1.01 * m * g * L / (ub - float(np.min(tr.measured))))
    sig = D.signatures(tr, soft, sigma, D.regimes(tr, soft))["slack"]
    assert sig["score"] == 0.0 and "the record never goes below it" in sig["text"]
    ea = m * g * L / ub
    win = D.CandidateResult(effect="slack", model="linear+slack", added_parameters=0, rms=1.0, heldout_rms=1.0,
                            bic_change=-1.0, signature=0.0, signature_text=sig["text"], fit=model("linear+slack", ea))
    text = document._slack_seen_by(tr, win)
    share = 100.0 * np.mean(np.asarray(tr.measured) + ub < 0)
    assert share > 1.0
    assert text.startswith(sig["text"])
    assert f"balance stretch {ub:.4g} m" in text and f"below zero in {share:.1f} % of the record" in text
    # a slack the model before the step already showed keeps its own signature
    win.signature, win.signature_text = 0.3, "shown before"
    assert document._slack_seen_by(tr, win) == "shown before"


# ---------------------------------------------------------------------------------------------
# a long record searched on every k-th sample, its final model fitted to the whole record
def _sine_forced(write_trace, name, f_hz, n, periodic=None, rate=1000.0, interpolation=None):
    """A forced record with a sinusoidal force of f_hz sampled at ``rate``; the displacement a
    sinusoid with 1e-5 m of noise."""
    t = np.arange(n) / rate
    x = 1e-3 * np.sin(2 * np.pi * f_hz * t - 0.3) + 1e-5 * np.random.default_rng(3).standard_normal(n)
    meta = write_trace.meta("forced", **({"periodic_samples": periodic} if periodic else {}),
                            **({"input_interpolation": interpolation} if interpolation else {}))
    return read_trace(write_trace(name, meta, {"time": t, "force": 10 * np.sin(2 * np.pi * f_hz * t),
                                               "displacement": x}))


def test_a_long_record_is_thinned_only_where_its_input_is_rebuilt_within_the_noise(write_trace):
    slow = _sine_forced(write_trace, "slow", 1.0, 20000)
    # a cubic spline through every 5th sample (200 Hz) of a 1 Hz sine misses it by ~(wh)^4/384,
    # 3e-9 of its amplitude: far below the noise carried to the force (1e-5 m of 1e-3 m)
    assert D.thinned_input_miss(slow, 5) < 1e-4 * 1e-5
    assert D.search_thinning(slow, 1e-5) == 5               # 20000 samples -> 4000
    # 120 Hz: at 200 Hz or 500 Hz the spline cannot follow it (wh = 3.8 and 1.5 rad): every sample
    fast = _sine_forced(write_trace, "fast", 120.0, 20000)
    assert D.thinned_input_miss(fast, 2) > 1e-5
    assert D.search_thinning(fast, 1e-5) == 1
    # an 8 Hz sine the record says to join by straight lines: through every 5th sample they miss it
    # by (wh)^2 / 8 = 0.8 % of its amplitude, above the noise carried to the force; the thinned
    # record rebuilds its input with a cubic spline, (wh)^4 / 384 = 1e-5 of it
    lines = _sine_forced(write_trace, "lines", 8.0, 20000, interpolation="linear")
    assert D.thinned_input_miss(lines, 5, "linear") > 0.05 * 1e-5 > D.thinned_input_miss(lines, 5, "spline")
    assert D.search_thinning(lines, 1e-5) == 5
    assert D.thinned(lines, 5).meta["input_interpolation"] == "spline"
    assert lines.meta["input_interpolation"] == "linear"
    # a periodic record: k divides the period, and the thinned record keeps whole periods
    per = _sine_forced(write_trace, "per", 1.0, 12000, periodic=6000, rate=6000.0)
    assert D.search_thinning(per, 1e-5) == 2
    th = D.thinned(per, 2)
    assert th.periodic_samples == 3000 and len(th.time) == 6000 and th.time[1] == per.time[2]
    odd = _sine_forced(write_trace, "odd", 1.0, 2 * 4001, periodic=4001, rate=4001.0)
    assert D.search_thinning(odd, 1e-5) == 1                 # 2 does not divide 4001
    # a record that is not periodic keeps its last sample
    th = D.thinned(_sine_forced(write_trace, "end", 1.0, 10001), 3)
    assert th.time[-1] == 10.0 and th.time[-2] == 9.999 and len(th.time) == 3335


def test_a_long_record_searched_thinned_reports_the_whole_records_errors(tmp_path, run_cli):
    stem, tr = _write(tmp_path, "forced_long", "forced", {"nonlinear_stiffness"}, 5, noise=1e-4, rate=1000.0,
                      duration_s=9.0)
    doc, out, _ = _discover_cli(run_cli, stem, tmp_path, "--report", tmp_path / "report")
    assert doc["samples"] == 9001 and doc["searched_every"] == 3, (doc["samples"], doc["searched_every"])
    assert "searched on every 3rd sample of 9001" in out
    assert "the search ran on every 3rd sample of 9001" in (tmp_path / "report" / "index.html").read_text()
    assert doc["added_effects"] == ["nonlinear_stiffness"]
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    assert doc["rmse_final"] <= 1.5 * sigma
    # the errors reported are the whole record's: the FMU reruns the final model on all 9001 samples
    # (OUT.json as --params: the model's parameters and, for its own record, the nuisance values)
    measured = read_trace(stem).measured
    rerun = rerun_rms(run_cli, tmp_path, stem, tmp_path / "forced_long.discovery.json", measured)
    assert rerun == pytest.approx(doc["rmse_final"], rel=1e-6)
    assert doc["steps"][0]["rmse_before"] == doc["rmse_initial"]
    # and the start model's values from every third sample fit the whole record as well as its own
    # fit to the whole record does
    whole = read_trace(stem)
    nz = D.nuisance_parameters(whole)
    lin = D.fit_model(whole, models.parse_model("linear", "forced"), (), [nuisance_start(whole, nz), None],
                      scales._scales(whole), nuisance=nz)
    assert 0.999 * lin.rms <= doc["rmse_initial"] <= 1.01 * lin.rms


def test_an_effect_added_beside_another_starts_from_the_data_too(tmp_path):
    """A free vibration with Iwan friction and a Gaussian c(x) (seed 42, 200 Hz, 10 s): the Iwan
    bank fitted alone dissipates what the damping does, at 30 x noise. Warm starts from it keep the
    bank there and the damping candidate gains nothing (29.3-31.4 x noise from each); the
    equation-error estimate of the whole model, among the candidate's starts since the base has an
    effect, brings the candidate below 10 x."""
    from tether.models import parse_model

    stem, gen = _write(tmp_path, "fv_iwan_gauss", "free_vibration", {"hysteresis", "nonlinear_damping"}, 42,
                       rate=200.0, duration_s=10.0, damping_law="gauss")
    assert gen.meta["hidden"]["laws"]["hysteresis"] == "iwan"
    tr = read_trace(stem)
    sc = scales._scales(tr)
    nz = D.nuisance_parameters(tr)
    base = D.fit_model(tr, parse_model("linear+iwan", tr.experiment), ("hysteresis",), [None], sc, nuisance=nz)
    spec = parse_model("linear+iwan+nonlinear_damping", tr.experiment)
    begins = starts.candidate_starts(base, spec, sc, tr)
    assert None in begins
    new = D.fit_model(tr, spec, ("hysteresis", "nonlinear_damping"), begins, sc, nuisance=nz)
    assert new.rms < 0.5 * base.rms, (new.rms / base.rms, base.rms / gen.meta["hidden"]["noise_sigma_m"])


def test_the_iwan_candidate_first_starts_next_to_the_model_it_extends(tmp_path):
    """A forced record with Iwan friction and slack, cut from a longer run, before slack is named:
    the Iwan candidate's first start is a weak bank beside the base model's own values, which
    simulated misses the record by little more than the base model does (the equation-error
    estimate, its only start before, reads the slack as friction: on a tuning record its fit ended
    at 348 x noise against the linear model's 79 x; docs/nuisance-discovery.md)."""
    from tether import nuisance as NZ
    from tether.api import simulate
    from tether.models import parse_model

    stem, _ = _write(tmp_path, "cut", "forced", {"hysteresis", "slack"}, 7, noise=1e-4, rate=100.0, duration_s=6.0,
                     nuisance=True, mass_factor=1.15, offset_noise=2.0, preroll_s=3.0)
    tr = read_trace(stem)
    sc = scales._scales(tr)
    nz = D.nuisance_parameters(tr)
    lin = D.fit_model(tr, parse_model("linear", "forced"), (), [nuisance_start(tr, nz), None], sc, nuisance=nz)
    first = starts.candidate_starts(lin, parse_model("linear+iwan", "forced"), sc, tr)[0]
    assert isinstance(first, dict)
    law = {n: v for n, v in first.items() if n not in NZ.NUISANCE}
    sim = simulate(tr, "linear+iwan", law, nuisance={n: v for n, v in first.items() if n in NZ.NUISANCE})
    rms = float(np.sqrt(np.mean((sim.predicted - tr.measured) ** 2)))
    assert rms < 1.5 * lin.rms, (rms, lin.rms)


def test_the_rival_law_starts_from_the_fitted_nuisance_and_beside_the_model(tmp_path):
    """rival_law's fits of the Iwan bank in Bouc-Wen's place start from the mass, initial state and
    offset the search fitted (before: from the record's stated mass, 15 % off here), the first of
    them a weak bank beside the final model (simulated: within 1.5 x that model's error), and with
    the bank's slip strains free where Bouc-Wen's shape terms were."""
    from dataclasses import replace as _replace

    from tether import nuisance as NZ
    from tether.api import simulate
    from tether.models import IWAN_EPS_FIT, parse_model

    stem, gen = _write(tmp_path, "cut", "forced", {"hysteresis", "slack"}, 7, noise=1e-4, rate=100.0, duration_s=6.0,
                       nuisance=True, mass_factor=1.15, offset_noise=2.0, preroll_s=3.0)
    tr, sigma, sc, part, held_out, _ = _record_and_part(stem)
    nz = D.nuisance_parameters(tr)
    lin = D.fit_model(tr, parse_model("linear", "forced"), (), [nuisance_start(tr, nz), None], sc, nuisance=nz)
    spec = parse_model("linear+boucwen+slack", "forced")
    cur = _replace(lin, spec=spec, effects=("hysteresis", "slack"),
                   params={**lin.params, "bw_A": 1e-3, "bw_beta": 1.0, "bw_gamma": 1.0})
    seen = []

    def fit(t, sp, eff, starts, baseline_rms=None, cap_factor=1.0, extra=()):
        seen.append((list(starts), tuple(extra)))
        return _replace(cur, ok=False, message="recorded")

    rival.rival_law(tr, part, held_out, cur, 10 * sigma, sigma, fit, {}, ["hysteresis", "slack"], lambda s: None,
                    incumbent_shaped=True)
    (begins, extra), = seen
    assert extra == tuple(IWAN_EPS_FIT)
    fitted = {n: v for n, v in cur.params.items() if n in NZ.NUISANCE}
    assert abs(fitted["m"] / tr.payload_mass_kg - 1.0) > 0.05
    for s in begins:
        if s is not None:
            assert {n: s[n] for n in fitted} == fitted
    first_start = begins[0]
    law = {n: v for n, v in first_start.items() if n not in NZ.NUISANCE}
    sim = simulate(tr, "linear+iwan+slack", law, nuisance={n: v for n, v in first_start.items() if n in NZ.NUISANCE})
    assert float(np.sqrt(np.mean((sim.predicted - tr.measured) ** 2))) < 1.5 * cur.rms


def test_a_rival_that_loses_only_on_the_held_out_part_gets_its_reseeding_moves_first():
    """_law_swapped: the rival's fit lowers the BIC and the error on the whole record but predicts
    the held-out part worse; where its law has reseeding moves, they run on it before the verdict,
    and the reseeded fit is judged again against the law in place (kept here: better on both). A
    reseed that changes nothing leaves the verdict as it was; without reseeding moves none runs."""
    from dataclasses import replace as _replace

    from tether.models import parse_model

    sigma, n = 1e-4, 2000
    cur = fitting.ModelFit(spec=parse_model("linear+boucwen+slack", "forced"), effects=("hysteresis", "slack"),
                           params={}, free=["EA", "c0", "bw_A", "bw_beta", "bw_gamma"], rms=2.07 * sigma,
                           predicted=np.zeros(1))
    iwan_free = ["EA", "c0", *models.IWAN_K_FIT]
    rival_fit = _replace(cur, spec=parse_model("linear+iwan+slack", "forced"), rms=1.75 * sigma, free=iwan_free,
                         params={k: 1.0 for k in iwan_free})
    reseeded_fit = _replace(rival_fit, rms=1.0 * sigma)
    held = {id(cur): 1.71 * sigma, id(rival_fit): 1.97 * sigma, id(reseeded_fit): 1.05 * sigma}

    from types import SimpleNamespace

    whole, part = SimpleNamespace(time=np.zeros(n)), SimpleNamespace(time=np.zeros(n // 2))

    def fit(t, sp, eff, starts, **kw):
        return rival_fit if t is whole else _replace(rival_fit, params={"part": 1.0})

    calls = []

    def run(reseed):
        orig = rival._heldout
        rival._heldout = lambda trace, spec, params, held_out: held[id(rival_fit)]
        try:
            return rival._law_swapped(whole, part, 0, cur, held[id(cur)], sigma, fit, rival_fit.spec,
                                      "hysteresis", "boucwen", [None], lambda k: True, lambda s: None, reseed=reseed)
        finally:
            rival._heldout = orig

    def better(m, h):
        calls.append(m)
        return reseeded_fit, held[id(reseeded_fit)]

    m, h, r = run(better)
    assert calls == [rival_fit] and m is reseeded_fit and r.accepted and "after its reseeding moves" in r.verdict
    m, h, r = run(lambda m, h: (m, h))
    assert m is cur and not r.accepted and "held-out part gets worse" in r.verdict
    m, h, r = run(None)
    assert m is cur and not r.accepted
