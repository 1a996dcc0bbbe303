"""tether validate: the acceptance of issue 4's validation runs, on the bundled reference traces.

The reference traces are synthetic with a stated noise sigma and record the model that generated
them: validating each with that model must leave an error at the noise level (independent
expectation: the noise the generator added), and a model that lacks the trace's physics must not.
"""

import json
import re
from pathlib import Path

import numpy as np
import pytest

REF = Path(__file__).resolve().parents[1] / "reference_results"


def test_validate_reference_results_within_their_noise(tmp_path, run_cli):
    report = tmp_path / "report"
    status, out, err = run_cli("validate", "--report", report)
    assert status == 0, err
    doc = json.loads((report / "validation.json").read_text())
    rows = doc["traces"]
    names = {Path(r["trace"]).name for r in rows}
    expected = {p.stem for p in REF.glob("*.csv") if p.with_suffix(".json").is_file()}
    assert names == expected and len(rows) >= 15
    for r in rows:
        assert r["noise_sigma"] is not None, r["trace"]
        # the residual is the added noise: RMS within 20 % of sigma, R^2 close to 1
        assert 0.8 * r["noise_sigma"] < r["rms_error"] <= 1.2 * r["noise_sigma"], r
        assert r["within_noise"] is True
        assert r["r2"] > 0.999
        assert r["max_error"] >= r["rms_error"]
    # the table on the terminal has a row per trace, the page embeds a plot per trace
    for n in names:
        assert re.search(rf"^{re.escape(n)}\s", out, re.M), n
    page = (report / "index.html").read_text()
    imgs = re.findall(r"<img src='([^']+)'", page)
    assert len(imgs) == len(rows)
    for img in imgs:
        png = report / img
        assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_wrong_model_is_flagged_outside_the_noise(tmp_path, run_cli):
    # the linear baseline on a Kawabata loop: hysteresis and the power-law branches are missing
    report = tmp_path / "r"
    status, out, err = run_cli("validate", REF / "kawabata_16m_6kg", "--model", "linear",
                               "--report", report)
    assert status == 1, err           # outside the default tolerance: the exit status gates a script
    row = json.loads((report / "validation.json").read_text())["traces"][0]
    assert row["model"] == "linear" and row["within_noise"] is False
    assert row["rms_error"] > 10 * row["noise_sigma"]
    assert "outside their stated noise: kawabata_16m_6kg" in out


def test_metrics_against_hand_computation():
    from tether.validate import metrics

    t = np.linspace(0, 1, 5)
    meas = np.array([0.0, 1.0, 2.0, 1.0, 0.0])
    pred = np.array([0.0, 1.5, 2.0, 1.0, -0.5])
    m = metrics(meas, pred, t)
    rms = np.sqrt((0.25 + 0.25) / 5)
    assert m["rms"] == pytest.approx(rms)
    assert m["nrmse"] == pytest.approx(rms / np.std(meas))
    assert m["r2"] == pytest.approx(1 - 0.5 / np.sum((meas - meas.mean()) ** 2))
    assert m["max_error"] == pytest.approx(0.5) and m["max_error_time"] == pytest.approx(0.25)


def test_bad_trace_fails_before_any_output(tmp_path, run_cli, write_trace):
    good = REF / "stiffness_8m"
    bad = tmp_path / "missing_trace"
    report = tmp_path / "r"
    status, out, err = run_cli("validate", good, bad, "--report", report)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tether: error: ") and "missing_trace" in lines[0]
    assert not report.exists()


def test_unknown_model_fails_before_any_output(tmp_path, run_cli):
    report = tmp_path / "r"
    status, out, err = run_cli("validate", REF / "stiffness_8m", "--model", "linear+friction", "--report", report)
    assert status == 2 and "friction" in err and not report.exists()
