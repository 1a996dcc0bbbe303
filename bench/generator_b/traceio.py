"""Writing traces in `tether-trace/1` (NAME.csv + NAME.json) and checking them against the format."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

COLUMNS = {
    "free_vibration": ["time", "displacement"],
    "forced": ["time", "force", "displacement"],
    "load_unload": ["time", "load", "elongation"],
    "creep": ["time", "load", "elongation"],
}


def _plain(obj):
    """numpy scalars and arrays to JSON's own types."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def write_trace(directory: Path, name: str, columns: dict, meta: dict) -> Path:
    """Write NAME.csv and NAME.json; each file appears whole or not at all. Returns the stem."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    names = COLUMNS[meta["experiment"]]
    data = np.column_stack([np.asarray(columns[c], float) for c in names])
    check_columns(name, meta["experiment"], names, data)
    stem = directory / name
    _atomic_write(stem.with_suffix(".csv"), lambda f: _write_csv(f, names, data))
    _atomic_write(stem.with_suffix(".json"), lambda f: f.write(json.dumps(_plain(meta), indent=1) + "\n"))
    return stem


def _write_csv(f, names: list, data: np.ndarray) -> None:
    f.write(",".join(names) + "\n")
    for row in data:
        f.write(",".join(f"{v:.12g}" for v in row) + "\n")


def _atomic_write(path: Path, fill) -> None:
    tmp = path.with_name(path.name + ".part")
    with open(tmp, "w") as f:
        fill(f)
    os.replace(tmp, path)


def check_columns(name: str, experiment: str, names: list, data: np.ndarray) -> None:
    """Numbers only, finite, time strictly increasing."""
    if not np.all(np.isfinite(data)):
        bad = int(np.argwhere(~np.isfinite(data))[0][0])
        raise ValueError(f"{name}: non-finite value in row {bad + 2} of the {experiment} columns {names}")
    steps = np.diff(data[:, 0])
    if np.any(steps <= 0.0):
        raise ValueError(f"{name}: time not strictly increasing at row {int(np.argmin(steps)) + 3}")


def read_trace(stem: Path) -> tuple[dict, dict]:
    """(columns, meta) of a written trace, checked against the format; errors name file and key."""
    stem = Path(stem)
    meta = json.loads(stem.with_suffix(".json").read_text())
    for key in ("format", "experiment", "tether"):
        if key not in meta:
            raise ValueError(f"{stem}.json: required key '{key}' missing")
    if meta["format"] != "tether-trace/1":
        raise ValueError(f"{stem}.json: format is {meta['format']!r}, expected 'tether-trace/1'")
    if meta["experiment"] not in COLUMNS:
        raise ValueError(f"{stem}.json: unknown experiment {meta['experiment']!r}")
    length = meta["tether"].get("length_m")
    if not isinstance(length, (int, float)) or not length > 0:
        raise ValueError(f"{stem}.json: tether.length_m is {length!r}, expected a positive number")
    if meta["experiment"] in ("free_vibration", "forced") and not meta.get("payload_mass_kg", 0) > 0:
        raise ValueError(f"{stem}.json: payload_mass_kg missing or not positive")
    with open(stem.with_suffix(".csv")) as f:
        header = f.readline().strip().split(",")
    if header != COLUMNS[meta["experiment"]]:
        raise ValueError(f"{stem}.csv: header {header}, expected {COLUMNS[meta['experiment']]}")
    data = np.loadtxt(stem.with_suffix(".csv"), delimiter=",", skiprows=1, ndmin=2)
    check_columns(str(stem), meta["experiment"], header, data)
    return {c: data[:, i] for i, c in enumerate(header)}, meta
