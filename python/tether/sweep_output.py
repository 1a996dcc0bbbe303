"""A sweep's files: the rows (CSV, appended as runs finish), the state that lets a killed sweep go
on (``OUT.sweep.json`` beside it), and each run's time series (Parquet).

While a sweep runs, OUT holds the header and the rows finished so far in the order they finished,
each written whole with one write and flushed. When every run is in, OUT is rewritten in run order
(atomically) and the state file marked finished: OUT is then the same byte for byte however the
sweep was split, scheduled, killed and resumed.

``--resume`` reads OUT's complete lines (a line cut by a kill is dropped), checks that the sweep is
the same one (trace, model, parameters, columns and runs, against the state file) and runs only
the missing rows (none for a finished sweep: its report can be written again so).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

import numpy as np

from .atomic import replace_with, write_text

STATE_FORMAT = "tether-sweep-state/1"


class SweepFileError(ValueError):
    """OUT or its state file cannot be used; ``str(e)`` is one line naming the file and what differs."""


def state_path(out: Path) -> Path:
    return out.with_name(out.name + ".sweep.json")


class RowsFile:
    """OUT.csv of one sweep: :meth:`start` or :meth:`resume`, :meth:`append` each row, :meth:`finish`."""

    def __init__(self, out: Path, columns: Sequence[str], fingerprint: dict):
        self.out = Path(out)
        self.columns = list(columns)
        self.header = ",".join(self.columns) + "\n"
        self.fingerprint = fingerprint
        self.rows: dict[int, str] = {}
        self._f = None

    def start(self) -> None:
        """A new sweep: write the state file, then OUT with its header (an old OUT is replaced)."""
        self._write_state(finished=False)
        replace_with(self.out, lambda tmp: Path(tmp).write_text(self.header, encoding="utf-8"))
        self._f = open(self.out, "a", encoding="utf-8", newline="\n")

    def resume(self) -> set[int]:
        """Go on with the sweep OUT holds; the runs already done."""
        sp = state_path(self.out)
        if not self.out.is_file():
            raise SweepFileError(f"--resume: {self.out} does not exist; nothing to resume (run without --resume)")
        if not sp.is_file():
            raise SweepFileError(f"--resume: {sp} does not exist: {self.out} is not a sweep's output; nothing "
                                 "to resume")
        try:
            state = json.loads(sp.read_text(encoding="utf-8"))
        except (OSError, ValueError) as e:
            raise SweepFileError(f"--resume: {sp}: not a sweep state file ({e})") from None
        for key, want in self.fingerprint.items():
            if state.get(key) != want:
                raise SweepFileError(f"--resume: {sp}: key '{key}' differs from this sweep's ({state.get(key)!r} "
                                     f"there, {want!r} here); resume with the same trace, model, parameters and "
                                     "sweep options, or run without --resume")
        text = self.out.read_bytes().decode("utf-8")
        complete = text[:text.rfind("\n") + 1]      # a line cut by a kill has no newline yet
        lines = complete.splitlines(keepends=True)
        if not lines or lines[0] != self.header:
            raise SweepFileError(f"--resume: {self.out}: the header differs from this sweep's columns "
                                 f"({','.join(self.columns)})")
        n = len(self.columns)
        for k, line in enumerate(lines[1:], 2):
            fields = line.rstrip("\n").split(",")
            if len(fields) != n or not fields[0].isdigit():
                raise SweepFileError(f"--resume: {self.out}: line {k} is not a row of this sweep: {line.strip()!r}")
            self.rows[int(fields[0])] = line
        with open(self.out, "r+b") as f:            # drop the cut line, if any
            f.truncate(len(complete.encode("utf-8")))
        self._f = open(self.out, "a", encoding="utf-8", newline="\n")
        return set(self.rows)

    def append(self, index: int, line: str) -> None:
        self.rows[index] = line
        self._f.write(line)
        self._f.flush()

    def finish(self) -> None:
        """All runs in: OUT in run order, atomically; the state file marked finished."""
        self.close()
        ordered = "".join(self.rows[i] for i in sorted(self.rows))
        replace_with(self.out, lambda tmp: Path(tmp).write_text(self.header + ordered, encoding="utf-8"))
        self._write_state(finished=True)

    def _write_state(self, finished: bool) -> None:
        doc = {"format": STATE_FORMAT, "finished": finished, **self.fingerprint}
        write_text(state_path(self.out), json.dumps(doc, indent=1) + "\n")

    def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None


# ---------------------------------------------------------------------------------------------
def series_path(folder: Path, index: int) -> Path:
    return Path(folder) / f"run_{index:06d}.parquet"


def write_series(folder: Path, index: int, measured_column: str, time, predicted, tension) -> None:
    """One run's series as Parquet (columns time, the measured column, tension), atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({"time": np.asarray(time, float), measured_column: np.asarray(predicted, float),
                      "tension": np.asarray(tension, float)})
    replace_with(series_path(folder, index), lambda tmp: pq.write_table(table, tmp))


def read_series(folder: Path, index: int, measured_column: str) -> np.ndarray:
    """The predicted measured column of run ``index``."""
    import pyarrow.parquet as pq

    path = series_path(folder, index)
    if not path.is_file():
        raise SweepFileError(f"{path}: missing; run the sweep again with --resume to write it")
    return pq.read_table(path, columns=[measured_column]).column(0).to_numpy()

