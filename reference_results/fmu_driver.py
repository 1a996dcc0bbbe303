"""Drive the KevlarTether FMU sample by sample with fmpy's low-level FMI 2.0 co-simulation API.

Used by ``regenerate.py`` (to make the synthetic reference traces) and by the tests in
``python_tests/`` (to re-simulate them and to measure the paper's experiments). It depends on
numpy and fmpy only, not on the ``tether`` package, so the reference results can be made and
checked while that package changes.

Inputs between samples:
- ``load`` (load rig): piecewise linear through the samples; each communication step passes the
  value at its start and the slope (``fmi2SetRealInputDerivatives``, order 1), so the FMU integrates
  the ramp exactly.
- ``force`` (payload rig): a cubic spline through the samples; each step passes the value and the
  derivatives of order 1..3 at its start, so the FMU integrates the spline exactly.

The FMU is the one named by the environment variable ``KT_FMU``, else
``<repo>/build/KevlarTether.fmu``.
"""
from __future__ import annotations

import atexit
import os
import re
import shutil
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent

_CACHE: dict = {}
SWITCH_VALUE = re.compile(r"\b(\d+) = ([a-z_]+)\b")


def fmu_path() -> Path:
    """The FMU under test: $KT_FMU, else <repo>/build/KevlarTether.fmu."""
    env = os.environ.get("KT_FMU")
    path = Path(env) if env else REPO / "build" / "KevlarTether.fmu"
    if not path.is_file():
        raise FileNotFoundError(
            f"KevlarTether FMU not found at {path} (set KT_FMU or build it: bash scripts/setup.sh)")
    return path


class FMUError(RuntimeError):
    pass


class _Model:
    """The FMU's model description and its extracted binary, loaded once per process."""

    def __init__(self, path: Path):
        from fmpy import extract, read_model_description

        self.path = path
        self.md = read_model_description(str(path))
        self.unzipdir = extract(str(path))
        atexit.register(shutil.rmtree, self.unzipdir, ignore_errors=True)
        self.vars = {v.name: v for v in self.md.modelVariables}
        # the switches are Integer variables whose descriptions list their values as "1 = element, ..."
        self.switch_values = {v.name: {label: int(k) for k, label in SWITCH_VALUE.findall(v.description or "")}
                              for v in self.md.modelVariables if v.type == "Integer"}

    def vr(self, name: str) -> int:
        try:
            return self.vars[name].valueReference
        except KeyError:
            raise FMUError(f"the FMU has no variable named {name!r}") from None

    def start_value(self, name: str):
        v = self.vars[name]
        if v.type == "Integer":
            return int(v.start)
        if v.type == "Boolean":
            return v.start in (True, "true", "1", 1)
        return float(v.start)


def model(path: Path | None = None) -> _Model:
    path = Path(path) if path else fmu_path()
    key = str(path.resolve())
    if key not in _CACHE:
        _CACHE[key] = _Model(path)
    return _CACHE[key]


def fmu_version(path: Path | None = None) -> str:
    md = model(path).md
    return f"{md.modelName} {md.version} guid {md.guid}"


class Instance:
    """One co-simulation instance with its parameters set and initialised at t0."""

    def __init__(self, start_values: dict, t0: float = 0.0, inputs: dict | None = None,
                 input_derivatives: dict | None = None, fmu: Path | None = None):
        from fmpy.fmi2 import FMU2Slave

        self.m = model(fmu)
        md = self.m.md
        self.s = FMU2Slave(guid=md.guid, unzipDirectory=self.m.unzipdir,
                           modelIdentifier=md.coSimulation.modelIdentifier, instanceName="ref")
        self.s.instantiate()
        try:
            self.s.setupExperiment(startTime=t0)
            self.set(start_values)
            if inputs:
                self.set(inputs)
            if input_derivatives:
                self.set_derivatives(input_derivatives)
            self.s.enterInitializationMode()
            self.s.exitInitializationMode()
        except Exception:
            self.free()
            raise
        self.t = t0

    def set(self, values: dict):
        for name, value in values.items():
            var = self.m.vars.get(name)
            if var is None:
                raise FMUError(f"the FMU has no variable named {name!r}")
            vr = [var.valueReference]
            if var.type == "Integer":
                if isinstance(value, str):
                    values = self.m.switch_values[name]
                    if value not in values:
                        raise FMUError(f"{name} = {value!r}: expected one of {', '.join(values)}")
                    value = values[value]
                self.s.setInteger(vr, [int(value)])
            elif var.type == "Boolean":
                self.s.setBoolean(vr, [bool(value)])
            else:
                self.s.setReal(vr, [float(value)])

    def set_derivatives(self, derivatives: dict):
        """{name: [d1, d2, ...]}: input derivatives of order 1, 2, ..."""
        for name, ders in derivatives.items():
            vr = self.m.vr(name)
            n = len(ders)
            self.s.setRealInputDerivatives([vr] * n, list(range(1, n + 1)), [float(d) for d in ders])

    def get(self, names):
        reals = [n for n in names if self.m.vars[n].type == "Real"]
        out = dict(zip(reals, self.s.getReal([self.m.vr(n) for n in reals]))) if reals else {}
        for n in names:
            if n not in out:
                out[n] = float(self.s.getBoolean([self.m.vr(n)])[0]) \
                    if self.m.vars[n].type == "Boolean" else float(self.s.getInteger([self.m.vr(n)])[0])
        return [out[n] for n in names]

    def step(self, t_next: float):
        h = t_next - self.t
        self.s.doStep(currentCommunicationPoint=self.t, communicationStepSize=h)
        self.t = t_next

    def free(self):
        try:
            self.s.terminate()
        except Exception:
            pass
        self.s.freeInstance()


def _record(inst: Instance, outputs, rows):
    rows.append(inst.get(outputs))


def simulate_load(start_values: dict, time, load, outputs=("elongation", "tension"),
                  fmu: Path | None = None) -> dict:
    """Load rig driven by a piecewise-linear load through (time, load); outputs at every sample."""
    time = np.asarray(time, float)
    load = np.asarray(load, float)
    slope = np.diff(load) / np.diff(time)
    inst = Instance(start_values, t0=time[0], inputs={"load": load[0]},
                    input_derivatives={"load": [slope[0] if len(slope) else 0.0]}, fmu=fmu)
    rows = []
    try:
        _record(inst, outputs, rows)
        for i in range(len(time) - 1):
            inst.set({"load": load[i]})
            inst.set_derivatives({"load": [slope[i]]})
            inst.step(time[i + 1])
            # the load at the end of the step, for the outputs at this sample
            inst.set({"load": load[i + 1]})
            _record(inst, outputs, rows)
    finally:
        inst.free()
    arr = np.array(rows, float)
    return {"time": time, **{n: arr[:, k] for k, n in enumerate(outputs)}}


def simulate_payload(start_values: dict, time, force=None, spline=None,
                     outputs=("displacement", "tension"), fmu: Path | None = None,
                     check=None) -> dict:
    """Payload rig: free (no force) or forced by ``spline`` (a scipy CubicSpline of the force).
    ``check(values)`` is called with the outputs at every sample (for assertions during the run)."""
    time = np.asarray(time, float)

    def force_at(t):
        if spline is None:
            return {}, {}
        return ({"force": float(spline(t))},
                {"force": [float(spline(t, 1)), float(spline(t, 2)), float(spline(t, 3))]})

    f0, d0 = force_at(time[0])
    inst = Instance(start_values, t0=time[0], inputs=f0, input_derivatives=d0, fmu=fmu)
    rows = []
    try:
        _record(inst, outputs, rows)
        for i in range(len(time) - 1):
            f, d = force_at(time[i])
            if f:
                inst.set(f)
                inst.set_derivatives(d)
            inst.step(time[i + 1])
            _record(inst, outputs, rows)
            if check:
                check(dict(zip(outputs, rows[-1])))
    finally:
        inst.free()
    arr = np.array(rows, float)
    return {"time": time, **{n: arr[:, k] for k, n in enumerate(outputs)}}


def spline_derivatives(spline, t):
    """Value and derivatives 1..3 of a scipy CubicSpline at the sample times t (vectorised)."""
    return [spline(t, k) for k in range(4)]


def simulate_forced_samples(start_values: dict, time, f, fmu: Path | None = None,
                            outputs=("displacement",)) -> dict:
    """Payload rig driven by force samples with precomputed derivatives ``f = [F, F', F'', F''']``
    at every sample (the spline's Taylor polynomial on each step); faster than simulate_payload
    for long records."""
    time = np.asarray(time, float)
    F, F1, F2, F3 = (np.asarray(a, float) for a in f)
    inst = Instance(start_values, t0=time[0], inputs={"force": F[0]},
                    input_derivatives={"force": [F1[0], F2[0], F3[0]]}, fmu=fmu)
    s = inst.s
    vr_force = inst.m.vr("force")
    vr_out = [inst.m.vr(n) for n in outputs]
    out = np.empty((len(time), len(outputs)))
    try:
        out[0] = s.getReal(vr_out)
        t = time[0]
        for i in range(len(time) - 1):
            s.setReal([vr_force], [F[i]])
            s.setRealInputDerivatives([vr_force] * 3, [1, 2, 3], [F1[i], F2[i], F3[i]])
            s.doStep(currentCommunicationPoint=t, communicationStepSize=time[i + 1] - t)
            t = time[i + 1]
            out[i + 1] = s.getReal(vr_out)
    finally:
        inst.free()
    return {"time": time, **{n: out[:, k] for k, n in enumerate(outputs)}}
