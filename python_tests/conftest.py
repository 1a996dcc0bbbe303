"""Shared fixtures for the Python tests.

* ``fmu_path``: the FMU the package will use ($KT_FMU, else <repo>/build/KevlarTether.fmu); a
  missing FMU fails the test with the setup hint (nothing is skipped).
* ``repo_root``, ``datasets_dir`` (the bundled third-party data sets, datasets/ in the repository).
* ``write_trace``: writes NAME.csv + NAME.json into tmp_path and returns the stem path.
* ``run_cli``: runs ``tether`` in-process; returns (status, stdout, stderr).
* ``slack_forced_b26``: generator B's development-draw record b26 (seed 11: a forced linear tether
  that goes slack 14 times), written once per session; (its spec, the read Trace).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture(scope="session")
def datasets_dir() -> Path:
    d = REPO_ROOT / "datasets"
    if not d.is_dir():
        pytest.fail(f"third-party datasets not found at {d} (expected datasets/ in the repository)")
    return d


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    from tether.fmu import FMUError, fmu_path as locate

    try:
        return locate()
    except FMUError as e:
        pytest.fail(str(e))


class TraceWriter:
    """Write tether-trace/1 files into a directory.

    ``writer(name, meta, columns)`` with ``columns`` a dict name -> array (written in order, full
    precision), or ``csv="raw text"`` for malformed files; ``json_text=`` writes the JSON verbatim.
    Returns the stem path (``dir/name``).
    """

    def __init__(self, directory: Path):
        self.dir = directory

    def __call__(self, name: str = "trace", meta: dict | None = None, columns: dict | None = None, *,
                 csv: str | None = None, json_text: str | None = None) -> Path:
        stem = self.dir / name
        if json_text is not None:
            (self.dir / f"{name}.json").write_text(json_text)
        elif meta is not None:
            (self.dir / f"{name}.json").write_text(json.dumps(meta, indent=1))
        if csv is not None:
            (self.dir / f"{name}.csv").write_text(csv)
        elif columns is not None:
            names = list(columns)
            data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
            with open(self.dir / f"{name}.csv", "w") as f:
                f.write(",".join(names) + "\n")
                np.savetxt(f, data, delimiter=",", fmt="%.17g")
        return stem

    @staticmethod
    def meta(experiment: str = "free_vibration", **extra) -> dict:
        """A valid JSON for ``experiment``; keyword arguments override/add keys."""
        m = {"format": "tether-trace/1", "experiment": experiment, "tether": {"length_m": 16.0}}
        if experiment in ("free_vibration", "forced"):
            m["payload_mass_kg"] = 4.3
        m.update(extra)
        return m


@pytest.fixture
def write_trace(tmp_path) -> TraceWriter:
    return TraceWriter(tmp_path)


@pytest.fixture
def run_cli(capsys):
    from tether.cli import main

    def run(*argv):
        capsys.readouterr()
        try:
            status = main([str(a) for a in argv])
        except SystemExit as e:   # argparse usage errors / --help
            status = e.code
        out, err = capsys.readouterr()
        return status, out, err

    return run


@pytest.fixture(scope="session")
def slack_forced_b26(tmp_path_factory):
    import sys

    sys.path.insert(0, str(REPO_ROOT))
    from bench.generator_b import generate, suite, write_trace as write_b
    from tether.traces import read_trace

    spec = suite(48, 11)[26]
    assert spec["effects"] == ["slack"] and spec["experiment"] == "forced"
    stem = write_b(tmp_path_factory.mktemp("genb_11"), spec["name"], *generate(spec))
    return spec, read_trace(f"{stem}.csv")
