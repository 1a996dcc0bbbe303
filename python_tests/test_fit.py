"""tether fit: the acceptance of issue 4's fits (tether.fit, `tether fit`).

a) The Bouc-Wen benchmark: `tether fit train_multisine --model linear+boucwen` from the tool's own
   data-based start, then the FMU (`tether simulate --params`) on the two test records: RMS error
   below 1e-6 m on test_multisine and 5e-6 m on test_sinesweep (independent expectation: the
   published table; the true equations give 2.3e-7 m on test_multisine).
b) Synthetic reference traces, generated with known parameters (the FMU's start values, recorded
   in each trace's JSON): the fits recover them within their 95 % intervals; the `full` model on a
   single free-vibration trace has parameters the report flags as not determined.
c) The command line: the parameter file it writes is what --params reads; bad names are one line,
   exit status 2, no output file.
The measured figures are printed (pytest -s shows them, and so does the terminal on -q via
capsys.disabled()).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tether import identify_native as idn
from tether.fit import default_free_parameters, fit_traces, initial_estimate, write_fit_params
from tether.models import read_params
from tether.traces import read_trace
from tether.validate import generating_model

REF = Path(__file__).resolve().parents[1] / "reference_results"


def _say(capsys, text):
    with capsys.disabled():
        print("\n  [test_fit] " + text.replace("\n", "\n  [test_fit] "))


def _truth(stem: Path) -> dict:
    """The generating values of a synthetic trace: its recorded parameters over the FMU's start values."""
    model, params = generating_model(read_trace(stem))
    return {**{n: idn.parameter_start(n) for n in idn.parameter_names(kind=0)}, **params}


def _recovered(r, truth, names=None) -> list[str]:
    """Lines 'name value [lo, hi] truth' and the names whose truth lies outside the interval."""
    lines, outside = [], []
    for n in names or r.free:
        lo, hi = r.ci95[n]
        ok = lo <= truth[n] <= hi
        outside += [] if ok else [n]
        lines.append(f"{n:14s} {r.values[n]:13.6g} ± {r.std_error[n]:9.3g}  [{lo:.6g}, {hi:.6g}]  truth "
                     f"{truth[n]:.6g} ({(r.values[n] - truth[n]) / r.std_error[n]:+.2f} se){'' if ok else '  OUTSIDE'}"
                     f"{'  (flagged)' if n in r.unidentifiable else ''}")
    return lines, outside


# ---- a) the Bouc-Wen benchmark ------------------------------------------------------------------
def test_boucwen_benchmark_fit_from_the_default_start(tmp_path, run_cli, datasets_dir, capsys):
    bw = datasets_dir / "boucwen"
    params = tmp_path / "P.json"
    status, out, err = run_cli("fit", bw / "train_multisine", "--model", "linear+boucwen", "--out", params)
    assert status == 0, err
    assert "iteration" in err and "stage 2/2" in err          # progress on stderr
    doc = json.loads(params.read_text())
    assert doc["model"] == "linear+boucwen"
    assert set(doc["intervals"]) == {"EA", "c0", "bw_A", "bw_beta", "bw_gamma"}
    rms = {}
    for name in ("test_multisine", "test_sinesweep"):
        sim = tmp_path / f"{name}.csv"
        status, _, err = run_cli("simulate", bw / name, "--params", params, "--out", sim)
        assert status == 0, err
        pred = np.loadtxt(sim, delimiter=",", skiprows=1)[:, 1]
        rms[name] = float(np.sqrt(np.mean((pred - read_trace(bw / name).measured) ** 2)))
    p = doc["parameters"]
    _say(capsys, f"Bouc-Wen benchmark, fitted on train_multisine from the data-based start: "
                 f"RMS error test_multisine {rms['test_multisine']:.3g} m, test_sinesweep {rms['test_sinesweep']:.3g} m "
                 f"(train RMS {doc['rms']:.3g} m); EA {p['EA']:.6g}, c0 {p['c0']:.5g}, A {p['bw_A']:.6g}, "
                 f"beta {p['bw_beta']:.5g}, gamma {p['bw_gamma']:.5g}")
    assert rms["test_multisine"] < 1e-6
    assert rms["test_sinesweep"] < 5e-6
    # the fit reaches the training record's noise (sigma about 7e-6 m)
    assert doc["rms"] < 8e-6


# ---- b) recovery of the generating parameters ---------------------------------------------------
def test_stiffness_test_cubic_law_recovered(capsys):
    stem = REF / "stiffness_16m"
    r = fit_traces([stem], "cubic")
    assert r.free == ["a1", "a2", "a3"] and not r.unidentifiable
    lines, outside = _recovered(r, _truth(stem))
    _say(capsys, f"stiffness_16m, cubic ({r.seconds:.1f} s, RMS {r.rms:.3g} m):\n" + "\n".join(lines))
    assert not outside


def test_simplified_model_joint_fit_of_both_release_amplitudes(capsys):
    stems = [REF / "freevib_simplified_0p1669", REF / "freevib_simplified_0p1184"]
    truth = _truth(stems[0])
    other = _truth(stems[1])                                  # one parameter set generated both
    assert {k: v for k, v in truth.items() if k != "x0"} == {k: v for k, v in other.items() if k != "x0"}
    r = fit_traces(stems, "simplified+slack")
    assert r.free == ["a1", "a2", "a3", "c0", "c1", "c2"]
    lines, outside = _recovered(r, truth)
    _say(capsys, f"freevib_simplified pair, simplified+slack, joint ({r.seconds:.1f} s, RMS per trace "
                 f"{r.rms_per_trace[0]:.3g}, {r.rms_per_trace[1]:.3g} m):\n" + "\n".join(lines))
    assert not outside
    for n in ("a1", "a2", "a3", "c0", "c1"):                 # the identifiable ones, tightly
        assert n not in r.unidentifiable
        assert r.std_error[n] < 0.02 * abs(truth[n])
    # each trace down to its noise (the traces state sigma = 5e-4 m)
    assert all(4.5e-4 < v < 5.5e-4 for v in r.rms_per_trace)
    assert len(r.predictions) == 2 and all(len(p) == 4001 for p in r.predictions)


def test_a_fit_started_at_its_optimum_hands_back_no_more_error():
    """The stages (elastic law and viscous damping first, free vibration's first quarter and half of
    the record before all of it) move a start that is already at the whole record's optimum; one
    iteration after them the error is higher (here 4.99594e-4 -> 4.99608e-4 m; a discovery's final
    model refitted from its own values went 7.47 -> 15.2 x noise). The fit then returns its start."""
    stem = REF / "freevib_simplified_0p1669"
    r = fit_traces([stem], "simplified+slack")
    again = fit_traces([stem], "simplified+slack", start=r.values, max_iterations=1)
    assert again.rms <= r.rms
    if "the start is returned" in again.message:
        assert again.values == r.values
        # the returned error is the start's, recomputed from its simulation
        assert again.rms == pytest.approx(r.rms, rel=1e-12)


def test_kawabata_loop_parameters_recovered(capsys):
    stem = REF / "kawabata_16m_6kg"
    truth = _truth(stem)
    est = initial_estimate([read_trace(stem)], "kawabata")
    for n in ("kaw_LT", "kaw_RT", "kaw_residual"):           # Kawabata's energies alone land close
        assert est[n] == pytest.approx(truth[n], rel=0.01)
    r = fit_traces([stem], "kawabata")
    assert r.free == ["kaw_LT", "kaw_RT", "kaw_F_ref", "kaw_residual"]
    lines, outside = _recovered(r, truth)
    _say(capsys, f"kawabata_16m_6kg ({r.seconds:.1f} s, RMS {r.rms:.3g} m):\n" + "\n".join(lines))
    assert not outside and not r.unidentifiable


def test_creep_compliances_and_slip_recovered(capsys):
    stem = REF / "creep_16m_1p5mm"
    truth = _truth(stem)
    r = fit_traces([stem], "cubic+creep")
    assert r.free == ["creep_J1", "creep_J2", "creep_J3", "slip_capacity0", "slip_rate"]
    lines, outside = _recovered(r, truth)
    _say(capsys, f"creep_16m_1p5mm, cubic+creep, elastic law held ({r.seconds:.1f} s, RMS {r.rms:.3g} m):\n"
                 + "\n".join(lines))
    assert not r.unidentifiable
    assert r.rms < 1.1 * 2e-5
    # each within 3 standard errors. J3 (the 2-day cell, over a 36 h record) and the slip capacity
    # trade off; this trace's noise happens to push both about 2.2 standard errors along that one
    # direction (fits of the noise-free record recover all five to 1e-6 relative; three other
    # noise draws stayed within 2.0 standard errors)
    for n in r.free:
        assert abs(r.values[n] - truth[n]) <= 3 * r.std_error[n], n
    assert set(outside) <= {"creep_J3", "slip_capacity0"}


def test_full_model_on_one_free_vibration_trace_flags_what_is_not_determined(tmp_path, run_cli, capsys):
    stem = REF / "freevib_full_0p1669"
    report = tmp_path / "report"
    out_file = tmp_path / "full.json"
    status, out, err = run_cli("fit", stem, "--model", "full+slack", "--out", out_file, "--report", report)
    assert status == 0, err
    doc = json.loads((report / "fit.json").read_text())
    assert doc["free"] == default_free_parameters("full+slack", "free_vibration")
    assert doc["unidentifiable"], doc["identifiability_report"]
    for n in doc["unidentifiable"]:
        assert n in doc["identifiability_report"]
        assert re.search(rf"^{n}\s.*UNIDENTIFIABLE$", out, re.M), out
    assert "Not determined by the data" in doc["identifiability_report"]
    truth = _truth(stem)
    inside = [n for n in doc["free"] if doc["intervals"][n][0] <= truth[n] <= doc["intervals"][n][1]]
    _say(capsys, f"freevib_full_0p1669, full+slack ({doc['seconds']:.1f} s, RMS {doc['rms']:.3g} m): flagged "
                 f"{', '.join(doc['unidentifiable'])}; truth inside the 95 % interval for {len(inside)}/"
                 f"{len(doc['free'])}\n{doc['identifiability_report']}")
    # the page: a plot of the trace and the correlation matrix as an image, the report text
    page = (report / "index.html").read_text()
    imgs = re.findall(r"<img src='([^']+)'", page)
    assert "plots/correlation.png" in imgs and "plots/freevib_full_0p1669.png" in imgs
    for img in imgs:
        assert (report / img).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Not determined by the data" in page
    # the correlation matrix on the terminal
    assert "correlation matrix:" in out


# ---- c) the command line and the parameter file -------------------------------------------------
def test_fitted_parameter_file_is_what_params_reads(tmp_path, run_cli):
    stem = REF / "stiffness_16m"
    params = tmp_path / "fit.json"
    status, out, err = run_cli("fit", stem, "--model", "cubic", "--free", "a1,a2,a3", "--out", params)
    assert status == 0, err
    pf = read_params(params)
    assert pf.model == "cubic"
    assert set(pf.parameters) == {"a1", "a2", "a3", "pow_F", "pow_eps", "pow_n", "c0"}    # every parameter of the model
    for key in ("intervals", "std_error", "correlation", "unidentifiable", "rms"):
        assert key in pf.extra
    assert pf.extra["correlation"]["parameters"] == ["a1", "a2", "a3"]
    # validate with it: the error is the trace's noise
    status, vout, verr = run_cli("validate", stem, "--params", params, "--report", tmp_path / "v")
    assert status == 0, verr
    row = json.loads((tmp_path / "v" / "validation.json").read_text())["traces"][0]
    assert row["within_noise"] is True and row["model"] == "cubic"
    assert row["rms_error"] == pytest.approx(pf.extra["rms"], rel=1e-6)
    # the table: a row per parameter with its unit (modelDescription.xml: N), value, std error, interval
    for n in ("a1", "a2", "a3"):
        lo, hi = pf.extra["intervals"][n]
        assert re.search(rf"^{n}\s+N\s+\S+\s+\S+\s+" + re.escape(f"[{lo:.6g}, {hi:.6g}]"), out, re.M), out


def test_params_file_gives_starts_and_held_values(tmp_path, run_cli):
    stem = REF / "stiffness_16m"
    start = tmp_path / "start.json"
    start.write_text(json.dumps({"model": "cubic", "parameters": {"a1": 1000.0, "a2": 1.5e5, "a3": -1.9e6}}))
    out = tmp_path / "fit.json"
    status, _, err = run_cli("fit", stem, "--params", start, "--free", "a1,a2", "--out", out)
    assert status == 0, err
    doc = json.loads(out.read_text())
    assert doc["parameters"]["a3"] == -1.9e6                  # held at the file's value
    assert set(doc["intervals"]) == {"a1", "a2"}


@pytest.mark.parametrize("free, needle", [
    ("a1,bogus", "'bogus': not a parameter of the FMU"),
    ("a1,c1", "'c1': not used by the model 'cubic'"),
    ("a1,L0", "'L0': set by each trace's metadata"),
    ("a1,stiffness", "'stiffness': a structural switch"),
    ("a1,,a2", "empty name"),
    ("a1,a1", "'a1' given twice"),
])
def test_bad_free_names_are_one_line_exit_2_and_no_output(tmp_path, run_cli, free, needle):
    out = tmp_path / "P.json"
    status, stdout, err = run_cli("fit", REF / "stiffness_16m", "--model", "cubic", "--free", free, "--out", out)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tether: error: ") and needle in lines[0], err
    assert not out.exists() and not list(tmp_path.iterdir())


def test_other_bad_input_is_one_line_exit_2(tmp_path, run_cli):
    out = tmp_path / "P.json"
    cases = [
        (["fit", REF / "stiffness_16m", "--out", out], "no model"),
        (["fit", REF / "stiffness_16m", "--model", "cubix", "--out", out], "unknown name 'cubix'"),
        (["fit", tmp_path / "missing", "--model", "cubic", "--out", out], "not found"),
        (["fit", REF / "stiffness_16m", "--model", "cubic", "--out", tmp_path / "no" / "P.json"], "does not exist"),
        (["fit", REF / "stiffness_16m", "--model", "cubic", "--out", out, "--starts", "0"], "--starts 0"),
    ]
    for argv, needle in cases:
        status, _, err = run_cli(*argv)
        assert status == 2, (argv, err)
        assert len(err.strip().splitlines()) == 1 and needle in err, (argv, err)
        assert not out.exists()


def test_default_free_parameters_follow_what_each_experiment_sees():
    assert default_free_parameters("linear+boucwen", "forced") == ["EA", "c0", "bw_A", "bw_beta", "bw_gamma"]
    assert default_free_parameters("full", "free_vibration") == ["a1", "a2", "a3", "c0", "c1", "c2", "bw_A",
                                                                   "bw_beta", "bw_gamma"]
    # quasi-static load tests do not see damping; a creep test does not determine a cubic
    assert default_free_parameters("cubic", "load_unload") == ["a1", "a2", "a3"]
    assert default_free_parameters("kawabata", "load_unload") == ["kaw_LT", "kaw_RT", "kaw_F_ref", "kaw_residual"]
    assert default_free_parameters("linear+creep", "creep")[0] == "EA"
    assert "a1" not in default_free_parameters("cubic+creep", "creep")
    # creep is invisible in seconds of vibration
    assert not any(n.startswith(("creep", "slip")) for n in default_free_parameters("simplified+creep", "free_vibration"))



def test_iwan_spring_strains_follow_the_generators_bank():
    """The Iwan bank's spring strains of the fit's equation error (tether.fit.iwan_spring_strains,
    numpy) against the hidden-effects generator's Jenkins elements (python_tests/hidden_effects.py,
    committed sample by sample) along a path with nested reversals: the same bank force."""
    import hidden_effects as he
    from tether.fit.iwan_bank import iwan_slip_grid, iwan_spring_strains

    t = np.linspace(0.0, 20.0, 4001)
    d = 2e-3 * np.sin(2 * np.pi * 0.3 * t) * np.exp(-0.05 * t) + 4e-4 * np.sin(2 * np.pi * 1.7 * t)
    slip = iwan_slip_grid(1.5e-3)
    k = np.array([50.0, 0.0, 120.0, 80.0, 30.0, 200.0, 60.0, 90.0])
    H = iwan_spring_strains(d, slip) @ k
    bank = he.Iwan(k, k * np.asarray(slip))
    bank.reset(0.0)
    ref = []
    for x in d:
        bank.commit(x)
        ref.append(bank.force(x))
    err = float(np.max(np.abs(H - np.asarray(ref))))
    assert float(np.ptp(ref)) > 0.1 and err < 1e-12 * float(np.ptp(ref)), err
    # periodic: the second lap of a closed path is the steady loop (a lap more changes nothing)
    P = 800
    loop = d[:P] - d[0]
    two = iwan_spring_strains(np.tile(loop, 3), slip)[2 * P:]
    assert np.allclose(iwan_spring_strains(loop, slip, periodic=True), two, atol=1e-15)


def test_iwan_fit_of_a_load_test_with_hidden_friction(tmp_path, capsys):
    """A load-unload test of the hidden-effects generator with Iwan hysteresis (its twelve elements
    on a power-law spread of slip strains, not the fit's grid of eight): linear+iwan from the fit's
    own equation-error start, on its grid, leaves a third of the Bouc-Wen force's error; with the
    slip strains freed as well it reaches the noise."""
    from tether.models import IWAN_EPS
    import hidden_effects as he
    from tether.discover import estimate_noise

    gen = he.generate("load_unload", {"hysteresis"}, 23, noise=5e-5, rate=5.0)
    gen.write(tmp_path, "iwan_load")
    tr = read_trace(tmp_path / "iwan_load")
    sigma = gen.meta["hidden"]["noise_sigma_m"]
    iw = fit_traces([tr], "linear+iwan")
    free = default_free_parameters("linear+iwan", tr.experiment) + list(IWAN_EPS)
    iw2 = fit_traces([tr], "linear+iwan", free=free, start={k: iw.parameters[k] for k in free})
    bw = fit_traces([tr], "linear+boucwen")
    _say(capsys, f"Iwan load test ({len(tr.time)} samples): linear+iwan {iw.rms / sigma:.2f} x noise on the "
                 f"grid, {iw2.rms / sigma:.2f} x with the slip strains free; linear+boucwen {bw.rms / sigma:.2f} x noise")
    assert estimate_noise(tr).sigma == pytest.approx(sigma, rel=0.2)
    assert iw.rms < 0.5 * bw.rms
    assert iw2.rms <= 1.3 * sigma


def test_the_estimate_of_a_bank_that_takes_all_the_stiffness_is_a_valid_model(tmp_path):
    """The generator's forced record with Iwan friction and slack of the nuisance family's seed 7
    (record 29): fitted without slack, the equation error gives the bank all the stiffness and
    the elastic law a negative one (EA -624 N before the fix), a model the engine refuses, so every
    fit from the estimate failed. The estimate keeps the linear start's stiffness there, and the
    engine simulates it."""
    import hidden_effects as he
    from tether.fit.experiments import trace_experiment
    from tether.models import parse_model

    name, kw = next(s for s in he.nuisance_specs(24, 7) if s[0].startswith("29_"))
    he.generate(**kw).write(tmp_path, name)
    tr = read_trace(tmp_path / name)
    spec = parse_model("linear+iwan", "forced")
    est = {k: v for k, v in initial_estimate([tr], spec).items() if not k.startswith("_")}
    assert est["EA"] > 0, est["EA"]
    y = idn.simulate(trace_experiment(tr, spec, {}).exp, est)
    assert np.all(np.isfinite(y))


def test_a_log_scaled_parameter_a_stage_drove_to_zero_starts_the_next_stage_above_zero(monkeypatch):
    """A stage can drive a parameter the records hardly see below the smallest double (a campaign of
    seed 1008: its damping beside Bouc-Wen, c0 = 0.0 after the first stage). The engine refuses a
    log-scaled start of 0: the next stage starts it at the fit's own start again, and the fit goes
    on (it used to fail: "log scaling needs a start and bounds of one sign"). Not at the smallest
    double: a log-scaled parameter there never moves again (a rival Iwan bank's fit beside slack
    ended at 5.33 x noise so, where from its own start it reaches 2.67 x)."""
    import tether.fit.engine as engine

    real_fit, starts = engine.idn.fit, []

    def first_stage_underflows(exps, free, **kw):
        starts.append({n: v[2] for n, v in free.items()})
        r = real_fit(exps, free, **kw)
        if len(starts) == 1:
            r.values[r.names.index("c0")] = 0.0
        return r

    monkeypatch.setattr(engine.idn, "fit", first_stage_underflows)
    r = fit_traces([REF / "freevib_simplified_0p1669"], "simplified+slack")
    assert len(starts) == 2 and "c1" not in starts[0] and "c1" in starts[1]   # two stages
    assert starts[1]["c0"] == starts[0]["c0"] > 0.0
    assert np.isfinite(r.rms)
