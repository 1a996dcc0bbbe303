"""The command line's manners (issue 26): help everywhere, --quiet/--verbose/--debug, progress,
no traceback ever, a quiet broken pipe, units in the tables, validate's exit status, lazy imports.

Expectations are the documented behaviour: argparse's exit status 0 for help, the exit statuses of
`tether --help`, the units of modelDescription.xml, and the normalized RMS errors of the bundled
reference traces (their own model at the noise, the linear model far off).
"""

from __future__ import annotations

import json
import os
import pty
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REF = Path(__file__).resolve().parents[1] / "reference_results"
TETHER = Path(sys.executable).with_name("tether")
SUBCOMMANDS = ["simulate", "validate", "fit", "discover", "demo"]


def run(*argv, stdin=subprocess.DEVNULL, **kw):
    return subprocess.run([str(a) for a in argv], capture_output=True, text=True, stdin=stdin, **kw)


# ---------------------------------------------------------------------------------------------
# 1. help everywhere
@pytest.mark.parametrize("argv", [
    [TETHER, "--help"], [TETHER, "-h"], [sys.executable, "-m", "tether", "--help"],
    *([TETHER, c, "--help"] for c in SUBCOMMANDS), *([sys.executable, "-m", "tether", c, "-h"] for c in SUBCOMMANDS),
], ids=lambda a: " ".join(Path(str(x)).name for x in a))
def test_help_exits_0(argv):
    p = run(*argv)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("usage: tether"), p.stdout[:200]
    assert p.stderr == ""


def test_fit_help_shows_its_percent_sign():
    p = run(TETHER, "--help")
    assert re.search(r"95 %\s+intervals", p.stdout)
    assert "--quiet" in p.stdout and "--verbose" in p.stdout and "--debug" in p.stdout


# ---------------------------------------------------------------------------------------------
# 2. --quiet, --verbose, progress
@pytest.fixture
def fv_trace(write_trace):
    """A free-vibration trace of a damped linear oscillator (EA 3500 N, c0 1.5 N s/m, 4.3 kg, 16 m)."""
    m, L0, EA, c0 = 4.3, 16.0, 3500.0, 1.5
    t = np.arange(0, 2001) * 2e-3
    k = EA / L0
    wn, zeta = np.sqrt(k / m), c0 / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta ** 2)
    x = 0.05 * np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))
    x += np.random.default_rng(1).normal(0, 1e-5, t.size)
    return write_trace("fv", write_trace.meta(payload_mass_kg=m, tether={"length_m": L0}),
                       {"time": t, "displacement": x})


@pytest.mark.parametrize("where", ["before", "after"])
def test_quiet_says_nothing_on_stderr(fv_trace, tmp_path, fmu_path, where):
    out = tmp_path / "p.json"
    args = ["fit", fv_trace, "--model", "linear", "--out", out]
    argv = ["--quiet", *args] if where == "before" else [*args, "-q"]
    p = run(TETHER, *argv)
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""
    assert "EA" in p.stdout and out.is_file()


def test_default_and_verbose_progress_without_terminal(fv_trace, tmp_path, fmu_path):
    out = tmp_path / "p.json"
    normal = run(TETHER, "fit", fv_trace, "--model", "linear", "--out", out)
    verbose = run(TETHER, "--verbose", "fit", fv_trace, "--model", "linear", "--out", out)
    assert normal.returncode == 0 and verbose.returncode == 0, normal.stderr + verbose.stderr
    assert "fitting linear to fv" in normal.stderr and "\r" not in normal.stderr    # plain lines, no bar
    iterations = [line for line in verbose.stderr.splitlines() if "iteration" in line]
    assert len(iterations) >= 3                         # every LM iteration on its own line
    assert len(verbose.stderr.splitlines()) > len(normal.stderr.splitlines())
    fitted = json.loads(out.read_text())["parameters"]
    assert fitted["EA"] == pytest.approx(3500.0, rel=1e-3)


def test_progress_bar_with_time_left_on_a_terminal(fv_trace, tmp_path, fmu_path):
    # stderr a terminal: a tqdm bar with the elapsed time and the time left
    master, slave = pty.openpty()
    out = tmp_path / "p.json"
    proc = subprocess.Popen([str(TETHER), "fit", str(fv_trace), "--model", "linear", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=slave, stdin=subprocess.DEVNULL)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:             # the pty is closed when the process ends
            break
        if not data:
            break
        chunks.append(data)
    proc.stdout.read()
    assert proc.wait() == 0
    os.close(master)
    tty = b"".join(chunks).decode(errors="replace")
    assert re.search(r"fit:\s+\d+%\|", tty), tty
    assert "elapsed" in tty and " left" in tty
    assert "fitting linear to fv" in tty


def test_progress_fraction_grows_to_one():
    from tether.cli.fit import fit_fraction
    from tether.fit import FitProgress

    seq = [FitProgress("a", 0, 2, -1, float("nan"), 0, 0.0)]
    seq += [FitProgress("a", 0, 2, i, 1.0, i, 0.0, horizon=f"{h}/3") for h in (1, 2, 3) for i in range(5)]
    second = len(seq)
    seq += [FitProgress("b", 1, 2, -1, float("nan"), 0, 0.0)]
    seq += [FitProgress("b", 1, 2, i, 1.0, i, 0.0, start=s) for s in (0, 1) for i in range(40)]
    f = [fit_fraction(p, n_starts=2) for p in seq]
    assert f[0] == 0.0 and all(b >= a for a, b in zip(f, f[1:])) and 0.99 < f[-1] < 1.0
    assert f[second] == 0.5                  # the second stage starts half way
    assert f[second + 41] >= 0.75            # its second start begins three quarters in


# ---------------------------------------------------------------------------------------------
# 3. no traceback ever
def test_broken_pipe_ends_quietly(fv_trace, tmp_path, fmu_path):
    # `tether fit ... | head -1` with head gone before the table is printed
    out = tmp_path / "p.json"
    proc = subprocess.Popen([str(TETHER), "fit", str(fv_trace), "--model", "linear", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    status = proc.wait()
    assert "Traceback" not in err and "BrokenPipe" not in err and "Exception ignored" not in err, err
    assert status == 141
    assert json.loads(out.read_text())["model"] == "linear"        # the file was written first


def test_broken_pipe_in_help():
    proc = subprocess.Popen([str(TETHER), "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait() in (0, 141) and err == "", err


def test_internal_error_is_one_line_and_debug_shows_the_trace(monkeypatch, run_cli, fv_trace, tmp_path):
    import tether.cli.simulate as sim

    def broken(args):
        return {}["no such key"]

    monkeypatch.setattr(sim, "run", broken)
    status, out, err = run_cli("simulate", fv_trace, "--out", tmp_path / "o.csv")
    assert status == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err
    assert lines[0].startswith("tether: error: internal error: KeyError") and "--debug" in lines[0]
    status, out, err = run_cli("--debug", "simulate", fv_trace, "--out", tmp_path / "o.csv")
    assert status == 1
    assert "Traceback (most recent call last)" in err and "def broken" not in err and "broken" in err
    assert err.strip().splitlines()[-1].startswith("tether: error: internal error: KeyError")


# ---------------------------------------------------------------------------------------------
# 4. units
def test_fit_table_has_units(fv_trace, tmp_path, run_cli, fmu_path):
    status, out, err = run_cli("fit", fv_trace, "--model", "linear", "--out", tmp_path / "p.json")
    assert status == 0, err
    # the units of modelDescription.xml: EA in N, c0 in N.s/m; the RMS error in the measured unit
    assert re.search(r"^EA\s+N\s+\d", out, re.M), out
    assert re.search(r"^c0\s+N\.s/m\s+\d", out, re.M), out
    assert re.search(r"RMS error [\d.e+-]+ m over 1 trace", out), out
    assert re.search(r"^fv: RMS error [\d.e+-]+ m \(noise estimated from the data [\d.e+-]+ m\)", out, re.M), out


def test_validate_table_has_units(tmp_path, run_cli, fmu_path):
    status, out, err = run_cli("validate", REF / "stiffness_8m", "--report", tmp_path / "r")
    assert status == 0, err
    header = out.splitlines()[0]
    for col in ("RMS error [m]", "NRMSE [-]", "max error [m]", "at [s]", "noise σ [m]"):
        assert col in header, header


# ---------------------------------------------------------------------------------------------
# 5. validate's exit status
def test_validate_exit_status_gates_on_the_tolerance(tmp_path, run_cli, fmu_path):
    loop = REF / "kawabata_12m_3kg"
    # its own model (Kawabata, from the trace's JSON): NRMSE at the noise, ~5e-4
    status, out, err = run_cli("validate", loop, "--report", tmp_path / "own")
    assert status == 0, err
    assert "within the tolerance (NRMSE <= 0.05)" in out
    # the linear model misses the hysteresis loop: NRMSE ~1, far above the default 0.05
    status, out, err = run_cli("validate", loop, "--model", "linear", "--report", tmp_path / "lin")
    assert status == 1, err
    assert "outside the tolerance" in out and "kawabata_12m_3kg" in out
    doc = json.loads((tmp_path / "lin" / "validation.json").read_text())
    assert doc["tolerance"] == {"on": "normalized_rms_error", "max": 0.05}
    assert doc["traces"][0]["within_tolerance"] is False and doc["traces"][0]["normalized_rms_error"] > 0.5
    # a looser tolerance lets the same run pass
    status, out, err = run_cli("validate", loop, "--model", "linear", "--tolerance", "2", "--report", tmp_path / "x")
    assert status == 0, err


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "abc"])
def test_validate_bad_tolerance(value, run_cli, tmp_path):
    status, _, err = run_cli("validate", REF / "stiffness_8m", "--tolerance", value, "--report", tmp_path / "r")
    assert status == 2 and len(err.strip().splitlines()) == 1 and "--tolerance" in err
    assert not (tmp_path / "r").exists()


# ---------------------------------------------------------------------------------------------
# 6. lazy imports (the start-up time itself is measured by bench/bench_cli_startup.py)
def test_cli_import_loads_no_scipy_matplotlib_numpy():
    code = ("import sys, tether.cli; heavy = [m for m in ('scipy', 'matplotlib', 'numpy', 'fmpy') "
            "if m in sys.modules]; print(','.join(heavy))")
    p = run(sys.executable, "-c", code)
    assert p.returncode == 0 and p.stdout.strip() == "", p.stdout + p.stderr


def test_simulate_without_input_loads_no_scipy(fv_trace, tmp_path, fmu_path):
    # a free vibration needs no interpolation of an input: no scipy, no matplotlib
    code = ("import sys; from tether.cli import main; s = main(sys.argv[1:]); "
            "print(s, 'scipy' in sys.modules, 'matplotlib' in sys.modules)")
    p = run(sys.executable, "-c", code, "simulate", fv_trace, "--out", tmp_path / "o.csv")
    assert p.returncode == 0 and p.stdout.split() == ["0", "False", "False"], p.stdout + p.stderr
