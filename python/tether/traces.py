"""Read and check measured traces in the `tether-trace/1` format.

A trace is ``NAME.csv`` (samples) plus ``NAME.json`` (the experiment), side by side; see
``docs/trace-format.md`` (the contract). :func:`read_trace` accepts either file or the stem
and checks everything strictly. Every problem raises :class:`TraceError` with one line that names
the file, the line/column or key, the offending value and what was expected.

Also read, beyond the letter of the format (real files): ``NAME.csv.gz`` in place of ``NAME.csv``;
quoted column names (fmpy's result CSV, ``fmpy.util.write_csv``); a leading column without a name
(the index pandas' ``DataFrame.to_csv`` writes). ``read_trace(..., require_measured=False)`` takes an
input-only trace (no measured column; ``measured`` is None) for a pure prediction.
Traces from memory: :meth:`Trace.from_arrays` and :meth:`Trace.from_dataframe`, checked the same way.

Defaults applied here (from the format):

* ``gravity_m_s2``: 9.81
* ``initial_displacement_m``: the first ``displacement`` sample for ``free_vibration``, 0 for
  ``forced``; ``initial_velocity_m_s``: 0
* ``tether.line_density_kg_m``: 0 (a massless line; the payload rig's ``line_density``)
* ``periodic_samples`` absent: the record starts from the initial state (not periodic)

Extra CSV columns and unknown JSON keys are ignored.
"""

from __future__ import annotations

import csv
import gzip
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
#: the SI unit of every column the format names (the format is SI throughout)
COLUMN_UNITS = {"time": "s", "force": "N", "load": "N", "displacement": "m", "elongation": "m"}
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
    measured: np.ndarray | None  # None only for an input-only trace (read_trace(require_measured=False))
    description: str = ""
    meta: dict[str, Any] = field(default_factory=dict, repr=False)  # the JSON as read
    # half-width of the band, relative to payload_mass_kg, where the effective payload mass lies
    # (None: not stated; 0: the mass is exact); docs/nuisance.md
    mass_uncertainty_rel: float | None = None
    # False: the force column carries an unknown gain (docs/nuisance.md)
    force_gain_known: bool = True
    line_density_kg_m: float = 0.0  # tether.line_density_kg_m: the FMU's line_density (payload rig)
    # the samples a fit sees (bool per sample; None: every one): a held-out part inside the record
    # (discover.samples.heldout_split); never read from a file
    fitted_samples: np.ndarray | None = field(default=None, repr=False)

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

    @classmethod
    def from_arrays(cls, time, *, experiment: str, length_m: float, force=None, load=None,
                    displacement=None, elongation=None, payload_mass_kg: float | None = None,
                    gravity_m_s2: float | None = None, initial_displacement_m: float | None = None,
                    initial_velocity_m_s: float | None = None, periodic_samples: int | None = None,
                    line_density_kg_m: float | None = None, name: str = "trace", description: str = "", require_measured: bool = True,
                    extra: dict[str, Any] | None = None) -> "Trace":
        """A trace from arrays in memory, checked as a file would be (keys as in NAME.json).

        ``Trace.from_arrays(t, experiment="forced", length_m=1.0, payload_mass_kg=2.0, force=u,
        displacement=y)``; the input column the experiment needs (``force`` or ``load``) is
        required, the measured one (``displacement`` or ``elongation``) unless ``require_measured``
        is False. ``line_density_kg_m`` is the JSON's ``tether.line_density_kg_m``. ``extra``: other keys a NAME.json may hold (e.g. ``input_interpolation``). Errors
        name ``name``, the argument and the first bad index.
        """
        meta: dict[str, Any] = dict(extra or {})
        meta.update({"format": FORMAT, "experiment": experiment, "tether": {"length_m": length_m}})
        if line_density_kg_m is not None:
            meta["tether"]["line_density_kg_m"] = (line_density_kg_m.item() if hasattr(line_density_kg_m, "item")
                                                   else line_density_kg_m)
        for key, value in (("payload_mass_kg", payload_mass_kg), ("gravity_m_s2", gravity_m_s2),
                           ("initial_displacement_m", initial_displacement_m),
                           ("initial_velocity_m_s", initial_velocity_m_s), ("periodic_samples", periodic_samples)):
            if value is not None:
                meta[key] = value.item() if hasattr(value, "item") else value
        if description:
            meta["description"] = description
        where = f"{name} (in memory)"
        columns = {"time": time, "force": force, "load": load, "displacement": displacement, "elongation": elongation}
        given = {k: v for k, v in columns.items() if v is not None}
        return _trace_from_columns(Path(where), meta, given, name=name, require_measured=require_measured)

    @classmethod
    def from_dataframe(cls, df, *, experiment: str, length_m: float, name: str = "trace",
                       require_measured: bool = True, **keys) -> "Trace":
        """A trace from a pandas DataFrame with the format's column names.

        ``time`` is a column or the index (an index named ``time``); other columns are ignored;
        ``keys`` are the other arguments of :meth:`from_arrays` (payload_mass_kg, gravity_m_s2, ...).
        """
        cols = {str(c).strip(): c for c in df.columns}
        if "time" in cols:
            time = df[cols["time"]].to_numpy(dtype=float)
        elif getattr(df.index, "name", None) == "time":
            time = df.index.to_numpy(dtype=float)
        else:
            raise TraceError(f"{name} (in memory): no column or index named 'time' (columns: "
                             f"{', '.join(map(str, df.columns))}); expected the time in seconds")
        arrays = {c: df[cols[c]].to_numpy(dtype=float)
                  for c in ("force", "load", "displacement", "elongation") if c in cols}
        return cls.from_arrays(time, experiment=experiment, length_m=length_m, name=name,
                               require_measured=require_measured, **arrays, **keys)


# ---------------------------------------------------------------------------------------------
def trace_paths(path: str | os.PathLike) -> tuple[Path, Path, Path]:
    """(stem, csv, json) for a path naming NAME.csv, NAME.csv.gz, NAME.json or the stem NAME.

    The CSV is NAME.csv, or NAME.csv.gz where only that exists (or is named)."""
    p = Path(path)
    name = p.name
    if name.lower().endswith(".csv.gz"):
        stem = p.with_name(name[:-len(".csv.gz")])
        return stem, p, stem.with_name(stem.name + ".json")
    stem = p.with_suffix("") if p.suffix.lower() in (".csv", ".json") else p
    csv_path = stem.with_name(stem.name + ".csv")
    gz_path = stem.with_name(stem.name + ".csv.gz")
    if not os.path.isfile(csv_path) and os.path.isfile(gz_path):     # (isfile: a name too long is no file)
        csv_path = gz_path
    return stem, csv_path, stem.with_name(stem.name + ".json")


def read_trace(path: str | os.PathLike, *, require_measured: bool = True) -> Trace:
    """Read and check the trace named by ``path`` (NAME.csv, NAME.csv.gz, NAME.json or NAME).

    With ``require_measured=False`` the measured column may be absent (an input-only trace for a
    prediction); ``Trace.measured`` is then None.
    """
    stem, csv_path, json_path = trace_paths(path)
    _check_trace_files(path, csv_path, json_path)
    meta = _read_json(json_path)
    experiment = meta["experiment"]
    input_col, measured_col = EXPERIMENTS[experiment]
    required = ["time"] + ([input_col] if input_col else []) + [measured_col]
    columns, nrows = _read_csv(csv_path, required, experiment, optional=() if require_measured else (measured_col,))
    return _make_trace(stem, csv_path, json_path, meta, columns, nrows)


def _make_trace(stem: Path, csv_path: Path, json_path: Path, meta: dict, columns: dict, nrows: int) -> Trace:
    """The Trace from checked metadata and columns (the measured one may be missing)."""
    experiment = meta["experiment"]
    input_col, measured_col = EXPERIMENTS[experiment]
    time = columns["time"]
    measured = columns.get(measured_col)
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
        if "initial_displacement_m" not in meta and measured is None:
            raise TraceError(f"{json_path}: key 'initial_displacement_m' is missing and there is no "
                             f"'{measured_col}' column to take it from; a free_vibration trace without "
                             "measurements needs the initial displacement in metres", json_path)
        x0 = meta.get("initial_displacement_m", float(measured[0]) if measured is not None else 0.0)
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
        description=str(meta.get("description", "")), meta=meta,
        mass_uncertainty_rel=meta.get("mass_uncertainty_rel"), force_gain_known=meta.get("force_gain_known", True),
        line_density_kg_m=float(meta["tether"].get("line_density_kg_m", 0.0)))


def _trace_from_columns(where: Path, meta: dict, given: dict, *, name: str, require_measured: bool) -> Trace:
    """Check in-memory metadata and arrays as read_trace checks files (errors name ``where``)."""
    meta = _check_meta(meta, where)
    experiment = meta["experiment"]
    input_col, measured_col = EXPERIMENTS[experiment]
    required = ["time"] + ([input_col] if input_col else []) + [measured_col]
    missing = [c for c in required if c not in given and not (c == measured_col and not require_measured)]
    if missing:
        raise TraceError(f"{where}: argument{'s' if len(missing) > 1 else ''} {', '.join(missing)} missing; "
                         f"a {experiment} trace needs {', '.join(required)}", where)
    columns: dict[str, np.ndarray] = {}
    for c in required:
        if c not in given:
            continue
        try:
            a = np.asarray(given[c], dtype=float)
        except (TypeError, ValueError) as e:
            raise TraceError(f"{where}: argument '{c}': not numbers ({e}); expected a 1-D array of numbers", where) from None
        if a.ndim != 1:
            raise TraceError(f"{where}: argument '{c}': shape {a.shape}; expected a 1-D array", where)
        columns[c] = np.ascontiguousarray(a)
    n = len(columns["time"])
    for c, a in columns.items():
        if len(a) != n:
            raise TraceError(f"{where}: argument '{c}': {len(a)} samples, 'time' has {n}; expected equal lengths", where)
        bad = np.nonzero(~np.isfinite(a))[0]
        if bad.size:
            i = int(bad[0])
            raise TraceError(f"{where}: argument '{c}' at index {i}: value {a[i]!r} is not finite; expected a finite number", where)
    if n < 2:
        raise TraceError(f"{where}: {n} sample{'' if n == 1 else 's'}; expected at least 2", where)
    t = columns["time"]
    bad = np.nonzero(~(np.diff(t) > 0))[0]
    if bad.size:
        i = int(bad[0])
        raise TraceError(f"{where}: argument 'time' at index {i + 1}: {_fmt(t[i + 1])} after {_fmt(t[i])}; "
                         "expected strictly increasing time", where)
    if input_col == "load":
        neg = np.nonzero(columns["load"] < 0)[0]
        if neg.size:
            i = int(neg[0])
            raise TraceError(f"{where}: argument 'load' at index {i}: value {_fmt(columns['load'][i])} is negative; "
                             "expected a tension >= 0", where)
    return _make_trace(Path(name), where, where, meta, columns, n)


def _check_trace_files(given: str | os.PathLike, csv_path: Path, json_path: Path) -> None:
    """Both files of a trace are regular files that can be read; else a TraceError saying what they are."""
    from .filecheck import input_problem

    where = "a trace is NAME.csv plus NAME.json side by side"
    problems = [(p, input_problem(p)) for p in (csv_path, json_path)]
    given = Path(given)
    if given.suffix.lower() not in (".csv", ".json") and any(why for _, why in problems) and \
            os.path.lexists(given):                # (lexists: a name too long is not there, not an error)
        # the stem form names something that is there, but not a trace: say what it is
        why = input_problem(given) or "is a file without the .csv or .json suffix"
        raise TraceError(f"{given}: {why}; expected a trace: NAME.csv, NAME.json or the stem NAME ({where})", given)
    if all(why == "not found" for _, why in problems):
        raise TraceError(f"{csv_path} and {json_path}: not found ({where}; given '{given}')", csv_path)
    for p, why in problems:
        if why == "not found":
            raise TraceError(f"{p}: not found ({where}; given '{given}')", p)
        if why is not None:
            raise TraceError(f"{p}: {why}; expected a trace file ({where})", p)


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


def _parse_json(text: str, path: Path) -> Any:
    from .filecheck import JSONInputError, load_json

    try:
        return load_json(text)
    except JSONInputError as e:
        raise TraceError(f"{path}: {e}", path) from None


def _read_json(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise TraceError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start}); expected a JSON object", path) from None
    except OSError as e:
        raise TraceError(f"{path}: cannot be read ({e.strerror})", path) from None
    if not text.strip():
        raise TraceError(f"{path}: empty file; expected a JSON object with 'format', 'experiment' and 'tether'", path)
    raw = _parse_json(text, path)
    if not isinstance(raw, dict):
        raise TraceError(f"{path}: the top level is {type(raw).__name__} {_show(raw)[:40]}; expected a JSON object", path)
    return _check_meta(raw, path)


def _check_meta(raw: dict, path: Path) -> dict:
    """Check the experiment's keys (NAME.json or the arguments of Trace.from_arrays); a checked copy."""
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
    if "line_density_kg_m" in tether:
        tether["line_density_kg_m"] = _number(tether, "line_density_kg_m", "tether.line_density_kg_m", path,
                                              nonnegative=True)
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

    if "mass_uncertainty_rel" in meta:
        meta["mass_uncertainty_rel"] = _number(meta, "mass_uncertainty_rel", "mass_uncertainty_rel", path,
                                               nonnegative=True)
    if "force_gain_known" in meta and not isinstance(meta["force_gain_known"], bool):
        raise TraceError(f"{path}: key 'force_gain_known': value {_show(meta['force_gain_known'])} is not a boolean; "
                         "expected true (the force column is in newtons) or false (it carries an unknown gain)", path)

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


def _read_text(path: Path) -> str:
    """The CSV's text (gzip-compressed where the name ends in .gz)."""
    try:
        if path.name.lower().endswith(".gz"):
            with gzip.open(path, "rt", encoding="utf-8-sig", newline="") as f:
                return f.read()
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as e:
        raise TraceError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start}); expected comma-separated numbers", path) from None
    except (OSError, EOFError) as e:
        raise TraceError(f"{path}: cannot be read ({getattr(e, 'strerror', None) or e})", path) from None


def _header(path: Path, line: str, required: list[str]) -> list[str]:
    """Column names of line 1: quotes (fmpy, pandas) removed; an unnamed first column (a pandas
    index before 'time') kept as ''. Checks names: none empty, unique, 'time' first."""
    try:
        header = [h.strip() for h in next(csv.reader([line], skipinitialspace=True))]
    except csv.Error as e:
        raise TraceError(f"{path}: line 1: not a header of column names ({e})", path) from None
    index_column = len(header) > 1 and header[0] == "" and header[1] == "time"
    for j, h in enumerate(header):
        if not h and not (j == 0 and index_column):
            raise TraceError(f"{path}: line 1, column {j + 1}: empty column name; expected a header of names "
                             f"({', '.join(required)}, ...)", path)
    seen = set()
    for h in header:
        if h in seen:
            raise TraceError(f"{path}: line 1: column '{h}' appears twice; expected unique column names", path)
        seen.add(h)
    first = header[1] if index_column else header[0]
    if first != "time":
        raise TraceError(f"{path}: line 1, column 1: '{first}'; expected the first column to be 'time'", path)
    return header


def _read_csv(path: Path, required: list[str], experiment: str,
              optional: tuple[str, ...] = ()) -> tuple[dict[str, np.ndarray], int]:
    """Parse and check the CSV; return the required columns (less absent ``optional`` ones) and
    the number of rows."""
    text = _read_text(path)
    lines = text.splitlines()
    # trailing blank lines (a final newline, editors) are not rows
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise TraceError(f"{path}: empty file; expected a header row ({', '.join(required)}) and samples", path)

    header = _header(path, lines[0], required)
    missing = [c for c in required if c not in header and c not in optional]
    if missing:
        raise TraceError(f"{path}: line 1: column{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(repr(c) for c in missing)} missing; a {experiment} trace needs "
                         f"{', '.join(required)} (found {', '.join(header)})", path)
    required = [c for c in required if c in header]
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
