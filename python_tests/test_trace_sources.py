"""Traces from real files and from memory: fmpy's result CSV, pandas' CSV, compressed CSV,
Trace.from_arrays / from_dataframe, and input-only traces for `tether simulate`.

Expectations are independent of the reader: the closed-form damped oscillator, the arrays that
were written, and fmpy's own simulation of the FMU."""

from __future__ import annotations

import gzip
import json
import math

import numpy as np
import pytest

from tether.traces import Trace, TraceError, read_trace

M, L0, EA, C0, X0, G = 4.3, 16.0, 3500.0, 1.5, 0.05, 9.81


def oscillator(t, x0=X0):
    """Closed-form x(t) of m x'' + c x' + (EA/L) x = 0, x(0) = x0, v(0) = 0 (underdamped)."""
    k = EA / L0
    wn = math.sqrt(k / M)
    zeta = C0 / (2.0 * math.sqrt(k * M))
    wd = wn * math.sqrt(1.0 - zeta ** 2)
    s = zeta * wn
    return np.exp(-s * t) * (x0 * np.cos(wd * t) + (s * x0 / wd) * np.sin(wd * t))


def free_vibration_meta(**extra):
    m = {"format": "tether-trace/1", "experiment": "free_vibration", "tether": {"length_m": L0},
         "payload_mass_kg": M, "gravity_m_s2": G}
    m.update(extra)
    return m


# ---------------------------------------------------------------------------------------------
# fmpy's result CSV (quoted header) of the FMU itself
def test_fmpy_result_csv_of_the_fmu_reads_as_a_trace(tmp_path, fmu_path):
    from fmpy import simulate_fmu
    from fmpy.util import write_csv

    from tether.models import parse_model

    start = dict(parse_model("linear").for_experiment("free_vibration").switches)
    start.update(EA=EA, c0=C0, m=M, g=G, L0=L0, x0=X0, v0=0.0)
    result = simulate_fmu(str(fmu_path), start_time=0.0, stop_time=2.0, output_interval=1e-3,
                          start_values=start, output=["displacement", "tension"])
    csv_file = tmp_path / "fmpy_run.csv"
    write_csv(str(csv_file), result)
    header = csv_file.read_text().splitlines()[0]
    assert header.startswith('"time",') and '"displacement"' in header, header   # fmpy quotes names
    (tmp_path / "fmpy_run.json").write_text(json.dumps(free_vibration_meta()))

    tr = read_trace(csv_file)
    np.testing.assert_array_equal(tr.time, result["time"])
    np.testing.assert_array_equal(tr.measured, result["displacement"])
    assert tr.initial_displacement_m == pytest.approx(X0, abs=1e-12)
    # and the FMU's run is the closed-form oscillator
    assert np.max(np.abs(tr.measured - oscillator(tr.time))) < 1e-6 * X0


# ---------------------------------------------------------------------------------------------
# pandas: the index column, quoted names; DataFrames in memory
def test_pandas_csv_with_index_column_and_quoted_names(tmp_path):
    pd = pytest.importorskip("pandas")
    import csv

    t = np.arange(0, 501) * 2e-3
    df = pd.DataFrame({"time": t, "force": np.sin(t), "displacement": 1e-3 * np.cos(t), "note": 1})
    meta = {"format": "tether-trace/1", "experiment": "forced", "tether": {"length_m": L0}, "payload_mass_kg": M}
    for name, kwargs in (("indexed", {}), ("quoted", {"index": False, "quoting": csv.QUOTE_NONNUMERIC})):
        df.to_csv(tmp_path / f"{name}.csv", **kwargs)
        (tmp_path / f"{name}.json").write_text(json.dumps(meta))
        tr = read_trace(tmp_path / name)
        np.testing.assert_array_equal(tr.time, t)
        np.testing.assert_array_equal(tr.input, np.sin(t))
        np.testing.assert_array_equal(tr.measured, 1e-3 * np.cos(t))
    first = (tmp_path / "indexed.csv").read_text().splitlines()[0]
    assert first.startswith(",time,"), first      # what the index column looks like


def test_unnamed_column_elsewhere_is_still_an_error(write_trace):
    stem = write_trace("bad", write_trace.meta(), csv="time,,displacement\n0,1,0.1\n0.1,2,0.2\n")
    with pytest.raises(TraceError, match=r"line 1, column 2: empty column name"):
        read_trace(stem)


def test_from_dataframe_time_as_column_or_index():
    pd = pytest.importorskip("pandas")
    t = np.arange(0, 101) * 1e-2
    x = oscillator(t)
    df = pd.DataFrame({"time": t, "displacement": x})
    a = Trace.from_dataframe(df, experiment="free_vibration", length_m=L0, payload_mass_kg=M)
    b = Trace.from_dataframe(df.set_index("time"), experiment="free_vibration", length_m=L0, payload_mass_kg=M)
    for tr in (a, b):
        np.testing.assert_array_equal(tr.time, t)
        np.testing.assert_array_equal(tr.measured, x)
        assert tr.initial_displacement_m == X0 and tr.gravity_m_s2 == 9.81
    with pytest.raises(TraceError, match="no column or index named 'time'"):
        Trace.from_dataframe(df.rename(columns={"time": "t"}), experiment="free_vibration", length_m=L0,
                             payload_mass_kg=M)


# ---------------------------------------------------------------------------------------------
# from arrays: simulated against the closed form; checked like files
def test_from_arrays_simulates_the_closed_form(fmu_path):
    from tether.run import simulate

    t = np.arange(0, 3001) * 1e-3
    x = oscillator(t)
    tr = Trace.from_arrays(t, experiment="free_vibration", length_m=L0, payload_mass_kg=M, displacement=x,
                           name="memory")
    assert tr.name == "memory" and tr.rig == "payload"
    r = simulate(tr, "linear", {"EA": EA, "c0": C0})
    assert np.max(np.abs(r.predicted - x)) < 1e-6 * X0


@pytest.mark.parametrize("kwargs, fragments", [
    (dict(displacement=[0.1, 0.2, 0.3], time=[0.0, 0.1, 0.1]), ("'time' at index 2", "strictly increasing")),
    (dict(displacement=[0.1, float("nan"), 0.3]), ("'displacement' at index 1", "not finite")),
    (dict(displacement=[0.1, 0.2]), ("'displacement': 2 samples", "'time' has 3")),
    (dict(), ("displacement missing",)),
    (dict(displacement=[0.1, 0.2, 0.3], payload_mass_kg=-1.0), ("payload_mass_kg", "> 0")),
])
def test_from_arrays_errors_name_the_argument(kwargs, fragments):
    args = dict(time=[0.0, 0.1, 0.2], experiment="free_vibration", length_m=L0, payload_mass_kg=M, name="mine")
    args.update(kwargs)
    with pytest.raises(TraceError) as ei:
        Trace.from_arrays(args.pop("time"), **args)
    msg = str(ei.value)
    assert msg.startswith("mine (in memory)") and "\n" not in msg, msg
    for f in fragments:
        assert f in msg, msg


def test_from_arrays_load_test_needs_its_input():
    with pytest.raises(TraceError, match="load missing; a load_unload trace needs time, load, elongation"):
        Trace.from_arrays([0.0, 1.0], experiment="load_unload", length_m=8.0, elongation=[0.0, 0.01])
    with pytest.raises(TraceError, match="'load' at index 1: value -5.0 is negative"):
        Trace.from_arrays([0.0, 1.0], experiment="load_unload", length_m=8.0, load=[0.0, -5.0],
                          elongation=[0.0, 0.01])


# ---------------------------------------------------------------------------------------------
# compressed CSV
def test_gzipped_csv_reads_like_the_plain_one(write_trace, tmp_path):
    t = np.arange(0, 201) * 1e-2
    stem = write_trace("plain", free_vibration_meta(), {"time": t, "displacement": oscillator(t)})
    plain = read_trace(stem)
    gz = tmp_path / "packed.csv.gz"
    with gzip.open(gz, "wt") as f:
        f.write((tmp_path / "plain.csv").read_text())
    (tmp_path / "packed.json").write_text((tmp_path / "plain.json").read_text())
    for given in (tmp_path / "packed", gz, tmp_path / "packed.json"):
        tr = read_trace(given)
        assert tr.csv_path == gz
        np.testing.assert_array_equal(tr.time, plain.time)
        np.testing.assert_array_equal(tr.measured, plain.measured)


def test_gzipped_csv_broken_is_one_line(tmp_path):
    (tmp_path / "broken.csv.gz").write_bytes(b"\x1f\x8b\x08\x00garbage")
    (tmp_path / "broken.json").write_text(json.dumps(free_vibration_meta()))
    with pytest.raises(TraceError, match=r"broken\.csv\.gz: cannot be read"):
        read_trace(tmp_path / "broken")


# ---------------------------------------------------------------------------------------------
# input-only traces: `tether simulate` predicts without a measured column
def test_simulate_input_only_forced_trace_predicts_as_with_measurements(write_trace, tmp_path, run_cli, fmu_path):
    t = np.arange(0, 2001) * 1e-3
    u = 5.0 * np.sin(2 * np.pi * 1.5 * t)
    meta = write_trace.meta("forced", payload_mass_kg=M, tether={"length_m": L0})
    full = write_trace("full", meta, {"time": t, "force": u, "displacement": np.zeros_like(t)})
    only = write_trace("only", meta, {"time": t, "force": u})
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA, "c0": C0}))
    outs = []
    for stem in (full, only):
        out = tmp_path / f"{stem.name}.out.csv"
        status, _, err = run_cli("simulate", stem, "--params", params, "--out", out)
        assert status == 0, err
        outs.append(np.loadtxt(out, delimiter=",", skiprows=1))
    np.testing.assert_array_equal(outs[0], outs[1])
    assert np.max(np.abs(outs[1][:, 1])) > 1e-4          # it moved


def test_simulate_input_only_free_vibration(write_trace, tmp_path, run_cli, fmu_path):
    t = np.arange(0, 2001) * 1e-3
    params = tmp_path / "p.json"
    params.write_text(json.dumps({"EA": EA, "c0": C0}))
    with_x0 = write_trace("x0", free_vibration_meta(initial_displacement_m=X0), {"time": t})
    out = tmp_path / "o.csv"
    status, _, err = run_cli("simulate", with_x0, "--params", params, "--out", out)
    assert status == 0, err
    pred = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.max(np.abs(pred[:, 1] - oscillator(t))) < 1e-6 * X0
    # without the initial displacement there is nothing to start from: one line, no output
    bare = write_trace("bare", free_vibration_meta(), {"time": t})
    out2 = tmp_path / "o2.csv"
    status, _, err = run_cli("simulate", bare, "--params", params, "--out", out2)
    assert status == 2 and "initial_displacement_m" in err and len(err.strip().splitlines()) == 1, err
    assert not out2.exists()


def test_read_trace_still_requires_the_measured_column_by_default(write_trace):
    stem = write_trace("only", write_trace.meta("forced"), {"time": [0.0, 0.1], "force": [1.0, 2.0]})
    with pytest.raises(TraceError, match="column 'displacement' missing"):
        read_trace(stem)
    assert read_trace(stem, require_measured=False).measured is None
