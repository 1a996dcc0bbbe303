"""Nuisance parameters (issue 30; tether.nuisance, docs/nuisance.md): the effective mass, the
initial state of a forced record, the offsets of both columns and the gain of the input.

Independent expectations: the scaling law of the physics (every force on a free payload scales
with its mass), the generating values of synthetic records made with the engine (noise added), the
FMU run by tether.run as a second implementation of the measurement rule, and the command line's
one-line refusals.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from tether import identify_native as idn
from tether.fit import FitError, fit_traces
from tether.fit.experiments import trace_experiment
from tether.models import parse_model
from tether.traces import Trace, TraceError

NOISE = 2e-5          # m
M_JSON = 4.0          # kg
TRUTH = {"EA": 30000.0, "c0": 3.0}
L0 = 10.0


def _say(capsys, text):
    with capsys.disabled():
        print("\n  [test_nuisance] " + text.replace("\n", "\n  [test_nuisance] "))


def _multisine(t):
    return sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in ((20, 1.3, 0.1), (15, 2.9, 1.0), (10, 4.1, 2.0),
                                                                  (8, 6.3, 0.5)))


def _record(experiment, t, inp, measured, model="linear", **meta):
    """A trace from arrays (input and measured columns by experiment)."""
    col_in = {"forced": "force", "load_unload": "load"}.get(experiment)
    col_out = "elongation" if experiment == "load_unload" else "displacement"
    kw = {col_out: measured}
    if col_in:
        kw[col_in] = inp
    if experiment in ("forced", "free_vibration"):
        meta.setdefault("payload_mass_kg", M_JSON)
        meta.setdefault("gravity_m_s2", 9.81)
    return Trace.from_arrays(t, experiment=experiment, length_m=L0, **kw, **meta)


def _synthetic(experiment, t, inp, truth, model="linear", noise=NOISE, seed=1, **meta):
    """The record the engine simulates with ``truth`` (law and nuisance values), plus white noise."""
    shape = _record(experiment, t, inp, np.zeros_like(t), model, **meta)
    x = trace_experiment(shape, parse_model(model), {})
    y = idn.simulate(x.exp, truth) + noise * np.random.default_rng(seed).standard_normal(len(t))
    return _record(experiment, t, inp, y, model, **meta)


def _forced(truth, **meta):
    t = np.arange(3000) * 2e-3
    return _synthetic("forced", t, _multisine(t), truth, **meta)


def _inside(r, name, value):
    lo, hi = r.ci95[name]
    return lo <= value <= hi


def _row(r, n, truth):
    lo, hi = r.ci95[n]
    return f"{n:16s} {r.values[n]:.7g} [{lo:.7g}, {hi:.7g}] truth {truth:.7g}"


# ---- the physics the refusal of m on a free vibration rests on ----------------------------------
@pytest.mark.parametrize("model,law", [
    ("linear", {"EA": 30000.0, "c0": 3.0}),
    ("cubic+nonlinear_damping", {"a1": 28000.0, "a2": -2.0e5, "a3": 4.0e7, "c0": 2.0, "c1": 30.0, "c2": 400.0}),
    ("linear+boucwen", {"EA": 30000.0, "c0": 3.0, "bw_A": 2000.0, "bw_beta": 15.0, "bw_gamma": 5.0}),
])
def test_free_vibration_is_unchanged_when_the_mass_and_every_force_scale_together(model, law):
    t = np.arange(4000) * 1e-3
    tr = _record("free_vibration", t, None, np.zeros_like(t), initial_displacement_m=0.02,
                 initial_velocity_m_s=0.1)
    x = trace_experiment(tr, parse_model(model), {"rtol": 1e-10})
    s = 1.37
    # forces scale with s; Bouc-Wen's z is a force and its law z' = x' (A - |z| psi) (n = 1) is
    # homogeneous in (z, A): A scales, beta and gamma (psi, 1/m) stay
    unchanged = {"bw_beta", "bw_gamma"}
    scaled = {n: v if n in unchanged else v * s for n, v in law.items()}
    y1 = idn.simulate(x.exp, {**law, "m": M_JSON})
    y2 = idn.simulate(x.exp, {**scaled, "m": s * M_JSON})
    assert np.ptp(y1) > 1e-2
    assert np.max(np.abs(y1 - y2)) < 1e-9
    # ... which is why freeing m on a free vibration is refused
    from tether.nuisance import refusal

    assert "scales" in refusal(tr, "m")


# ---- a forced record that starts in motion -------------------------------------------------------
def test_forced_record_starting_in_motion_recovers_x0_and_v0(capsys):
    x0, v0 = 0.012, -0.06
    tr = _forced({**TRUTH, "x0": x0, "v0": v0})
    r = fit_traces([tr], "linear", free=["EA", "c0", "x0", "v0"])
    _say(capsys, "\n".join(_row(r, n, v) for n, v in (("x0", x0), ("v0", v0), *TRUTH.items())))
    for n, v in (("x0", x0), ("v0", v0)):
        lo, hi = r.ci95[n]
        assert lo <= v <= hi, (n, r.values[n], r.ci95[n])
        assert hi - lo < abs(v) / 5, (n, r.ci95[n])
    assert set(r.nuisance) == {"x0", "v0"} and "x0" not in r.parameters
    assert any(line.startswith("v0:") and "moved" in line for line in r.nuisance_moved)
    # held at the trace's state (rest), the same fit is far off
    held = fit_traces([tr], "linear", free=["EA", "c0"])
    assert r.rms < 1.2 * NOISE and held.rms > 3 * NOISE, (r.rms, held.rms)


def test_forced_record_in_motion_with_an_iwan_bank_needs_its_last_reversal(capsys):
    """A forced record cut out of a longer run with an Iwan bank whose elements remember where the
    motion last reversed: 1.6 cm below the balance, further than the record's own motion goes down
    (its force is half the other records'), so the memory lasts through the record. Freed with x0
    and v0 (last_reversal_beyond: 1.2 cm beyond the span [-x0, x0]), the fit recovers x0 and v0
    within their intervals and a reversal of the same side and order, and reaches the noise; with the bank
    started as if displaced monotonically from the balance (held at 0, the default), x0 or v0
    lands outside its interval and the error stays above the noise."""
    from tether.fit.iwan_bank import iwan_params, iwan_slip_grid
    from tether.models import IWAN_K_FIT

    k = np.array([900.0, 700.0, 1200.0, 800.0, 600.0, 1000.0, 500.0, 400.0])
    bank = iwan_params(iwan_slip_grid(3e-3), k)
    state = {"x0": 0.004, "v0": 0.05, "last_reversal_beyond": -0.012}
    law = {**TRUTH, **bank}
    t = np.arange(3000) * 2e-3
    tr = _synthetic("forced", t, 0.5 * _multisine(t), {**law, **state}, model="linear+iwan")
    assert np.min(tr.measured) > -0.016 + 3 * NOISE        # the record never reaches the reversal again
    fixed = {n: v for n, v in bank.items() if n not in IWAN_K_FIT}
    start = {**law, "EA": 0.9 * TRUTH["EA"], "c0": 1.5 * TRUTH["c0"]}
    free = ["EA", "c0", *IWAN_K_FIT, "x0", "v0"]
    r = fit_traces([tr], "linear+iwan", free=free + ["last_reversal_beyond"], fixed=fixed, start=start)
    held = fit_traces([tr], "linear+iwan", free=free, fixed=fixed, start=start)
    _say(capsys, "\n".join(_row(r, n, v) for n, v in state.items()) + f"\nrms {r.rms / NOISE:.3f} x noise; "
         f"last_reversal_beyond held at 0: {held.rms / NOISE:.3f} x noise,\n"
         + "\n".join(_row(held, n, state[n]) for n in ("x0", "v0")))
    for n in ("x0", "v0"):
        assert _inside(r, n, state[n]), (n, r.values[n], r.ci95[n])
    # a reversal on the same side and of the same order: the record never reaches it again, so it
    # tells how far it was only through the elements that slipped there
    assert 0.5 * state["last_reversal_beyond"] > r.values["last_reversal_beyond"] > 2.0 * state["last_reversal_beyond"]
    assert r.rms < 1.1 * NOISE, r.rms
    assert held.rms > 1.2 * NOISE, held.rms
    assert not (_inside(held, "x0", state["x0"]) and _inside(held, "v0", state["v0"]))
    assert r.nuisance["last_reversal_beyond"] == r.values["last_reversal_beyond"]


def test_last_reversal_beyond_is_refused_without_an_iwan_bank():
    tr = _forced({**TRUTH, "x0": 0.01})
    with pytest.raises(FitError, match="last_reversal_beyond.*iwan"):
        fit_traces([tr], "linear+boucwen", free=["EA", "x0", "last_reversal_beyond"])


# ---- a forced record whose effective mass is 1.2 x the JSON's -------------------------------------
def test_forced_record_with_a_heavier_payload_needs_m_or_the_gain_free(capsys):
    m_true = 1.2 * M_JSON
    tr = _forced({**TRUTH, "m": m_true})
    free_m = fit_traces([tr], "linear", free=["EA", "c0", "m"])
    held = fit_traces([tr], "linear", free=["EA", "c0"])
    gain = fit_traces([tr], "linear", free=["EA", "c0", "input_gain"])
    G = M_JSON / m_true
    _say(capsys, "m free:    " + _row(free_m, "m", m_true) + f", rms/noise {free_m.rms / NOISE:.3f}\n"
         f"m held:    rms/noise {held.rms / NOISE:.1f}\n"
         "gain free: " + _row(gain, "input_gain", G) + f", rms/noise {gain.rms / NOISE:.3f}\n"
         "           " + _row(gain, "EA", TRUTH["EA"] * G) + "\n           " + _row(gain, "c0", TRUTH["c0"] * G))
    assert _inside(free_m, "m", m_true) and free_m.rms <= 1.2 * NOISE
    assert _inside(free_m, "EA", TRUTH["EA"]) and _inside(free_m, "c0", TRUTH["c0"])
    assert held.rms > 3 * NOISE
    # m x'' = m g + G f - T: with the JSON's mass the record fixes G = m_json / m_true and the forces scale so
    assert _inside(gain, "input_gain", G) and gain.rms <= 1.2 * NOISE
    assert _inside(gain, "EA", TRUTH["EA"] * G) and _inside(gain, "c0", TRUTH["c0"] * G)
    assert free_m.nuisance == {"m": free_m.values["m"]} and free_m.parameters.keys() == held.parameters.keys()


# ---- a load test with offsets on both columns ----------------------------------------------------
def test_load_test_offsets_on_both_columns_are_recovered(capsys):
    # Kawabata's branches are power laws: shifted in load and elongation they are no longer of the
    # family, so the two offsets are separable (a cubic shifted is another cubic: docs/nuisance.md)
    t = np.linspace(0.0, 200.0, 2001)
    load = 100.0 * np.interp(t, [0, 40, 60, 100, 120, 160, 200], [0, 1, 1, 0.3, 0.3, 1, 0])
    law = {"kaw_LT": 0.7, "kaw_RT": 0.5, "kaw_F_ref": 88.0, "kaw_residual": 0.1}
    truth = {**law, "offset_measured": 0.004, "offset_input": 2.0}
    noise = 2e-5
    tr = _synthetic("load_unload", t, load, truth, model="kawabata", noise=noise)
    r = fit_traces([tr], "kawabata", free=[*law, "offset_measured", "offset_input"])
    _say(capsys, "\n".join(_row(r, n, truth[n]) for n in r.free) + f"\nrms/noise {r.rms / noise:.3f}")
    for n in ("offset_measured", "offset_input"):
        lo, hi = r.ci95[n]
        assert lo <= truth[n] <= hi and hi - lo < abs(truth[n]) / 5, (n, r.values[n], r.ci95[n])
    assert r.rms <= 1.2 * noise and not r.unidentifiable


def test_load_test_offsets_on_a_cubic_law_are_flagged_not_determined():
    # a cubic through the origin shifted by (d_eps, d_T) with d_T = F(-d_eps) is another cubic
    # through the origin: the record cannot separate the two offsets, and the fit must say so
    t = np.linspace(0.0, 200.0, 2001)
    load = 800.0 * np.interp(t, [0, 80, 100, 180, 200], [0, 1, 1, 0, 0])
    truth = {"a1": 30000.0, "a2": 4.0e5, "a3": 2.0e7, "offset_measured": 0.004, "offset_input": 25.0}
    tr = _synthetic("load_unload", t, load, truth, model="cubic")
    r = fit_traces([tr], "cubic", free=["a1", "a2", "a3", "offset_measured", "offset_input"])
    assert "offset_input" in r.unidentifiable or "offset_measured" in r.unidentifiable, r.identifiability_report


# ---- the measurement rule: the engine's and the FMU's path agree ---------------------------------
def test_the_fmu_path_applies_the_nuisance_parameters_as_the_engine_does():
    from tether.discover import predict
    from tether.run import simulate

    tr = _forced(TRUTH)
    nuisance = {"m": 4.6, "x0": 0.01, "v0": -0.03, "offset_measured": 0.002, "offset_input": 3.0,
                "input_gain": 0.8}
    law = {**TRUTH, "rtol": 1e-10}
    engine = predict(tr, "linear", {**law, **nuisance})
    fmu = simulate(tr, "linear", law, nuisance=nuisance).predicted
    plain = simulate(tr, "linear", law).predicted
    assert np.max(np.abs(engine - plain)) > 1e-3        # the nuisance values matter
    assert np.max(np.abs(engine - fmu)) < 1e-8 * max(1.0, np.max(np.abs(fmu)))


# ---- refusals and the mass band ------------------------------------------------------------------
def _free_vibration():
    t = np.arange(2000) * 2e-3
    return _synthetic("free_vibration", t, None, TRUTH, initial_displacement_m=0.02)


@pytest.mark.parametrize("free,needle", [
    (["EA", "c0", "m"], "every force on the payload scales with it"),
    (["EA", "c0", "offset_input"], "has no input"),
])
def test_what_a_free_vibration_cannot_determine_is_refused(free, needle):
    with pytest.raises(FitError, match=needle):
        fit_traces([_free_vibration()], "linear", free=free)


def test_m_with_the_gain_and_the_state_of_a_periodic_or_load_record_are_refused():
    tr = _forced(TRUTH)
    with pytest.raises(FitError, match="m and input_gain cannot both be free"):
        fit_traces([tr], "linear", free=["EA", "c0", "m", "input_gain"])
    t = np.arange(1000) * 2e-3
    per = _record("forced", t, np.sin(2 * np.pi * 5 * t), np.zeros_like(t), periodic_samples=100)
    with pytest.raises(FitError, match="periodic steady state"):
        fit_traces([per], "linear", free=["EA", "c0", "x0"])
    t = np.linspace(0, 10, 101)
    load = _record("load_unload", t, 100 * np.sin(np.pi * t / 10), 1e-3 * np.sin(np.pi * t / 10))
    for n, needle in (("m", "payload mass plays no part"), ("v0", "no payload state")):
        with pytest.raises(FitError, match=needle):
            fit_traces([load], "linear", free=["EA", n])


def test_mass_form_follows_the_trace_keys():
    from tether.nuisance import mass_form

    assert mass_form(_forced(TRUTH)) == "m"
    assert mass_form(_forced(TRUTH, extra={"force_gain_known": False})) == "input_gain"
    assert mass_form(_forced(TRUTH, extra={"mass_uncertainty_rel": 0})) is None
    assert mass_form(_free_vibration()) is None


def test_the_mass_band_bounds_m(capsys):
    from tether.nuisance import mass_bounds

    tr = _forced({**TRUTH, "m": 1.2 * M_JSON})
    assert mass_bounds(tr) == pytest.approx((0.7 * M_JSON, 1.3 * M_JSON))
    stated = _forced(TRUTH, extra={"mass_uncertainty_rel": 0.05})
    assert mass_bounds(stated) == pytest.approx((0.95 * M_JSON, 1.05 * M_JSON))
    assert mass_bounds(stated, 0.5) == pytest.approx((0.5 * M_JSON, 1.5 * M_JSON))
    # a band that excludes the truth holds m at its edge
    r = fit_traces([tr], "linear", free=["EA", "c0", "m"], mass_band=0.1)
    assert r.values["m"] == pytest.approx(1.1 * M_JSON, rel=1e-9)
    with pytest.raises(FitError, match="mass_band"):
        fit_traces([tr], "linear", free=["EA", "c0", "m"], mass_band=-1)
    exact = _forced(TRUTH, extra={"mass_uncertainty_rel": 0})
    with pytest.raises(FitError, match="mass is exact"):
        fit_traces([exact], "linear", free=["EA", "c0", "m"])


# ---- trace keys -----------------------------------------------------------------------------------
def test_trace_keys_default_to_todays_meaning_and_bad_values_are_refused(write_trace):
    from tether.traces import read_trace

    t = np.arange(10) * 0.01
    cols = {"time": t, "force": np.zeros(10), "displacement": np.zeros(10)}
    tr = read_trace(write_trace("plain", write_trace.meta("forced"), cols))
    assert tr.mass_uncertainty_rel is None and tr.force_gain_known is True
    tr = read_trace(write_trace("stated", write_trace.meta("forced", mass_uncertainty_rel=0.1,
                                                           force_gain_known=False), cols))
    assert tr.mass_uncertainty_rel == 0.1 and tr.force_gain_known is False
    for key, value, needle in (("mass_uncertainty_rel", -0.2, "expected a number >= 0"),
                               ("mass_uncertainty_rel", "0.1", "is not a number"),
                               ("force_gain_known", "no", "is not a boolean"),
                               ("force_gain_known", 0, "is not a boolean")):
        stem = write_trace("bad", write_trace.meta("forced", **{key: value}), cols)
        with pytest.raises(TraceError) as e:
            read_trace(stem)
        msg = str(e.value)
        assert "bad.json" in msg and f"'{key}'" in msg and json.dumps(value) in msg and needle in msg, msg


# ---- the command line -----------------------------------------------------------------------------
def _write(tr, stem):
    col_in, col_out = tr.input_column, tr.measured_column
    cols = {"time": tr.time, **({col_in: tr.input} if col_in else {}), col_out: tr.measured}
    stem.with_suffix(".json").write_text(json.dumps(tr.meta))
    data = np.column_stack([np.asarray(v, float) for v in cols.values()])
    with open(stem.with_suffix(".csv"), "w") as f:
        f.write(",".join(cols) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")
    return stem


def test_cli_refuses_m_on_a_free_vibration_and_a_bad_mass_band(tmp_path, run_cli):
    stem = _write(_free_vibration(), tmp_path / "ring")
    out = tmp_path / "P.json"
    status, _, err = run_cli("fit", stem, "--model", "linear", "--free", "EA,c0,m", "--out", out)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert "ring.json" in lines[0] and "'m'" in lines[0] and "scales" in lines[0], err
    for band in ("-1", "1.5", "x"):
        status, _, err = run_cli("fit", stem, "--model", "linear", "--free", "EA,c0", "--mass-band", band,
                                 "--out", out)
        assert status == 2 and len(err.strip().splitlines()) == 1 and "--mass-band" in err, (band, err)
    assert not out.exists()


def test_cli_fit_reports_the_nuisance_and_validate_applies_it(tmp_path, run_cli):
    from test_json_schemas import assert_valid as check_schema

    m_true = 1.2 * M_JSON
    stem = _write(_forced({**TRUTH, "m": m_true, "offset_measured": 3e-4}), tmp_path / "heavy")
    out, rep = tmp_path / "P.json", tmp_path / "report"
    status, stdout, err = run_cli("fit", stem, "--model", "linear", "--free", "EA,c0,m,offset_measured",
                                  "--out", out, "--report", rep)
    assert status == 0, err
    assert "nuisance parameters" in stdout and re.search(r"\n  m: 4 -> 4\.(8|79).*: moved\n", stdout), stdout
    doc = json.loads((rep / "fit.json").read_text())
    check_schema(doc)
    assert set(doc["nuisance"]) == {"m", "offset_measured"} and "m" not in doc["parameters"]
    lo, hi = doc["intervals"]["m"]
    assert lo <= m_true <= hi
    params = json.loads(out.read_text())
    check_schema(params)
    assert params["nuisance"]["m"] == pytest.approx(m_true, rel=1e-3)
    # sweep --samples draws the law from such a file (its marginal), not the record's nuisance
    from tether.sweep import fit_uncertainty

    extra = {k: v for k, v in params.items() if k not in ("format", "model", "parameters")}
    names, values, errors, corr = fit_uncertainty(extra, params["parameters"], "P.json")
    assert names == ["EA", "c0"] and corr.shape == (2, 2)
    assert corr[0, 1] == pytest.approx(params["correlation"]["matrix"][0][1])
    status, stdout, err = run_cli("validate", stem, "--params", out, "--report", tmp_path / "val")
    assert status == 0, err
    v = json.loads((tmp_path / "val" / "validation.json").read_text())["traces"][0]
    assert v["rms_error"] < 1.2 * NOISE, v
