"""tether sweep (issue 28): campaigns on Dask.

Independent expectations: a serial run in this process (the rows of any cluster must equal it bit
for bit), closed forms of a linear tether (static balance; free fall while slack), the fit's own
standard errors (the spread of the draws) and the noise the generator added (the band's coverage).
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REF = Path(__file__).resolve().parents[1] / "reference_results"
#: the issue's sweep: 64 full-model runs on a short bundled record (20 s at 200 Hz)
TRACE = REF / "freevib_full_0p1184"
GRID = ["--vary", "a1=900:1500:8", "--vary", "c0=1:5:8"]


def tether(*args, check=True, **kw) -> subprocess.CompletedProcess:
    p = subprocess.run([sys.executable, "-m", "tether", *map(str, args)], capture_output=True, text=True, **kw)
    if check:
        assert p.returncode == 0, p.stderr
    return p


def serial_file(trace, model, base, vary) -> str:
    """The sweep's file computed run by run in this process, without Dask."""
    from tether.sweep import format_row, grid_plan, run_one
    from tether.traces import read_trace

    plan = grid_plan(read_trace(trace), model, base, vary)
    lines = [",".join(plan.columns) + "\n"]
    for i, values in enumerate(plan.runs):
        outputs, _ = run_one(plan.trace, plan.model, plan.base, dict(zip(plan.names, values)))
        lines.append(format_row(i, values, outputs))
    return "".join(lines)


@pytest.fixture(scope="module")
def embedded_rows(tmp_path_factory) -> Path:
    """The issue's 64-run sweep on the embedded default (a local cluster, one worker per core)."""
    out = tmp_path_factory.mktemp("embedded") / "rows.csv"
    tether("sweep", TRACE, "--model", "full", *GRID, "--out", out)
    return out


# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def dask_cluster(tmp_path_factory):
    """`dask scheduler` and two `dask worker` processes of this environment on 127.0.0.1."""
    from tether.campaign import spawned_cluster

    with spawned_cluster(tmp_path_factory.mktemp("dask"), workers=2) as address:
        yield address


def test_rows_on_a_scheduler_and_two_workers_equal_the_embedded_and_a_serial_run(dask_cluster, embedded_rows,
                                                                                 tmp_path):
    out = tmp_path / "cluster.csv"
    p = tether("sweep", TRACE, "--model", "full", *GRID, "--out", out, "--scheduler", dask_cluster)
    assert "2 workers" in p.stderr
    cluster_text = out.read_text()
    assert cluster_text == embedded_rows.read_text()
    assert cluster_text == serial_file(TRACE, "full", {}, GRID[1::2])
    rows = np.genfromtxt(out, delimiter=",", names=True)
    assert len(rows) == 64 and list(rows["run"]) == list(range(64))
    assert sorted(set(rows["a1"])) == pytest.approx(np.linspace(900, 1500, 8))
    assert sorted(set(rows["c0"])) == pytest.approx(np.linspace(1, 5, 8))
    # the runs differ: more damping, less motion
    assert rows["rms_displacement"][rows["c0"] == 5.0].max() < rows["rms_displacement"][rows["c0"] == 1.0].min()
    # the tasks ran on the workers, each with the FMU the client sent (not a build of its own)
    from dask.distributed import Client

    from tether.campaign import fmu_bytes

    _, data = fmu_bytes()
    with Client(dask_cluster) as c:
        paths = c.run(lambda: os.environ.get("KT_FMU"))
    assert len(paths) == 2
    for path in paths.values():
        assert path and Path(path).read_bytes() == data


def test_validate_and_discover_each_run_on_the_scheduler(dask_cluster, tmp_path):
    """validate --scheduler: the same numbers as in this process; discover --each: one discovery
    per record on the workers, each naming the law its generator used (the cubic's nonlinear
    stiffness) within the noise, and the summary table."""
    traces = [REF / "stiffness_8m", REF / "stiffness_12m"]
    tether("validate", *traces, "--scheduler", dask_cluster, "--report", tmp_path / "cluster")
    tether("validate", *traces, "--report", tmp_path / "serial")
    rows = [json.loads((tmp_path / d / "validation.json").read_text())["traces"] for d in ("cluster", "serial")]
    assert rows[0] == rows[1] and len(rows[0]) == 2

    out = tmp_path / "each"
    p = tether("discover", "--each", *traces, "--out-dir", out, "--scheduler", dask_cluster)
    summary = np.genfromtxt(out / "summary.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert [str(n) for n in summary["trace"]] == ["stiffness_8m", "stiffness_12m"]
    # the verdicts: the stiffness present; damping and slack undetermined in a quasi-static load test
    assert [str(v) for v in summary["present"]] == ["nonlinear_stiffness"] * 2
    assert all(set(str(v).split("+")) == {"nonlinear_damping", "slack"} for v in summary["undetermined"])
    for tr in traces:
        doc = json.loads((out / f"{tr.name}.json").read_text())
        assert doc["added_effects"] == ["nonlinear_stiffness"] and doc["rmse_final_over_noise"] < 1.2
        assert tr.name in p.stdout
    p = tether("discover", "--each", traces[0], "--json", tmp_path / "x.json", check=False)
    assert p.returncode == 2 and "--out-dir" in p.stderr
    # resumed: the records done are kept, nothing runs, the summary is the same
    summary = (out / "summary.csv").read_bytes()
    (out / "summary.csv").unlink()
    p = tether("discover", "--each", *traces, "--out-dir", out, "--scheduler", "tcp://127.0.0.1:1", "--resume")
    assert "2 of 2 records done before" in p.stderr and (out / "summary.csv").read_bytes() == summary


# ---------------------------------------------------------------------------------------------
def test_a_killed_sweep_resumed_gives_the_file_of_one_never_killed(embedded_rows, tmp_path):
    out = tmp_path / "rows.csv"
    series = tmp_path / "series"
    # one worker and the series written: slow enough to be caught halfway
    cmd = [sys.executable, "-m", "tether", "sweep", str(TRACE), "--model", "full", *GRID, "--out", str(out),
           "--workers", "1", "--series", str(series)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            if out.is_file() and out.read_text().count("\n") >= 2:     # the header and a row at least
                break
            time.sleep(0.005)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)                      # the sweep and its cluster
        proc.wait()
    assert proc.returncode == -signal.SIGKILL, "the sweep ended before it could be killed"
    text = out.read_text()
    partial = text[:text.rfind("\n") + 1].splitlines()[1:]     # complete lines: a kill may cut the last
    assert 1 <= len(partial) < 64
    assert (tmp_path / "rows.csv.sweep.json").is_file()

    p = tether("sweep", TRACE, "--model", "full", *GRID, "--out", out, "--workers", "1", "--series", series,
               "--resume")
    assert f"{64 - len(partial)} to run" in p.stderr or f"{len(partial)} done before" in p.stderr, p.stderr
    assert out.read_bytes() == embedded_rows.read_bytes()
    assert json.loads((tmp_path / "rows.csv.sweep.json").read_text())["finished"] is True
    assert len(list(series.glob("run_*.parquet"))) == 64
    # a run's series is the serial run's, sample for sample
    import pyarrow.parquet as pq

    from tether.sweep import grid_plan, run_one
    from tether.traces import read_trace

    plan = grid_plan(read_trace(TRACE), "full", {}, GRID[1::2])
    _, (t, y, T) = run_one(plan.trace, plan.model, plan.base, dict(zip(plan.names, plan.runs[37])), series=True)
    table = pq.read_table(series / "run_000037.parquet")
    assert table.column_names == ["time", "displacement", "tension"]
    for name, want in zip(table.column_names, (t, y, T)):
        assert np.array_equal(table.column(name).to_numpy(), want)
    # a finished sweep resumed runs nothing and leaves its file as it was
    p = tether("sweep", TRACE, "--model", "full", *GRID, "--out", out, "--resume")
    assert "64 done before, 0 to run" in p.stderr and out.read_bytes() == embedded_rows.read_bytes()


def test_resume_refuses_a_different_sweep_and_names_what_differs(tmp_path):
    out = tmp_path / "rows.csv"
    out.write_text("run,a1,c0\n")
    (tmp_path / "rows.csv.sweep.json").write_text(json.dumps({"format": "tether-sweep-state/1", "model": "linear"}))
    before = out.read_bytes()
    p = tether("sweep", TRACE, "--model", "full", *GRID, "--out", out, "--resume", check=False)
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "key 'trace'" in p.stderr and "rows.csv.sweep.json" in p.stderr
    assert out.read_bytes() == before


@pytest.mark.parametrize("vary, message", [
    ("a1=900:1500", "expected NAME=LO:HI:N"),
    ("a1=900:x:8", "must be numbers"),
    ("nonsense=1:2:3", "not a parameter of the FMU"),
    ("EA=1:2:3", "not used by the model 'full'"),
    ("c0=-1:5:8", "below the minimum"),
    ("load_scale=1:2:2", "vary"),
    ("a1=900:-5:8", "a1 = -5"),              # the FMU refuses it (status 1): the grid's far corner is tried first
])
def test_bad_vary_exits_in_one_line_and_writes_nothing(tmp_path, vary, message):
    out = tmp_path / "rows.csv"
    p = tether("sweep", TRACE, "--model", "full", "--vary", vary, "--out", out, check=False)
    assert p.returncode == (1 if "-5" in vary else 2)
    assert p.stderr.count("\n") == 1 and message in p.stderr, p.stderr
    assert not out.exists() and not (tmp_path / "rows.csv.sweep.json").exists()


def test_a_run_the_fmu_refuses_gives_a_row_of_nan_and_its_error_not_the_end_of_the_sweep():
    from tether.sweep import OUTPUTS, format_row, run_chunk, run_one
    from tether.traces import read_trace

    tr = read_trace(TRACE)
    got = run_chunk([(0, [900.0]), (1, [-5.0]), (2, [1500.0])], tr, "full", {}, ["a1"], None, False)
    assert [g[0] for g in got] == [0, 1, 2]
    assert got[0][1] == run_one(tr, "full", {}, {"a1": 900.0})[0] and got[0][3] is None
    assert all(math.isnan(v) for v in got[1][1]) and len(got[1][1]) == len(OUTPUTS)
    assert "a1 = -5" in got[1][3] and "\n" not in got[1][3]
    assert format_row(1, [-5.0], got[1][1]) == "1,-5.0," + ",".join(["nan"] * len(OUTPUTS)) + "\n"


# ---------------------------------------------------------------------------------------------
def test_outputs_match_the_closed_forms_of_a_linear_tether(write_trace):
    """At rest at its balance: tension m g, elongation m g L0 / EA for every varied L0 and m.
    Released from above the slack point without damping: free fall while slack, so slack_time
    is the time the closed-form motion spends with a negative stretch."""
    from tether.sweep import grid_plan, run_one
    from tether.traces import read_trace

    EA, g = 5e4, 9.81
    t = np.linspace(0.0, 5.0, 1001)
    meta = {"format": "tether-trace/1", "experiment": "free_vibration", "tether": {"length_m": 10.0},
            "payload_mass_kg": 2.0, "gravity_m_s2": g, "initial_displacement_m": 0.0, "initial_velocity_m_s": 0.0}
    tr = read_trace(write_trace("rest", meta, {"time": t, "displacement": np.zeros_like(t)}))
    plan = grid_plan(tr, "linear+slack", {"EA": EA, "c0": 0.0}, ["L0=5:20:3", "m=1:4:2"])
    for values in plan.runs:
        L0, m = values
        row, _ = run_one(tr, plan.model, plan.base, dict(zip(plan.names, values)))
        max_t, min_t, peak, rms, slack, final, rmse = row
        assert max_t == pytest.approx(m * g, rel=1e-9) and min_t == pytest.approx(m * g, rel=1e-9)
        assert final == pytest.approx(m * g * L0 / EA, rel=1e-9)
        assert peak < 1e-9 and slack == 0.0 and rmse == pytest.approx(rms, abs=1e-12)

    m, L0 = 2.0, 10.0
    k = EA / L0
    s = m * g / k                                  # static stretch
    A = 3.0 * s                                    # released 2 s above the slack point
    t1 = math.sqrt(2.0 * (A - s) / g)              # free fall to the slack point
    w = math.sqrt(k / m)
    R = math.hypot(s, g * t1 / w)                  # amplitude about the balance while taut
    period = 2.0 * t1 + (math.pi + 2.0 * math.asin(s / R)) / w
    phase = np.mod(t, period)
    slack_now = (phase < t1) | (phase > period - t1)
    expected = float(np.sum(np.diff(t)[slack_now[:-1]]))
    row, _ = run_one(tr, "linear+slack", {"EA": EA, "c0": 0.0}, {"x0": -A})
    assert row[2] == pytest.approx(A, rel=1e-6)                       # peak: the release point
    assert row[1] == 0.0                                              # min tension: slack
    # 2.48 s slack in 5 s; the sample grid may place a slack entry or exit one interval off
    assert expected > 2.0 and abs(row[4] - expected) <= 2 * (t[1] - t[0]) + 1e-12


def test_the_load_scale_scales_a_linear_load_test():
    """Load rig, linear law: tension = load, elongation = load L0 / EA, for the scaled load."""
    from tether.sweep import grid_plan, run_one
    from tether.traces import read_trace

    tr = read_trace(REF / "stiffness_8m")
    EA = 5e4
    plan = grid_plan(tr, "linear", {"EA": EA}, ["load_scale=0.5:2:2", "L0=4:8:2"])
    assert plan.names == ["load_scale", "L0"] and len(plan.runs) == 4
    for scale, L0 in plan.runs:
        row, _ = run_one(tr, plan.model, plan.base, {"load_scale": scale, "L0": L0})
        assert row[0] == pytest.approx(scale * tr.input.max(), rel=1e-12)
        assert row[2] == pytest.approx(scale * tr.input.max() * L0 / EA, rel=1e-9)


# ---------------------------------------------------------------------------------------------
def test_draws_keep_inside_bounds_and_repeat_with_the_seed():
    from tether.sweep import draw_samples

    names = ["a", "b"]
    values, errors = np.array([1.0, 10.0]), np.array([1.0, 1.0])
    corr = np.array([[1.0, 0.8], [0.8, 1.0]])
    d1 = draw_samples(names, values, errors, corr, 2000, 7, log_scaled=["b"], bounds={"a": (0.0, math.inf)})
    d2 = draw_samples(names, values, errors, corr, 2000, 7, log_scaled=["b"], bounds={"a": (0.0, math.inf)})
    assert np.array_equal(d1, d2) and d1.shape == (2000, 2)
    # a ~ N(1, 1) truncated at zero: mean 1 + phi(1) / Phi(1)
    assert d1[:, 0].min() >= 0.0
    assert d1[:, 0].mean() == pytest.approx(1.0 + 0.24197 / 0.84134, abs=0.05)
    d3 = draw_samples(names, values, errors, corr, 2000, 8, log_scaled=["b"])
    assert np.std(np.log(d3[:, 1])) == pytest.approx(0.1, rel=0.06)  # b: log scale, se / value = 0.1
    assert np.mean(np.log(d3[:, 1])) == pytest.approx(math.log(10.0), abs=0.01)
    assert np.corrcoef(d3[:, 0], np.log(d3[:, 1]))[0, 1] == pytest.approx(0.8, abs=0.04)
    assert not np.array_equal(d3, draw_samples(names, values, errors, corr, 2000, 9))


def test_samples_from_a_full_model_fit_spread_as_its_errors_and_the_band_covers_the_record(tmp_path):
    """A full-model fit within its noise (c2 held at the generator's 0: the data cannot tell it
    from zero); 100 draws: each parameter's spread within 20 % of its standard error; the 5-95 %
    prediction band holds about 90 % of the measured samples (the generator's noise sigma)."""
    trace = REF / "freevib_full_0p1669"
    P = tmp_path / "P.json"
    tether("fit", trace, "--model", "full+slack", "--free", "a1,a2,a3,c0,c1,bw_A,bw_beta,bw_gamma", "--out", P)
    fit = json.loads(P.read_text())
    sigma = json.loads(trace.with_suffix(".json").read_text())["synthetic"]["noise"]["sigma_m"]
    assert fit["rms"] <= 1.05 * sigma                                  # within its noise

    out, report = tmp_path / "samples.csv", tmp_path / "report"
    p = tether("sweep", trace, "--params", P, "--samples", 100, "--seed", 1, "--out", out, "--report", report)
    rows = np.genfromtxt(out, delimiter=",", names=True)
    assert len(rows) == 100
    for name, se in fit["std_error"].items():
        spread = float(np.std(rows[name], ddof=1))
        assert abs(spread / se - 1.0) <= 0.2, (name, spread, se)
    band = json.loads((report / "band.json").read_text())
    print(f"band coverage {band['coverage']:.3f} (noise {band['noise_sigma']:.3g})")
    assert 0.85 <= band["coverage"] <= 0.95
    assert "% of the measured samples inside" in p.stdout
    for f in ("index.html", "band.png", "distributions.png", "band.csv"):
        assert (report / f).is_file()
    assert len(list((report / "series").glob("run_*.parquet"))) == 100


def test_an_unreachable_scheduler_is_one_line_and_leaves_the_old_file(tmp_path):
    out = tmp_path / "rows.csv"
    out.write_text("an earlier sweep\n")
    p = tether("sweep", TRACE, "--model", "full", "--vary", "a1=900:1500:2", "--out", out,
               "--scheduler", "tcp://127.0.0.1:1", check=False)
    assert p.returncode == 1 and "tether: error: --scheduler tcp://127.0.0.1:1: cannot reach" in p.stderr
    assert out.read_text() == "an earlier sweep\n" and not (tmp_path / "rows.csv.sweep.json").exists()
    p = tether("validate", TRACE, "--scheduler", "nowhere", check=False)
    assert p.returncode == 2 and "--scheduler" in p.stderr


def test_the_prediction_band_is_the_quantiles_of_the_noisy_runs():
    """Runs that agree: the band is the noise's own 5/95 % (+-1.6449 sigma); runs at +-a: the
    mixture's 95 % solves (Phi((y - a)/s) + Phi((y + a)/s)) / 2 = 0.95, checked by the CDF itself."""
    from scipy.special import ndtr

    from tether.sweep_report import coverage, mixture_quantiles

    s = 0.002
    band = mixture_quantiles(np.zeros((50, 3)), s)
    assert band[0] == pytest.approx(-1.6448536 * s, rel=1e-6) and band[2] == pytest.approx(1.6448536 * s, rel=1e-6)
    assert np.all(np.abs(band[1]) < 1e-12)
    a = 3 * s
    Y = np.array([[a], [-a]])
    q = mixture_quantiles(Y, s)[:, 0]
    for p, y in zip((0.05, 0.5, 0.95), q):
        assert (ndtr((y - a) / s) + ndtr((y + a) / s)) / 2 == pytest.approx(p, abs=1e-9)
    assert coverage(np.array([0.0, 1.0, -1.0, 0.001]), np.array([[-0.5] * 4, [0.0] * 4, [0.5] * 4])) == 0.5
