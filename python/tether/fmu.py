"""Locate, extract and describe the KevlarTether FMU.

The FMU is ``$KT_FMU`` if that variable is set, else the one installed inside the package, else
``<repo root>/build/KevlarTether.fmu`` (built by ``scripts/setup.sh``; see :mod:`tether.resources`).
It is extracted once per FMU file (its path, modification time and size) into a folder of the
temporary directory that every process running that file shares (_shared_extraction).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path

from .resources import SETUP_HINT as _HINT, fmu_candidates

SETUP_HINT = _HINT + ", or set KT_FMU"


class FMUError(RuntimeError):
    """The FMU is missing, unreadable or failed; ``str(e)`` is one line."""


@dataclass(frozen=True)
class Variable:
    name: str
    vr: int
    type: str              # 'Real', 'Integer', 'Enumeration', 'Boolean', 'String'
    causality: str
    variability: str
    start: float | int | bool | None
    min: float | None
    max: float | None
    description: str = ""
    unit: str = ""         # the variable's unit (its own, else its declared type's); "" if none


@dataclass(frozen=True)
class Description:
    """What the rest of the package needs from modelDescription.xml."""

    path: Path                     # the FMU
    guid: str
    model_identifier: str           # co-simulation
    variables: dict                 # name -> Variable
    default_tolerance: float | None

    @property
    def parameters(self) -> dict:
        """name -> Variable for every variable with causality 'parameter'."""
        return {n: v for n, v in self.variables.items() if v.causality == "parameter"}

    def vr(self, name: str) -> int:
        return self.variables[name].vr


def fmu_path() -> Path:
    """The FMU to use; FMUError if it does not exist."""
    cands = fmu_candidates()
    p = next((c for c in cands if c.is_file()), None)
    if p is None:
        src = "KT_FMU" if os.environ.get("KT_FMU") else "looked at " + ", ".join(map(str, cands))
        raise FMUError(f"FMU not found: {cands[0]} ({src}); {SETUP_HINT}")
    return p


_lock = threading.Lock()
_extracted: dict = {}      # (path, mtime, size) -> unzip dir
_descriptions: dict = {}   # (path, mtime, size) -> Description


def _key(path: Path):
    st = path.stat()
    return (str(path.resolve()), st.st_mtime_ns, st.st_size)


def extract(path: Path | None = None) -> tuple[Path, tuple]:
    """The FMU's files, extracted once per FMU file (_shared_extraction); returns (directory, cache
    key)."""
    path = fmu_path() if path is None else Path(path)
    key = _key(path)
    with _lock:
        d = _extracted.get(key)
        if d is None:
            d = _extracted[key] = _shared_extraction(path, key)
    return d, key


def _shared_extraction(path: Path, key: tuple) -> Path:
    """The FMU's files in one folder of the temporary directory per FMU file (its path, time and
    size), shared by every process that runs it and extracted by the first: a process that is
    killed (a Dask worker closed with its cluster, a test worker) runs no exit handler, and a
    folder of its own per process was left behind each time. Extracted into a folder of its own,
    then renamed into place, so no process sees it half written."""
    import fmpy

    digest = hashlib.sha1(repr(key).encode()).hexdigest()[:16]
    d = Path(tempfile.gettempdir()) / f"tether-fmu-{digest}"
    if (d / "modelDescription.xml").is_file():
        return d
    part = Path(tempfile.mkdtemp(prefix=f"tether-fmu-{digest}-part-"))
    try:
        # sources/ (88 files) and documentation/ are not needed to run it: extracting them was half
        # the start-up of `tether simulate`
        fmpy.extract(str(path), unzipdir=str(part),
                     include=lambda name: not name.startswith(("sources/", "documentation/")))
        os.rename(part, d)
    except OSError:
        if not (d / "modelDescription.xml").is_file():      # not another process's rename that won
            shutil.rmtree(part, True)
            raise FMUError(f"{path}: cannot extract the FMU into {d}; {SETUP_HINT}") from None
    except Exception as e:  # noqa: BLE001 - a broken zip is a user-level error
        shutil.rmtree(part, True)
        raise FMUError(f"{path}: cannot extract the FMU ({e}); {SETUP_HINT}") from None
    shutil.rmtree(part, True)                                   # where another process's rename won
    return d


def model_description(path: Path | None = None) -> Description:
    """The FMU's modelDescription (variables with value references, start, min, max)."""
    from fmpy import read_model_description

    path = fmu_path() if path is None else Path(path)
    key = _key(path)
    with _lock:
        desc = _descriptions.get(key)
    if desc is not None:
        return desc
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as e:  # noqa: BLE001
        raise FMUError(f"{path}: cannot read modelDescription.xml ({e}); {SETUP_HINT}") from None
    if md.coSimulation is None:
        raise FMUError(f"{path}: the FMU has no Co-Simulation interface")
    variables = {}
    for v in md.modelVariables:
        t = v.type
        start = v.start
        if start is not None:
            if t == "Real":
                start = float(start)
            elif t in ("Integer", "Enumeration"):
                start = int(start)
            elif t == "Boolean":
                start = start in (True, "true", "1", 1)
        lo = getattr(v, "min", None)
        hi = getattr(v, "max", None)
        if t == "Enumeration" and v.declaredType is not None:
            vals = [int(it.value) for it in v.declaredType.items]
            lo = min(vals) if lo is None else lo
            hi = max(vals) if hi is None else hi
        variables[v.name] = Variable(
            name=v.name, vr=int(v.valueReference), type=t, causality=v.causality,
            variability=v.variability, start=start,
            min=None if lo is None else float(lo), max=None if hi is None else float(hi),
            description=v.description or "",
            unit=getattr(v, "unit", None) or getattr(v.declaredType, "unit", None) or "")
    tol = md.defaultExperiment.tolerance if md.defaultExperiment is not None else None
    desc = Description(path=path, guid=md.guid, model_identifier=md.coSimulation.modelIdentifier,
                       variables=variables, default_tolerance=None if tol is None else float(tol))
    with _lock:
        _descriptions[key] = desc
    return desc
