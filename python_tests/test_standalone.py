"""The repository stands alone, and the package finds its files inside itself first.

* nothing in code, scripts, tests, benches or the README reads from outside the repository
  (the team's shared folder);
* the bundled Bouc-Wen benchmark reads as traces, with its licence and citation beside it;
* tether.resources: an installed package's own FMU, engine and data win over a checkout's build/.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
OUTSIDE = ("../" + "shared", "/work/" + "shared")      # split so that this file does not match itself


def tracked_files() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout
        return [REPO / f for f in out.splitlines()]
    except (OSError, subprocess.CalledProcessError):
        return [p for p in REPO.rglob("*") if p.is_file() and ".git" not in p.parts and ".venv" not in p.parts
                and "build" not in p.parts]


def test_nothing_reads_from_outside_the_repository():
    roots = ("python/", "python_tests/", "scripts/", "bench/", "reference_results/", "cmake/", "tools/", ".ci/")
    hits = []
    for f in tracked_files():
        rel = f.relative_to(REPO).as_posix()
        if not (rel.startswith(roots) or rel in ("README.md", "CMakeLists.txt", "pyproject.toml")):
            continue
        if f.suffix in (".gz", ".png", ".fmu") or not f.is_file():
            continue
        text = f.read_text(errors="replace")
        hits += [f"{rel}:{i}: {line.strip()}" for i, line in enumerate(text.splitlines(), 1)
                 if any(o in line for o in OUTSIDE)]
    assert not hits, "\n".join(hits)


@pytest.mark.parametrize("name, samples", [("train_multisine", 40960), ("test_multisine", 8192),
                                           ("test_sinesweep", 153000)])
def test_bundled_benchmark_reads(name, samples):
    from tether.traces import read_trace

    d = REPO / "datasets" / "boucwen"
    tr = read_trace(d / name)
    assert tr.csv_path.name == f"{name}.csv.gz" and tr.n == samples
    assert tr.experiment == "forced" and tr.payload_mass_kg == 2.0 and tr.gravity_m_s2 == 0.0
    assert np.all(np.diff(tr.time) > 0)
    assert abs(1.0 / np.median(np.diff(tr.time)) - 750.0) < 1e-6      # 750 Hz, as the benchmark says


def test_bundled_benchmark_has_licence_and_citation():
    d = REPO / "datasets" / "boucwen"
    assert "MIT License" in (d / "LICENSE").read_text()
    readme = (d / "README.md").read_text()
    assert "10.4121/12967592" in readme and "Noël" in readme


def test_installed_files_win_over_the_checkout(tmp_path, monkeypatch, fmu_path):
    from tether import fmu, resources

    monkeypatch.delenv("KT_FMU", raising=False)
    monkeypatch.delenv("KT_IDENTIFY_LIB", raising=False)
    installed = tmp_path / "_data"
    monkeypatch.setattr(resources, "INSTALLED_DATA", installed)
    # nothing installed: the checkout's build/ and data
    assert fmu.fmu_path() == resources.build_dir() / "KevlarTether.fmu"
    assert resources.reference_results_dir() == REPO / "reference_results"
    assert resources.dataset_dir("boucwen") == REPO / "datasets" / "boucwen"
    # an installed package: its own files
    (installed / "reference_results").mkdir(parents=True)
    (installed / "datasets" / "boucwen").mkdir(parents=True)
    shutil.copy(fmu_path, installed / "KevlarTether.fmu")
    assert fmu.fmu_path() == installed / "KevlarTether.fmu"
    assert resources.identify_library_candidates()[0] == installed / "libtether_identify.so"
    assert resources.reference_results_dir() == installed / "reference_results"
    assert resources.dataset_dir("boucwen") == installed / "datasets" / "boucwen"


def test_missing_fmu_names_every_place_looked_at(tmp_path, monkeypatch):
    from tether import fmu, resources

    monkeypatch.delenv("KT_FMU", raising=False)
    monkeypatch.setattr(resources, "INSTALLED_DATA", tmp_path / "_data")
    monkeypatch.setenv("KT_BUILD_DIR", str(tmp_path / "nobuild"))
    with pytest.raises(fmu.FMUError) as ei:
        fmu.fmu_path()
    msg = str(ei.value)
    assert str(tmp_path / "_data" / "KevlarTether.fmu") in msg and str(tmp_path / "nobuild") in msg
    assert "pip install" in msg and "\n" not in msg
