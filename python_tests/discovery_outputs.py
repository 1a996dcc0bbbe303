"""What tests read of a discovery's outputs: its JSON, parsed as strictly as jq parses it, and the
error of its model rerun through the FMU by `tether simulate --params`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def read_strict_json(path: Path) -> dict:
    """The JSON at ``path``; a NaN or Infinity in it (which a strict parser such as jq refuses) fails the test."""
    return json.loads(Path(path).read_text(), parse_constant=_refuse)


def _refuse(token):
    raise AssertionError(f"not JSON: {token} (a strict parser such as jq refuses it)")


def rerun_rms(run_cli, tmp_path, stem, params, measured) -> float:
    """RMS error of `tether simulate STEM --params PARAMS` (the FMU) against ``measured``."""
    sim = tmp_path / "sim.csv"
    status, _, err = run_cli("simulate", stem, "--params", params, "--out", sim)
    assert status == 0, err
    y = np.genfromtxt(sim, delimiter=",", names=True)["displacement"]
    return float(np.sqrt(np.mean((y - measured) ** 2)))
