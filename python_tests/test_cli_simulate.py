"""`tether simulate`: end to end against closed forms and the Bouc-Wen benchmark, and its errors.

Expectations are computed independently of the package (closed-form oscillator, the benchmark's
own measured data, the quasi-static spring law)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time

import numpy as np
import pytest

# --- the free-vibration case (a): damped linear oscillator about the static balance -------------
M, L0, EA, C0, X0, G = 4.3, 16.0, 3500.0, 1.5, 0.05, 9.81


def oscillator(t, x0=X0, m=M, L=L0, EA=EA, c=C0):
    """Closed-form x(t), v(t) of m x'' + c x' + (EA/L) x = 0, x(0) = x0, v(0) = 0 (underdamped)."""
    k = EA / L
    wn = math.sqrt(k / m)
    zeta = c / (2.0 * math.sqrt(k * m))
    wd = wn * math.sqrt(1.0 - zeta ** 2)
    s = zeta * wn
    e = np.exp(-s * t)
    x = e * (x0 * np.cos(wd * t) + (s * x0 / wd) * np.sin(wd * t))
    v = -e * x0 * (wn ** 2 / wd) * np.sin(wd * t)
    return x, v


@pytest.fixture
def free_vibration_trace(write_trace):
    t = np.arange(0, 10001) * 1e-3          # 10 s at 1 kHz
    x, _ = oscillator(t)
    meta = write_trace.meta("free_vibration", payload_mass_kg=M, tether={"length_m": L0})
    return write_trace("fv", meta, {"time": t, "displacement": x})


def read_out(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return header, data


def assert_one_line_error(status, err, *fragments, code=2):
    assert status == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("tether: error: "), err
    assert "Traceback" not in err
    for f in fragments:
        assert f in lines[0], lines[0]


# ---------------------------------------------------------------------------------------------
# (a) free vibration vs the closed form
def test_free_vibration_closed_form(free_vibration_trace, tmp_path, run_cli, fmu_path):
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA, "c0": C0}))
    out = tmp_path / "out.csv"
    status, _, err = run_cli("simulate", free_vibration_trace, "--model", "linear", "--params", params, "--out", out)
    assert status == 0, err
    header, data = read_out(out)
    assert header == ["time", "displacement", "tension"]
    t = np.arange(0, 10001) * 1e-3
    x, v = oscillator(t)
    np.testing.assert_array_equal(data[:, 0], t)
    rel = np.max(np.abs(data[:, 1] - x)) / np.max(np.abs(x))
    assert rel < 1e-6, rel
    # tension of a linear spring + damper about the balance stretch m g L0 / EA
    tension = M * G + EA / L0 * x + C0 * v
    rel_t = np.max(np.abs(data[:, 2] - tension)) / np.max(np.abs(tension))
    assert rel_t < 1e-6, rel_t


def test_trace_metadata_wins_over_params_file(free_vibration_trace, tmp_path, run_cli, fmu_path):
    # L0, m, g, x0, v0 in the file are overridden by the trace's own values
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"model": "linear", "parameters": {"EA": EA, "c0": C0, "L0": 3.0, "m": 100.0,
                                                                    "x0": 1.0, "v0": 2.0, "g": 0.0}}))
    out = tmp_path / "out.csv"
    status, _, err = run_cli("simulate", free_vibration_trace, "--params", params, "--out", out)
    assert status == 0, err
    _, data = read_out(out)
    x, _ = oscillator(data[:, 0])
    assert np.max(np.abs(data[:, 1] - x)) / np.max(np.abs(x)) < 1e-6
    assert abs(data[0, 2] - (M * G + EA / L0 * X0)) < 1e-6 * M * G   # g = 9.81 from the trace default


def test_model_from_file_and_command_line_precedence(free_vibration_trace, tmp_path, run_cli, fmu_path):
    # the file asks for the cubic law (FMU start values a1, a2, a3); --model linear wins over it
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"model": "cubic", "parameters": {"EA": EA, "c0": C0}}))
    out_file, out_cli = tmp_path / "file.csv", tmp_path / "cli.csv"
    assert run_cli("simulate", free_vibration_trace, "--params", params, "--out", out_file)[0] == 0
    assert run_cli("simulate", free_vibration_trace, "--params", params, "--model", "linear", "--out", out_cli)[0] == 0
    x, _ = oscillator(np.arange(0, 10001) * 1e-3)
    err_cli = np.max(np.abs(read_out(out_cli)[1][:, 1] - x))
    err_file = np.max(np.abs(read_out(out_file)[1][:, 1] - x))
    assert err_cli < 1e-6 * X0
    assert err_file > 1e-3 * X0          # the cubic model is a different oscillator


def test_initial_state_from_json(write_trace, tmp_path, run_cli, fmu_path):
    # initial_displacement_m overrides the first sample (here deliberately wrong: 0)
    t = np.arange(0, 2001) * 1e-3
    x, _ = oscillator(t)
    meta = write_trace.meta("free_vibration", payload_mass_kg=M, initial_displacement_m=X0)
    stem = write_trace("fv0", meta, {"time": t, "displacement": np.r_[0.0, x[1:]]})
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA, "c0": C0}))
    out = tmp_path / "o.csv"
    assert run_cli("simulate", stem, "--params", params, "--out", out)[0] == 0
    assert np.max(np.abs(read_out(out)[1][:, 1] - x)) < 1e-6 * X0


# ---------------------------------------------------------------------------------------------
# (b) the Bouc-Wen benchmark with its nominal parameters (datasets/boucwen/README.md)
BW_NOMINAL = {"model": "linear+boucwen",
              "parameters": {"EA": 5e4, "c0": 10.0, "bw_A": 5e4, "bw_beta": 1e3 * 0.8, "bw_gamma": 1e3 * -1.1,
                             "bw_n": 1.0, "m": 2.0, "g": 0.0}}


@pytest.fixture
def bw_params(tmp_path):
    p = tmp_path / "P.json"
    p.write_text(json.dumps(BW_NOMINAL))
    return p


@pytest.mark.parametrize("record, limit", [("test_multisine", 5e-7), ("test_sinesweep", 5e-6)])
def test_boucwen_benchmark(record, limit, datasets_dir, bw_params, tmp_path, fmu_path):
    trace = datasets_dir / "boucwen" / f"{record}.csv.gz"
    out = tmp_path / "pred.csv"
    env = dict(os.environ, KT_FMU=str(fmu_path))
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "tether", "simulate", str(trace), "--model", "linear+boucwen",
                           "--params", str(bw_params), "--out", str(out)], capture_output=True, text=True, env=env)
    elapsed = time.perf_counter() - t0
    assert proc.returncode == 0, proc.stderr
    header, pred = read_out(out)
    measured = np.loadtxt(trace, delimiter=",", skiprows=1)
    assert header == ["time", "displacement", "tension"]
    np.testing.assert_array_equal(pred[:, 0], measured[:, 0])
    rms = float(np.sqrt(np.mean((pred[:, 1] - measured[:, 2]) ** 2)))
    print(f"\n{record}: RMS error {rms:.3e} m (limit {limit:.0e}), {elapsed:.2f} s")
    assert rms < limit


# ---------------------------------------------------------------------------------------------
# periodic records: steady state of a sine-driven linear oscillator (closed form)
def test_periodic_steady_state_closed_form(write_trace, tmp_path, run_cli, fmu_path):
    m, L, EA_, c, F0, w = 4.3, 16.0, 3500.0, 30.0, 10.0, 5.0
    k = EA_ / L
    P = 200
    period = 2 * math.pi / w
    t = np.arange(2 * P) * (period / P)          # two periods
    amp = F0 / math.hypot(k - m * w ** 2, c * w)
    phi = math.atan2(c * w, k - m * w ** 2)
    x = amp * np.sin(w * t - phi)
    meta = write_trace.meta("forced", payload_mass_kg=m, tether={"length_m": L}, periodic_samples=P,
                            initial_displacement_m=0.3)   # ignored: periodic runs start from rest
    stem = write_trace("ps", meta, {"time": t, "force": F0 * np.sin(w * t), "displacement": x})
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA_, "c0": c}))
    out = tmp_path / "ps_pred.csv"
    status, _, err = run_cli("simulate", stem, "--params", params, "--out", out)
    assert status == 0, err
    assert err == ""
    _, data = read_out(out)
    np.testing.assert_array_equal(data[:, 0], t)
    assert np.max(np.abs(data[:, 1] - x)) / amp < 1e-5


def test_non_periodic_input_warns(write_trace, tmp_path, run_cli, fmu_path):
    P = 50
    t = np.arange(2 * P) * 0.02
    f = np.sin(2 * np.pi * t)
    f[P + 3] += 1.0                                # the second period differs
    meta = write_trace.meta("forced", periodic_samples=P)
    stem = write_trace("np", meta, {"time": t, "force": f, "displacement": np.zeros_like(t)})
    out = tmp_path / "np_pred.csv"
    status, _, err = run_cli("simulate", stem, "--model", "linear", "--out", out)
    assert status == 0, err
    assert err.startswith("tether: warning: ") and "not periodic" in err and "np.csv" in err
    assert out.exists()


def test_fmu_warning_is_reported(write_trace, tmp_path, run_cli, fmu_path):
    # released 1 m below balance on 16 m, the strain passes the cubic's rising limit (FMU defaults)
    t = np.arange(0, 51) * 1e-2
    meta = write_trace.meta(initial_displacement_m=1.0)
    stem = write_trace("far", meta, {"time": t, "displacement": np.zeros_like(t)})
    out = tmp_path / "far_pred.csv"
    status, _, err = run_cli("simulate", stem, "--model", "cubic+slack", "--out", out)
    assert status == 0, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tether: warning: ") and "cubic law" in lines[0]
    assert out.exists()


# ---------------------------------------------------------------------------------------------
# (c) load_unload through the load rig
def test_load_unload_load_rig(write_trace, tmp_path, run_cli, fmu_path):
    t = np.linspace(0.0, 200.0, 401)
    load = np.interp(t, [0, 100, 200], [0.0, 100.0, 5.0])
    meta = write_trace.meta("load_unload", tether={"length_m": L0})
    stem = write_trace("lu", meta, {"time": t, "load": load, "elongation": load * L0 / EA})
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA}))
    out = tmp_path / "lu_pred.csv"
    status, _, err = run_cli("simulate", stem, "--model", "linear", "--params", params, "--out", out)
    assert status == 0, err
    header, data = read_out(out)
    assert header == ["time", "elongation", "tension"]
    np.testing.assert_array_equal(data[:, 0], t)
    # quasi-static linear spring: elongation = load L0 / EA; the tension is the applied load
    np.testing.assert_allclose(data[:, 1], load * L0 / EA, rtol=0, atol=1e-6 * 100 * L0 / EA)
    np.testing.assert_allclose(data[:, 2], load, rtol=0, atol=1e-9 * 100)


def test_creep_trace_runs_with_creep_model(write_trace, tmp_path, run_cli, fmu_path):
    t = np.linspace(0.0, 7200.0, 241)
    load = np.where(t < 3600, 100.0, 5.0)
    load[0] = 0.0
    meta = write_trace.meta("creep", tether={"length_m": L0})
    stem = write_trace("cr", meta, {"time": t, "load": load, "elongation": np.zeros_like(t)})
    out = tmp_path / "cr_pred.csv"
    status, _, err = run_cli("simulate", stem, "--model", "linear+creep", "--out", out)
    assert status == 0, err
    _, data = read_out(out)
    i1 = np.searchsorted(t, 600.0)
    i2 = np.searchsorted(t, 3500.0)
    assert data[i2, 1] > data[i1, 1] > 0          # elongation grows under constant load


# ---------------------------------------------------------------------------------------------
# errors: one line, exit 2, no output file
def test_bad_trace_error(write_trace, tmp_path, run_cli):
    stem = write_trace("bad", write_trace.meta(), csv="time,displacement\n0,0.1\n0.1,oops\n")
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", stem, "--out", out)
    assert_one_line_error(status, err, "bad.csv", "line 3", "'oops'")
    assert not out.exists()


def test_unknown_model_error(free_vibration_trace, tmp_path, run_cli):
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", free_vibration_trace, "--model", "linear+friction", "--out", out)
    assert_one_line_error(status, err, "'friction'", "valid names", "boucwen")
    assert not out.exists()


@pytest.mark.parametrize("obj, fragments", [
    ({"EA": -5}, ("p.json", "'EA'", "-5", "minimum")),
    ({"Ea": 5}, ("p.json", "'Ea'", "not a parameter")),
    ({"parameters": {"c0": "x"}}, ("p.json", "'parameters.c0'", '"x"', "not a number")),
])
def test_bad_params_error(free_vibration_trace, tmp_path, run_cli, fmu_path, obj, fragments):
    p = tmp_path / "p.json"
    p.write_text(json.dumps(obj))
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", free_vibration_trace, "--params", p, "--out", out)
    assert_one_line_error(status, err, *fragments)
    assert not out.exists()


def test_existing_output_untouched_on_error(write_trace, free_vibration_trace, tmp_path, run_cli):
    out = tmp_path / "keep.csv"
    out.write_text("previous result\n")
    before = sorted(os.listdir(tmp_path))
    status, _, err = run_cli("simulate", free_vibration_trace, "--model", "nope", "--out", out)
    assert status == 2
    assert out.read_text() == "previous result\n"
    assert sorted(os.listdir(tmp_path)) == before          # no temporary file left behind


def test_output_written_atomically_no_temp_left(free_vibration_trace, tmp_path, run_cli, fmu_path):
    out = tmp_path / "o.csv"
    out.write_text("old\n")
    assert run_cli("simulate", free_vibration_trace, "--out", out)[0] == 0
    assert out.read_text().startswith("time,displacement,tension\n")
    assert not [n for n in os.listdir(tmp_path) if n.endswith(".tmp")]


def test_fmu_refuses_parameters_one_line(write_trace, tmp_path, run_cli, fmu_path):
    # a1 <= 0 is in the FMU's declared range (no min) but its initialisation rejects it
    t = np.arange(0, 101) * 1e-3
    stem = write_trace("fv", write_trace.meta(), {"time": t, "displacement": 0.05 * np.cos(t)})
    p = tmp_path / "p.json"
    p.write_text(json.dumps({"model": "cubic", "parameters": {"a1": -1e9}}))
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", stem, "--params", p, "--out", out)
    assert_one_line_error(status, err, "fv", "a1", code=1)
    assert not out.exists()


def test_fmu_step_failure_names_trace_and_time(write_trace, tmp_path, run_cli, fmu_path):
    # released 0.6 m below balance without slack, the payload swings up into compression, past the
    # strain where the cubic law (FMU defaults, a3 < 0) stops rising: it runs away within the
    # first second and the FMU stops the step (fmi2Discard) at the time it ran away
    t = np.arange(0, 101) * 1e-2
    meta = write_trace.meta(initial_displacement_m=0.6)
    stem = write_trace("runaway", meta, {"time": t, "displacement": np.zeros_like(t)})
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", stem, "--model", "cubic", "--out", out)
    assert_one_line_error(status, err, "runaway", "stopped at t = 0.", "fmi2Discard", "run away", code=1)
    assert not out.exists()


def test_missing_fmu(free_vibration_trace, tmp_path, run_cli, monkeypatch):
    monkeypatch.setenv("KT_FMU", str(tmp_path / "missing.fmu"))
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", free_vibration_trace, "--out", out)
    assert_one_line_error(status, err, "missing.fmu", "scripts/setup.sh", code=1)
    assert not out.exists()


def test_missing_arguments_one_line(run_cli):
    status, _, err = run_cli("simulate")
    assert_one_line_error(status, err, "--out")


def test_output_directory_missing(free_vibration_trace, tmp_path, run_cli):
    status, _, err = run_cli("simulate", free_vibration_trace, "--out", tmp_path / "no" / "o.csv")
    assert_one_line_error(status, err, "does not exist")


def test_refuses_to_overwrite_trace(free_vibration_trace, run_cli):
    csv = free_vibration_trace.with_name("fv.csv")
    before = csv.read_text()
    status, _, err = run_cli("simulate", free_vibration_trace, "--out", csv)
    assert_one_line_error(status, err, "overwrite the trace")
    assert csv.read_text() == before


def test_console_script_error_has_no_traceback(tmp_path, fmu_path):
    env = dict(os.environ, KT_FMU=str(fmu_path))
    proc = subprocess.run([sys.executable, "-m", "tether", "simulate", str(tmp_path / "nothing"), "--out",
                           str(tmp_path / "o.csv")], capture_output=True, text=True, env=env)
    assert_one_line_error(proc.returncode, proc.stderr, "nothing.csv", "not found")
