"""Read and check measured traces in the `tether-trace/1` format.

A trace is ``NAME.csv`` (samples) plus ``NAME.json`` (the experiment), side by side; see
``/work/shared/trace-format.md`` (the contract). :func:`read_trace` accepts either file or the stem
and checks everything strictly. Every problem raises :class:`TraceError` with one line that names
the file, the line/column or key, the offending value and what was expected.

Defaults applied here (from the format):

* ``gravity_m_s2``: 9.81
* ``initial_displacement_m``: the first ``displacement`` sample for ``free_vibration``, 0 for
  ``forced``; ``initial_velocity_m_s``: 0
* ``periodic_samples`` absent: the record starts from the initial state (not periodic)

Extra CSV columns and unknown JSON keys are ignored.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "tether-trace/1"

#: experiment -> (input column or None, measured column)
EXPERIMENTS: dict[str, tuple[str | None, str]] = {
    "free_vibration": (None, "displacement"),
    "forced": ("force", "displacement"),
    "load_unload": ("load", "elongation"),
    "creep": ("load", "elongation"),
}
#: experiments on the payload rig (need payload_mass_kg); the others run on the load rig
PAYLOAD_EXPERIMENTS = ("free_vibration", "forced")

DEFAULT_GRAVITY = 9.81

# a decimal number as written in a CSV (Python's float() also takes '1_0', 'infinity', ...)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


class TraceError(ValueError):
    """A trace that does not follow the format. ``str(e)`` is one line naming file, place, value."""

    def __init__(self, message: str, path: str | os.PathLike | None = None):
        super().__init__(message)
        self.path = None if path is None else str(path)


@dataclass
class Trace:
    """A checked trace. Arrays are float64 numpy arrays of equal length."""

    stem: Path                   # path without suffix
    csv_path: Path
    json_path: Path
    experiment: str
    length_m: float              # tether.length_m (L0)
    payload_mass_kg: float | None
    gravity_m_s2: float
    initial_displacement_m: float
    initial_velocity_m_s: float
    periodic_samples: int | None
    time: np.ndarray
    input_column: str | None     # 'force' / 'load' / None
    input: np.ndarray | None
    measured_column: str         # 'displacement' / 'elongation'
    measured: np.ndarray
    description: str = ""
    meta: dict[str, Any] = field(default_factory=dict, repr=False)  # the JSON as read

    @property
    def name(self) -> str:
        return self.stem.name

    @property
    def rig(self) -> str:
        """'payload' for free_vibration/forced, 'load' for load_unload/creep."""
        return "payload" if self.experiment in PAYLOAD_EXPERIMENTS else "load"

    @property
    def n(self) -> int:
        return len(self.time)

    def __len__(self) -> int:
        return len(self.time)


# ---------------------------------------------------------------------------------------------
def trace_paths(path: str | os.PathLike) -> tuple[Path, Path, Path]:
    """(stem, csv, json) for a path naming NAME.csv, NAME.json or the stem NAME."""
    p = Path(path)
    if p.suffix.lower() in (".csv", ".json"):
        stem = p.with_suffix("")
    else:
        stem = p
    return stem, stem.with_name(stem.name + ".csv"), stem.with_name(stem.name + ".json")


def read_trace(path: str | os.PathLike) -> Trace:
    """Read and check the trace named by ``path`` (NAME.csv, NAME.json or NAME)."""
    stem, csv_path, json_path = trace_paths(path)
    missing = [p for p in (csv_path, json_path) if not p.is_file()]
    if missing:
        names = " and ".join(str(p) for p in missing)
        raise TraceError(
            f"{names}: not found (a trace is NAME.csv plus NAME.json side by side; given '{path}')",
            missing[0])
    meta = _read_json(json_path)
    experiment = meta["experiment"]
    input_col, measured_col = EXPERIMENTS[experiment]
    required = ["time"] + ([input_col] if input_col else []) + [measured_col]
    columns, nrows = _read_csv(csv_path, required, experiment)

    time = columns["time"]
    measured = columns[measured_col]
    inp = columns[input_col] if input_col else None

    P = meta.get("periodic_samples")
    if P is not None:
        if P > nrows:
            raise TraceError(f"{json_path}: key 'periodic_samples': value {P} is larger than the record "
                             f"({nrows} samples in {csv_path.name}); expected a period of at most {nrows} samples",
                             json_path)
        if nrows % P != 0:
            raise TraceError(f"{json_path}: key 'periodic_samples': value {P} does not divide the record "
                             f"({nrows} samples in {csv_path.name}); expected a whole number of periods",
                             json_path)
        if P < 2:
            raise TraceError(f"{json_path}: key 'periodic_samples': value {P}; expected at least 2 samples per period",
                             json_path)

    if experiment == "free_vibration":
        x0 = meta.get("initial_displacement_m", float(measured[0]))
    else:
        x0 = meta.get("initial_displacement_m", 0.0)
    v0 = meta.get("initial_velocity_m_s", 0.0)

    return Trace(
        stem=stem, csv_path=csv_path, json_path=json_path, experiment=experiment,
        length_m=meta["tether"]["length_m"], payload_mass_kg=meta.get("payload_mass_kg"),
        gravity_m_s2=meta.get("gravity_m_s2", DEFAULT_GRAVITY),
        initial_displacement_m=float(x0), initial_velocity_m_s=float(v0),
        periodic_samples=P, time=time, input_column=input_col, input=inp,
        measured_column=measured_col, measured=measured,
        description=str(meta.get("description", "")), meta=meta)


# ---------------------------------------------------------------------------------------------
def _show(value: Any) -> str:
    """A value as it would appear in JSON (for messages)."""
    try:
        return json.dumps(value)
    except (TypeError, ValueError):
        return repr(value)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(meta: dict, key: str, where: str, path: Path, *, positive: bool = False,
            nonnegative: bool = False) -> float:
    v = meta[key] if key in meta else None
    if not _is_number(v):
        raise TraceError(f"{path}: key '{where}': value {_show(v)} is not a number; expected a number"
                         + (" > 0" if positive else " >= 0" if nonnegative else ""), path)
    v = float(v)
    if not math.isfinite(v):
        raise TraceError(f"{path}: key '{where}': value {_show(meta[key])} is not finite; expected a finite number", path)
    if positive and not v > 0:
        raise TraceError(f"{path}: key '{where}': value {_show(meta[key])}; expected a number > 0", path)
    if nonnegative and not v >= 0:
        raise TraceError(f"{path}: key '{where}': value {_show(meta[key])}; expected a number >= 0", path)
    return v


def _read_json(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise TraceError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start}); expected a JSON object", path) from None
    except OSError as e:
        raise TraceError(f"{path}: cannot be read ({e.strerror})", path) from None
    if not text.strip():
        raise TraceError(f"{path}: empty file; expected a JSON object with 'format', 'experiment' and 'tether'", path)
    try:
        raw = json.loads(text)
    except json.JSONDecodeError as e:
        raise TraceError(f"{path}: line {e.lineno}, column {e.colno}: invalid JSON ({e.msg})", path) from None
    if not isinstance(raw, dict):
        raise TraceError(f"{path}: the top level is {type(raw).__name__} {_show(raw)[:40]}; expected a JSON object", path)
    meta = dict(raw)

    if "format" not in meta:
        raise TraceError(f"{path}: key 'format' is missing; expected \"{FORMAT}\"", path)
    if meta["format"] != FORMAT:
        raise TraceError(f"{path}: key 'format': value {_show(meta['format'])} is not known; expected \"{FORMAT}\"", path)

    valid = ", ".join(EXPERIMENTS)
    if "experiment" not in meta:
        raise TraceError(f"{path}: key 'experiment' is missing; expected one of {valid}", path)
    exp = meta["experiment"]
    if not isinstance(exp, str) or exp not in EXPERIMENTS:
        raise TraceError(f"{path}: key 'experiment': value {_show(exp)} is not known; expected one of {valid}", path)

    tether = meta.get("tether")
    if "tether" not in meta:
        raise TraceError(f"{path}: key 'tether' is missing; expected an object with 'length_m' (> 0, metres)", path)
    if not isinstance(tether, dict):
        raise TraceError(f"{path}: key 'tether': value {_show(tether)} is not an object; expected "
                         "{\"length_m\": ...}", path)
    if "length_m" not in tether:
        raise TraceError(f"{path}: key 'tether.length_m' is missing; expected the natural length in metres (> 0)", path)
    tether = dict(tether)
    tether["length_m"] = _number(tether, "length_m", "tether.length_m", path, positive=True)
    meta["tether"] = tether

    if exp in PAYLOAD_EXPERIMENTS:
        if "payload_mass_kg" not in meta:
            raise TraceError(f"{path}: key 'payload_mass_kg' is missing; a {exp} trace needs the payload mass "
                             "in kg (> 0)", path)
    if "payload_mass_kg" in meta:
        meta["payload_mass_kg"] = _number(meta, "payload_mass_kg", "payload_mass_kg", path, positive=True)
    if "gravity_m_s2" in meta:
        meta["gravity_m_s2"] = _number(meta, "gravity_m_s2", "gravity_m_s2", path, nonnegative=True)
    for key in ("initial_displacement_m", "initial_velocity_m_s"):
        if key in meta:
            meta[key] = _number(meta, key, key, path)

    if "periodic_samples" in meta:
        P = meta["periodic_samples"]
        ok = _is_number(P) and math.isfinite(P) and float(P).is_integer() and P >= 1
        if not ok:
            raise TraceError(f"{path}: key 'periodic_samples': value {_show(P)}; expected a positive whole number "
                             "of samples per period", path)
        if exp == "free_vibration":
            raise TraceError(f"{path}: key 'periodic_samples': value {_show(P)} given for a free_vibration trace, "
                             "which has no input to repeat; expected it only for forced, load_unload or creep", path)
        meta["periodic_samples"] = int(P)
    return meta


def _read_csv(path: Path, required: list[str], experiment: str) -> tuple[dict[str, np.ndarray], int]:
    """Parse and check the CSV; return the required columns and the number of rows."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise TraceError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start}); expected comma-separated numbers", path) from None
    except OSError as e:
        raise TraceError(f"{path}: cannot be read ({e.strerror})", path) from None
    lines = text.splitlines()
    # trailing blank lines (a final newline, editors) are not rows
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise TraceError(f"{path}: empty file; expected a header row ({', '.join(required)}) and samples", path)

    header = [h.strip() for h in lines[0].split(",")]
    for j, h in enumerate(header):
        if not h:
            raise TraceError(f"{path}: line 1, column {j + 1}: empty column name; expected a header of names "
                             f"({', '.join(required)}, ...)", path)
    seen = set()
    for h in header:
        if h in seen:
            raise TraceError(f"{path}: line 1: column '{h}' appears twice; expected unique column names", path)
        seen.add(h)
    if header[0] != "time":
        raise TraceError(f"{path}: line 1, column 1: '{header[0]}'; expected the first column to be 'time'", path)
    missing = [c for c in required if c not in header]
    if missing:
        raise TraceError(f"{path}: line 1: column{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(repr(c) for c in missing)} missing; a {experiment} trace needs "
                         f"{', '.join(required)} (found {', '.join(header)})", path)
    nrows = len(lines) - 1
    if nrows == 0:
        raise TraceError(f"{path}: only a header, no samples; expected at least 2 rows of numbers after line 1", path)

    ncol = len(header)
    idx = [header.index(c) for c in required]
    data = _fast_parse(lines, ncol, idx)
    if data is None:
        data = _slow_parse(path, lines, header, idx)
    bad = np.argwhere(~np.isfinite(data))
    if bad.size:
        i, k = (int(v) for v in bad[0])
        cell = lines[i + 1].split(",")[idx[k]].strip()
        raise TraceError(f"{path}: line {i + 2}, column '{header[idx[k]]}': value '{cell}' is not finite; "
                         "expected a finite number", path)
    if nrows < 2:
        raise TraceError(f"{path}: only one sample (line 2); expected at least 2 rows of numbers", path)
    t = data[:, 0]
    dt = np.diff(t)
    bad = np.nonzero(~(dt > 0))[0]
    if bad.size:
        i = int(bad[0])
        raise TraceError(f"{path}: line {i + 3}: time {_fmt(t[i + 1])} after {_fmt(t[i])} on line {i + 2}; "
                         "expected strictly increasing time", path)
    if experiment in ("load_unload", "creep"):
        neg = np.nonzero(data[:, 1] < 0)[0]
        if neg.size:
            i = int(neg[0])
            raise TraceError(f"{path}: line {i + 2}, column 'load': value {_fmt(data[i, 1])} is negative; expected "
                             "a tension >= 0 (a hanging weight pulls, it cannot push)", path)
    cols = {c: np.ascontiguousarray(data[:, k]) for k, c in enumerate(required)}
    return cols, nrows


def _fast_parse(lines: list[str], ncol: int, idx: list[int]) -> np.ndarray | None:
    """All-numeric, rectangular files in one numpy call; None if anything is unusual."""
    try:
        arr = np.loadtxt(lines[1:], delimiter=",", comments=None, ndmin=2, dtype=float)
    except ValueError:
        return None
    if arr.shape != (len(lines) - 1, ncol):
        return None
    return np.ascontiguousarray(arr[:, idx])


def _slow_parse(path: Path, lines: list[str], header: list[str], idx: list[int]) -> np.ndarray:
    """Line by line, to name the first bad line and cell."""
    ncol = len(header)
    nrows = len(lines) - 1
    data = np.empty((nrows, len(idx)))
    number = _NUMBER.fullmatch
    for i, line in enumerate(lines[1:]):
        cells = line.split(",")
        if len(cells) != ncol:
            lineno = i + 2
            what = ("is empty" if not line.strip() else
                        f"has {len(cells)} cell{'' if len(cells) == 1 else 's'}")
            raise TraceError(f"{path}: line {lineno} {what}; expected {ncol} cells as in the header "
                             f"({', '.join(header)})", path)
        row = data[i]
        for k, j in enumerate(idx):
            cell = cells[j].strip()
            if number(cell) is None:
                raise TraceError(f"{path}: line {i + 2}, column '{header[j]}': value '{cells[j]}' is not a number; "
                                 "expected a decimal number", path)
            v = float(cell)
            if not math.isfinite(v):
                raise TraceError(f"{path}: line {i + 2}, column '{header[j]}': value '{cells[j].strip()}' is not finite; "
                                 "expected a finite number", path)
            row[k] = v
        # extra columns are ignored (any content), but a ragged row is caught above
    return data


def _fmt(x: float) -> str:
    return repr(float(x))
