"""Small harness for the acceptance tests of the KevlarTether FMU (test_fmu_*.py).

- Locates the FMU: environment variable KT_FMU if set, else <repo>/build/KevlarTether.fmu.
- Extracts it once per test session and reads its modelDescription.xml (value references, types).
- Wraps fmpy's low-level FMU2Slave / FMU2Model so that the tests see the raw fmi2Status of every
  call (fmpy's own wrappers raise on fmi2Discard and fmi2Error, which the error-path tests need to
  look at) and capture every message the FMU sends through the logger callback.

Nothing here knows what the FMU computes: the expectations live in the tests (closed forms,
conservation laws, a second importer).
"""
from __future__ import annotations

import atexit
import ctypes
import functools
import os
import shutil
import tempfile
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent

fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal = 0, 1, 2, 3, 4
STATUS_NAMES = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal"}
fmi2ModelExchange, fmi2CoSimulation = 0, 1
fmi2LastSuccessfulTime = 2

# The nine continuous states in the order of the C enum of fmu_src/physics/tether.h.
STATE_NAMES = ["displacement", "velocity", "load_elongation", "hysteretic_force", "creep_strain_1",
               "creep_strain_2", "creep_strain_3", "slip_strain", "slip_capacity"]


def fmu_path() -> Path:
    """The FMU under test: $KT_FMU if set, else <repo>/build/KevlarTether.fmu."""
    env = os.environ.get("KT_FMU")
    return Path(env) if env else REPO / "build" / "KevlarTether.fmu"


def require_fmu() -> Path:
    p = fmu_path()
    if not p.is_file():
        pytest.fail(f"FMU not found at {p} (build it, or set KT_FMU to its path)", pytrace=False)
    return p


@functools.lru_cache(maxsize=None)
def unpacked() -> Path:
    """The FMU extracted once into a temporary directory (removed at exit)."""
    from fmpy import extract
    d = tempfile.mkdtemp(prefix="kt_fmu_")
    atexit.register(shutil.rmtree, d, ignore_errors=True)
    extract(str(require_fmu()), d)
    return Path(d)


@functools.lru_cache(maxsize=None)
def model_description():
    from fmpy import read_model_description
    return read_model_description(str(unpacked()))


def variables() -> dict:
    return {v.name: v for v in model_description().modelVariables}


def vr(name: str) -> int:
    return variables()[name].valueReference


def binary_path() -> Path:
    md = model_description()
    return unpacked() / "binaries" / "linux64" / (md.coSimulation.modelIdentifier + ".so")


# ---- logging -------------------------------------------------------------------------------
class Log:
    """Messages (status, category, text) one instance sent through the logger callback."""

    def __init__(self):
        self.records: list[tuple[int, str, str]] = []

    def clear(self):
        self.records.clear()

    def with_status(self, status: int):
        return [m for s, _, m in self.records if s == status]

    def in_category(self, category: str):
        return [m for _, c, m in self.records if c == category]

    def __repr__(self):
        return "\n".join(f"[{STATUS_NAMES.get(s, s)}|{c}] {m}" for s, c, m in self.records)


_LOGS: dict[str, Log] = {}


def _dispatch(env, instance_name, status, category, message):
    name = instance_name.decode() if instance_name else ""
    _LOGS.setdefault(name, Log()).records.append(
        (int(status), category.decode() if category else "", message.decode() if message else ""))


@functools.lru_cache(maxsize=None)
def _logger():
    """The one logger thunk of the harness, alive for the whole process."""
    from fmpy.fmi2 import fmi2CallbackLoggerTYPE
    return fmi2CallbackLoggerTYPE(_dispatch)


def callbacks():
    """A callback struct for one instance; messages are routed by instance name. fmpy's native
    proxy formats the variadic arguments (the FMU logs with format "%s"). The proxy keeps one
    logger for the whole process, the last one registered: each instance registers the harness's
    again, so that an instance never logs through a logger another user of fmpy (tether.run)
    registered in between."""
    from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions, calloc, free
    from fmpy.logging import addLoggerProxy
    cb = fmi2CallbackFunctions()
    cb.logger = _logger()
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    addLoggerProxy(byref(cb))
    return cb


_counter = [0]


def unique_name(prefix="kt") -> str:
    _counter[0] += 1
    return f"{prefix}{_counter[0]}"


def log_of(name: str) -> Log:
    return _LOGS.setdefault(name, Log())


# ---- instances -----------------------------------------------------------------------------
class Instance:
    """One FMU instance (kind 'cs' or 'me'), driven through raw calls that return the fmi2Status."""

    def __init__(self, kind="cs", name=None, logging_on=False, categories=None, directory=None):
        from fmpy.fmi2 import FMU2Model, FMU2Slave
        md = model_description()
        self.kind = kind
        self.name = name or unique_name(kind)
        self.log = log_of(self.name)
        cls = FMU2Slave if kind == "cs" else FMU2Model
        self.fmu = cls(guid=md.guid, unzipDirectory=str(directory or unpacked()),
                       modelIdentifier=md.coSimulation.modelIdentifier, instanceName=self.name)
        self.callbacks = callbacks()          # alive as long as the instance
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=logging_on)
        self.c = self.fmu.component
        if categories:
            self.check(self.set_debug_logging(True, categories), "fmi2SetDebugLogging")

    # raw access: a fresh ctypes prototype, independent of what fmpy declared
    def call(self, function, argtypes, *args):
        proto = ctypes.CFUNCTYPE(c_int, c_void_p, *argtypes)((function, self.fmu.dll))
        return proto(self.c, *args)

    def check(self, status, what):
        assert status == fmi2OK, f"{what} returned {STATUS_NAMES.get(status, status)}; log:\n{self.log}"

    def set_debug_logging(self, on, categories):
        arr = (c_char_p * len(categories))(*[c.encode() for c in categories])
        return self.call("fmi2SetDebugLogging", [c_int, c_size_t, POINTER(c_char_p)], int(on), len(categories), arr)

    def setup(self, tolerance=None, start=0.0):
        return self.call("fmi2SetupExperiment", [c_int, c_double, c_double, c_int, c_double],
                         int(tolerance is not None), tolerance or 0.0, start, 0, 0.0)

    def set_real(self, refs, values):
        n = len(refs)
        return self.call("fmi2SetReal", [POINTER(c_uint), c_size_t, POINTER(c_double)],
                         (c_uint * n)(*refs), n, (c_double * n)(*values))

    def set_integer(self, refs, values):
        n = len(refs)
        return self.call("fmi2SetInteger", [POINTER(c_uint), c_size_t, POINTER(c_int)],
                         (c_uint * n)(*refs), n, (c_int * n)(*values))

    def set_boolean(self, refs, values):
        n = len(refs)
        return self.call("fmi2SetBoolean", [POINTER(c_uint), c_size_t, POINTER(c_int)],
                         (c_uint * n)(*refs), n, (c_int * n)(*[int(bool(v)) for v in values]))

    def set(self, name, value):
        """Set one variable by name; returns the status."""
        t = variables()[name].type
        if t == "Real":
            return self.set_real([vr(name)], [float(value)])
        if t in ("Integer", "Enumeration"):
            return self.set_integer([vr(name)], [int(value)])
        if t == "Boolean":
            return self.set_boolean([vr(name)], [value])
        raise TypeError(name)

    def set_all(self, values: dict):
        for k, v in values.items():
            self.check(self.set(k, v), f"set {k} = {v}")

    def get_reals_raw(self, refs):
        n = len(refs)
        out = (c_double * n)()
        st = self.call("fmi2GetReal", [POINTER(c_uint), c_size_t, POINTER(c_double)], (c_uint * n)(*refs), n, out)
        return st, list(out)

    def get(self, *names):
        """Values by name (Real, Integer/Enumeration or Boolean); one value or a list."""
        out = []
        for name in names:
            t = variables()[name].type
            if t == "Real":
                st, v = self.get_reals_raw([vr(name)])
                v = v[0]
            else:
                arr = (c_int * 1)()
                fn = "fmi2GetBoolean" if t == "Boolean" else "fmi2GetInteger"
                st = self.call(fn, [POINTER(c_uint), c_size_t, POINTER(c_int)], (c_uint * 1)(vr(name)), 1, arr)
                v = bool(arr[0]) if t == "Boolean" else int(arr[0])
            self.check(st, f"get {name}")
            out.append(v)
        return out[0] if len(out) == 1 else out

    def enter_init(self):
        return self.call("fmi2EnterInitializationMode", [])

    def exit_init(self):
        return self.call("fmi2ExitInitializationMode", [])

    def initialize(self, values: dict, tolerance=None, start=0.0):
        """setupExperiment, start values, initialization mode; asserts every call succeeds."""
        self.check(self.setup(tolerance, start), "fmi2SetupExperiment")
        self.set_all(values)
        self.check(self.enter_init(), "fmi2EnterInitializationMode")
        self.check(self.exit_init(), "fmi2ExitInitializationMode")
        return self

    def do_step(self, t, h):
        return self.call("fmi2DoStep", [c_double, c_double, c_int], t, h, 1)

    def last_successful_time(self):
        v = c_double()
        st = self.call("fmi2GetRealStatus", [c_int, POINTER(c_double)], fmi2LastSuccessfulTime, byref(v))
        return st, v.value

    def free(self):
        if self.c:
            self.fmu.fmi2FreeInstance(self.c)
            self.fmu.freeLibrary()
            self.c = None


def cs(values: dict, tolerance=None, categories=None, name=None, directory=None) -> Instance:
    """A Co-Simulation instance initialised with the given start values."""
    return Instance("cs", name=name, categories=categories, directory=directory).initialize(values, tolerance)


def run_cs(inst: Instance, times, outputs, inputs=None):
    """Step inst through the communication points `times` (times[0] = its current time) and
    return {name: array} of the outputs sampled at every point (including times[0]).
    inputs: optional function t -> {name: value} applied before each step."""
    times = np.asarray(times, dtype=float)
    refs = [vr(n) for n in outputs]
    data = np.empty((len(times), len(refs)))
    st, data[0] = inst.get_reals_raw(refs)
    inst.check(st, "fmi2GetReal")
    for k in range(len(times) - 1):
        if inputs:
            for name, value in inputs(times[k]).items():
                inst.check(inst.set(name, value), f"set {name}")
        inst.check(inst.do_step(times[k], times[k + 1] - times[k]), f"fmi2DoStep at t = {times[k]}")
        st, data[k + 1] = inst.get_reals_raw(refs)
        inst.check(st, "fmi2GetReal")
    return {n: data[:, i] for i, n in enumerate(outputs)} | {"time": times}


def grid(t_end, h):
    n = int(round(t_end / h))
    return np.arange(n + 1) * h


def period_by_zero_crossings(t, x):
    """The mean period of an oscillation about zero from its upward zero crossings (linear
    interpolation between samples), and the number of crossings; the period is nan where there are
    fewer than two, so that the caller's assertion on the count, not an index error, reports it."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    s = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    tc = t[s] - x[s] * (t[s + 1] - t[s]) / (x[s + 1] - x[s])
    if len(tc) < 2:
        return float("nan"), len(tc)
    return float((tc[-1] - tc[0]) / (len(tc) - 1)), len(tc)
