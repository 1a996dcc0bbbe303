"""The Python API: `import tether` is cheap and exposes read_trace, Trace, simulate, fit, discover;
the README's example runs as written (extracted from README.md) and recovers the generating model."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
API = ["read_trace", "Trace", "TraceError", "simulate", "fit", "discover"]


def test_import_tether_is_cheap_and_lazy():
    code = ("import sys, tether; "
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numpy', 'scipy', 'matplotlib', 'fmpy'}); "
            f"print(heavy, all(n in dir(tether) for n in {API!r}))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=str(REPO.parent))
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[] True"


def test_api_names_are_the_package_functions():
    import tether
    from tether import api, traces

    assert tether.read_trace is traces.read_trace and tether.Trace is traces.Trace
    assert tether.simulate is api.simulate
    for name in API:
        assert callable(getattr(tether, name)), name
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        tether.nope  # noqa: B018


def test_fit_and_discover_stay_modules_as_well():
    import tether
    import tether.fit as F
    from tether import discover as D

    assert F is tether.fit and callable(F) and callable(F.fit_traces)
    assert D is tether.discover and callable(D) and callable(D.discovery_document)


def readme_example() -> str:
    text = (REPO / "README.md").read_text()
    m = re.search(r"<!-- api-example[^>]*-->\s*```python\n(.*?)```", text, re.S)
    assert m, "README.md: no ```python block after <!-- api-example -->"
    return m.group(1)


def fmu_start_values(names) -> dict:
    root = ET.parse(REPO / "modelDescription.xml").getroot()
    out = {}
    for sv in root.iter("ScalarVariable"):
        if sv.get("name") in names:
            out[sv.get("name")] = float(sv.find("Real").get("start"))
    return out


def test_readme_example_runs_and_recovers_the_generating_model(monkeypatch, capsys, fmu_path):
    code = readme_example()
    lines = [ln for ln in code.splitlines() if ln.strip()]
    assert len(lines) == 6, code
    monkeypatch.chdir(REPO)
    ns: dict = {}
    exec(compile(code, "README.md (api-example)", "exec"), ns)
    out = capsys.readouterr().out
    assert "RMS error" in out
    fitted, other, prediction = ns["fitted"], ns["other"], ns["prediction"]
    # the records are synthetic: the FMU's default cubic law and c(x) plus Gaussian noise
    truth = fmu_start_values(fitted.free)
    for name in ("a1", "a2", "c0", "c1"):
        assert fitted.values[name] == pytest.approx(truth[name], rel=0.05), (name, fitted.values[name], truth[name])
    sigma = json.loads(other.json_path.read_text())["synthetic"]["noise"]["sigma_m"]
    rms = prediction.rms_error(other.measured)
    assert rms < 1.1 * sigma, (rms, sigma)      # the other amplitude is predicted to within its noise


def test_api_takes_paths_and_arrays(fmu_path):
    import tether

    stem = REPO / "reference_results" / "stiffness_8m"
    from_path = tether.simulate(stem, "cubic")
    tr = tether.read_trace(stem)
    mem = tether.Trace.from_arrays(tr.time, experiment=tr.experiment, length_m=tr.length_m, load=tr.input,
                                   require_measured=False,          # input only: a prediction
                                   extra={"input_interpolation": tr.meta["input_interpolation"]})
    from_memory = tether.simulate(mem, "cubic")
    np.testing.assert_array_equal(from_path.predicted, from_memory.predicted)
    r = tether.fit(str(stem), "cubic")           # one trace, as a path
    assert r.traces == ["stiffness_8m"] and r.intervals is r.ci95
