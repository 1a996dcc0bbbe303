"""tether.traces: reading tether-trace/1 files, defaults, and every error path.

Every error must be ONE line naming the file, the line/column or key, the offending value and what
was expected (trace-format.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tether.traces import TraceError, read_trace

T = np.array([0.0, 0.1, 0.2, 0.3])
X = np.array([0.05, 0.04, 0.01, -0.02])


def good_columns(experiment):
    if experiment == "free_vibration":
        return {"time": T, "displacement": X}
    if experiment == "forced":
        return {"time": T, "force": [1.0, 2.0, 3.0, 4.0], "displacement": X}
    return {"time": T, "load": [0.0, 10.0, 20.0, 5.0], "elongation": [0.0, 0.01, 0.02, 0.005]}


def expect_error(path, *fragments) -> str:
    with pytest.raises(TraceError) as ei:
        read_trace(path)
    msg = str(ei.value)
    assert "\n" not in msg, msg
    for frag in fragments:
        assert frag in msg, f"{frag!r} not in {msg!r}"
    return msg


# ---------------------------------------------------------------------------------------------
# valid traces and defaults
@pytest.mark.parametrize("experiment", ["free_vibration", "forced", "load_unload", "creep"])
def test_valid_trace_each_experiment(write_trace, experiment):
    stem = write_trace("ok", write_trace.meta(experiment), good_columns(experiment))
    tr = read_trace(stem)
    cols = good_columns(experiment)
    assert tr.experiment == experiment
    assert tr.length_m == 16.0
    np.testing.assert_array_equal(tr.time, T)
    measured = "displacement" if experiment in ("free_vibration", "forced") else "elongation"
    assert tr.measured_column == measured
    np.testing.assert_array_equal(tr.measured, np.asarray(cols[measured], float))
    if experiment == "free_vibration":
        assert tr.input_column is None and tr.input is None
    else:
        assert tr.input_column == ("force" if experiment == "forced" else "load")
        np.testing.assert_array_equal(tr.input, np.asarray(cols[tr.input_column], float))
    assert tr.rig == ("payload" if experiment in ("free_vibration", "forced") else "load")


@pytest.mark.parametrize("given", ["stem", "csv", "json"])
def test_either_file_or_stem(write_trace, given):
    stem = write_trace("named", write_trace.meta(), good_columns("free_vibration"))
    path = {"stem": stem, "csv": stem.with_name("named.csv"), "json": stem.with_name("named.json")}[given]
    tr = read_trace(str(path))
    assert tr.csv_path.name == "named.csv" and tr.json_path.name == "named.json"


def test_defaults_free_vibration(write_trace):
    stem = write_trace("fv", write_trace.meta(), good_columns("free_vibration"))
    tr = read_trace(stem)
    assert tr.gravity_m_s2 == 9.81
    assert tr.initial_displacement_m == 0.05      # the first displacement sample
    assert tr.initial_velocity_m_s == 0.0
    assert tr.periodic_samples is None


def test_defaults_forced(write_trace):
    stem = write_trace("fo", write_trace.meta("forced"), good_columns("forced"))
    tr = read_trace(stem)
    assert tr.initial_displacement_m == 0.0       # forced: 0, not the first sample
    assert tr.initial_velocity_m_s == 0.0
    assert tr.gravity_m_s2 == 9.81


def test_explicit_values_override_defaults(write_trace):
    meta = write_trace.meta(gravity_m_s2=0.0, initial_displacement_m=0.1669, initial_velocity_m_s=-0.2)
    tr = read_trace(write_trace("fv", meta, good_columns("free_vibration")))
    assert (tr.gravity_m_s2, tr.initial_displacement_m, tr.initial_velocity_m_s) == (0.0, 0.1669, -0.2)


def test_extra_columns_and_unknown_keys_ignored(write_trace):
    csv = "time,note,displacement,temperature\n0,abc,0.05,20\n0.1,,0.04,21\n0.25,x y,0.01,22\n"
    meta = write_trace.meta(hidden={"effects": ["slack"]}, operator="someone")
    meta["tether"]["diameter_mm"] = 1.5
    tr = read_trace(write_trace("extra", meta, csv=csv))
    np.testing.assert_array_equal(tr.time, [0, 0.1, 0.25])        # non-uniform sampling is fine
    np.testing.assert_array_equal(tr.measured, [0.05, 0.04, 0.01])


def test_periodic_samples(write_trace):
    t = np.arange(8) * 0.5
    cols = {"time": t, "force": np.sin(t), "displacement": np.cos(t)}
    tr = read_trace(write_trace("per", write_trace.meta("forced", periodic_samples=4), cols))
    assert tr.periodic_samples == 4


def test_windows_line_endings_and_trailing_newlines(write_trace):
    csv = "time,displacement\r\n0,0.05\r\n0.1,0.04\r\n\r\n\n"
    tr = read_trace(write_trace("crlf", write_trace.meta(), csv=csv))
    assert len(tr) == 2


# ---------------------------------------------------------------------------------------------
# JSON errors
def test_missing_format(write_trace):
    meta = write_trace.meta()
    del meta["format"]
    stem = write_trace("t", meta, good_columns("free_vibration"))
    expect_error(stem, "t.json", "'format'", "missing", "tether-trace/1")


def test_unknown_format(write_trace):
    stem = write_trace("t", write_trace.meta(format="tether-trace/2"), good_columns("free_vibration"))
    expect_error(stem, "t.json", "'format'", '"tether-trace/2"', "expected \"tether-trace/1\"")


def test_missing_experiment(write_trace):
    meta = write_trace.meta()
    del meta["experiment"]
    stem = write_trace("t", meta, good_columns("free_vibration"))
    expect_error(stem, "t.json", "'experiment'", "missing", "free_vibration, forced, load_unload, creep")


def test_unknown_experiment(write_trace):
    stem = write_trace("t", write_trace.meta(experiment="tensile"), good_columns("free_vibration"))
    expect_error(stem, "t.json", "'experiment'", '"tensile"', "free_vibration, forced, load_unload, creep")


def test_missing_tether(write_trace):
    meta = write_trace.meta()
    del meta["tether"]
    expect_error(write_trace("t", meta, good_columns("free_vibration")), "t.json", "'tether'", "missing", "length_m")


def test_missing_length(write_trace):
    meta = write_trace.meta(tether={"diameter_mm": 1.5})
    expect_error(write_trace("t", meta, good_columns("free_vibration")),
                 "t.json", "'tether.length_m'", "missing", "> 0")


@pytest.mark.parametrize("value, shown", [(0, "0"), (-16.0, "-16.0"), ("16", '"16"'), (None, "null"),
                                          (True, "true")])
def test_bad_length(write_trace, value, shown):
    meta = write_trace.meta(tether={"length_m": value})
    expect_error(write_trace("t", meta, good_columns("free_vibration")),
                 "t.json", "'tether.length_m'", f"value {shown}", "expected a number > 0")


@pytest.mark.parametrize("experiment", ["free_vibration", "forced"])
def test_missing_payload_mass(write_trace, experiment):
    meta = write_trace.meta(experiment)
    del meta["payload_mass_kg"]
    expect_error(write_trace("t", meta, good_columns(experiment)),
                 "t.json", "'payload_mass_kg'", "missing", experiment)


@pytest.mark.parametrize("experiment", ["load_unload", "creep"])
def test_payload_mass_not_needed_for_load_tests(write_trace, experiment):
    tr = read_trace(write_trace("t", write_trace.meta(experiment), good_columns(experiment)))
    assert tr.payload_mass_kg is None


@pytest.mark.parametrize("key, value, shown, expected", [
    ("payload_mass_kg", -4.3, "-4.3", "> 0"),
    ("payload_mass_kg", "4.3", '"4.3"', "expected a number"),
    ("gravity_m_s2", -9.81, "-9.81", ">= 0"),
    ("initial_displacement_m", "0.1", '"0.1"', "expected a number"),
    ("initial_velocity_m_s", [0], "[0]", "expected a number"),
])
def test_bad_numeric_keys(write_trace, key, value, shown, expected):
    meta = write_trace.meta(**{key: value})
    expect_error(write_trace("t", meta, good_columns("free_vibration")), "t.json", f"'{key}'", shown, expected)


def test_invalid_json(write_trace):
    stem = write_trace("t", json_text='{"format": "tether-trace/1",\n "experiment": }', columns=good_columns("forced"))
    expect_error(stem, "t.json", "line 2", "invalid JSON")


def test_json_not_an_object(write_trace):
    stem = write_trace("t", json_text="[1, 2]", columns=good_columns("forced"))
    expect_error(stem, "t.json", "list", "expected a JSON object")


def test_empty_json(write_trace):
    stem = write_trace("t", json_text="", columns=good_columns("forced"))
    expect_error(stem, "t.json", "empty file")


def test_missing_files(write_trace, tmp_path):
    stem = write_trace("only_csv", columns=good_columns("free_vibration"))
    expect_error(stem, "only_csv.json", "not found", "side by side")
    expect_error(tmp_path / "nothing.csv", "nothing.csv", "nothing.json", "not found")


# ---------------------------------------------------------------------------------------------
# periodic_samples
@pytest.mark.parametrize("P, fragments", [
    (3, ("does not divide", "8 samples", "value 3")),
    (16, ("larger than the record", "8 samples", "value 16")),
    (2.5, ("2.5", "positive whole number",)),
    (0, ("value 0", "positive whole number")),
    ("4", ('"4"', "positive whole number")),
])
def test_bad_periodic_samples(write_trace, P, fragments):
    t = np.arange(8) * 0.5
    cols = {"time": t, "force": np.sin(t), "displacement": np.cos(t)}
    stem = write_trace("p", write_trace.meta("forced", periodic_samples=P), cols)
    expect_error(stem, "p.json", "'periodic_samples'", *fragments)


def test_periodic_free_vibration_rejected(write_trace):
    t = np.arange(8) * 0.5
    stem = write_trace("p", write_trace.meta(periodic_samples=4), {"time": t, "displacement": np.cos(t)})
    expect_error(stem, "p.json", "'periodic_samples'", "free_vibration")


# ---------------------------------------------------------------------------------------------
# CSV errors
def test_empty_csv(write_trace):
    expect_error(write_trace("t", write_trace.meta(), csv=""), "t.csv", "empty file", "time, displacement")


def test_header_only(write_trace):
    expect_error(write_trace("t", write_trace.meta(), csv="time,displacement\n"), "t.csv", "only a header")


def test_single_sample(write_trace):
    expect_error(write_trace("t", write_trace.meta(), csv="time,displacement\n0,0.1\n"),
                 "t.csv", "only one sample", "at least 2")


@pytest.mark.parametrize("experiment, csv_header, missing", [
    ("free_vibration", "time,elongation", "'displacement'"),
    ("forced", "time,displacement", "'force'"),
    ("forced", "time,force", "'displacement'"),
    ("load_unload", "time,elongation", "'load'"),
    ("load_unload", "time,load,displacement", "'elongation'"),
    ("creep", "time,force,displacement", "'load', 'elongation'"),
])
def test_missing_columns(write_trace, experiment, csv_header, missing):
    ncol = csv_header.count(",") + 1
    rows = "\n".join(",".join([str(i)] + ["1"] * (ncol - 1)) for i in range(3))
    stem = write_trace("t", write_trace.meta(experiment), csv=f"{csv_header}\n{rows}\n")
    msg = expect_error(stem, "t.csv", "line 1", missing, f"a {experiment} trace needs", f"found {csv_header.replace(',', ', ')}")
    assert "missing" in msg


def test_first_column_must_be_time(write_trace):
    stem = write_trace("t", write_trace.meta(), csv="displacement,time\n0.1,0\n0.2,1\n")
    expect_error(stem, "t.csv", "line 1", "'displacement'", "'time'")


def test_duplicate_column(write_trace):
    stem = write_trace("t", write_trace.meta(), csv="time,displacement,displacement\n0,1,1\n1,2,2\n")
    expect_error(stem, "t.csv", "line 1", "'displacement'", "twice")


@pytest.mark.parametrize("cell", ["abc", "", "1,5e-3x", "0x10", "1_0"])
def test_non_numeric_cell(write_trace, cell):
    if "," in cell:  # keep the row rectangular: the bad cell is 5e-3x
        cell = "5e-3x"
    csv = f"time,displacement\n0,0.05\n0.1,0.04\n0.2,{cell}\n0.3,0.01\n"
    msg = expect_error(write_trace("t", write_trace.meta(), csv=csv), "t.csv", "line 4", "column 'displacement'",
                       f"value '{cell}'", "not a number")
    assert "expected" in msg


def test_non_numeric_time(write_trace):
    csv = "time,displacement\n0,0.05\nnoon,0.04\n"
    expect_error(write_trace("t", write_trace.meta(), csv=csv), "t.csv", "line 3", "column 'time'", "'noon'")


@pytest.mark.parametrize("cell", ["nan", "NaN", "inf", "-Infinity", "1e400"])
def test_nan_inf(write_trace, cell):
    csv = f"time,force,displacement\n0,1,0\n0.1,{cell},0\n0.2,1,0\n"
    expect_error(write_trace("t", write_trace.meta("forced"), csv=csv), "t.csv", "line 3", "column 'force'",
                 f"'{cell}'", "not finite")


def test_nan_in_measured_column_slow_path(write_trace):
    # an extra text column forces the line-by-line parser; the check must be the same
    csv = "time,displacement,note\n0,0.05,a\n0.1,nan,b\n"
    expect_error(write_trace("t", write_trace.meta(), csv=csv), "t.csv", "line 3", "'displacement'", "'nan'",
                 "not finite")


@pytest.mark.parametrize("times, line, later, earlier", [
    ([0, 0.1, 0.1, 0.3], 4, "0.1", "0.1"),          # repeated
    ([0, 0.2, 0.1, 0.3], 4, "0.1", "0.2"),          # decreasing
])
def test_time_not_increasing(write_trace, times, line, later, earlier):
    stem = write_trace("t", write_trace.meta(), {"time": times, "displacement": X})
    msg = expect_error(stem, "t.csv", f"line {line}", f"time {later} after {earlier} on line {line - 1}",
                       "strictly increasing")
    assert msg


@pytest.mark.parametrize("row, what", [("0.2,0.01,7", "has 3 cells"), ("0.2", "has 1 cell;"), ("", "is empty")])
def test_ragged_rows(write_trace, row, what):
    csv = f"time,displacement\n0,0.05\n0.1,0.04\n{row}\n0.3,0.01\n"
    expect_error(write_trace("t", write_trace.meta(), csv=csv), "t.csv", f"line 4 {what}", "expected 2 cells")


def test_negative_load(write_trace):
    csv = "time,load,elongation\n0,0,0\n1,10,0.01\n2,-0.5,0\n"
    expect_error(write_trace("t", write_trace.meta("load_unload"), csv=csv), "t.csv", "line 4", "'load'", "-0.5",
                 ">= 0")


def test_error_carries_path(write_trace):
    stem = write_trace("t", write_trace.meta(format="x"), good_columns("free_vibration"))
    with pytest.raises(TraceError) as ei:
        read_trace(stem)
    assert ei.value.path.endswith("t.json")


def test_large_file_fast_path_matches_slow_path(write_trace):
    n = 5000
    t = np.cumsum(np.full(n, 1e-3))
    x = np.sin(t * 7.3) * 1e-3
    fast = read_trace(write_trace("fast", write_trace.meta(), {"time": t, "displacement": x}))
    # same numbers with a text column: line-by-line parser
    lines = ["time,displacement,tag"] + [f"{a!r},{b!r},r{i}" for i, (a, b) in enumerate(zip(t.tolist(), x.tolist()))]
    slow = read_trace(write_trace("slow", write_trace.meta(), csv="\n".join(lines) + "\n"))
    np.testing.assert_array_equal(fast.time, slow.time)
    np.testing.assert_array_equal(fast.measured, slow.measured)
    np.testing.assert_array_equal(fast.time, t)
    json.loads(fast.json_path.read_text())
