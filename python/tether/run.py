"""Simulate a trace with the KevlarTether FMU (FMI 2.0 Co-Simulation, through fmpy).

:func:`simulate` runs one trace with one model and parameter set and returns the predicted
measured column (``displacement`` or ``elongation``) and the tension on the trace's own time grid.

How a trace drives the FMU
--------------------------
* Rig: ``free_vibration``/``forced`` -> payload rig (``m``, ``g``, ``x0``, ``v0`` from the trace);
  ``load_unload``/``creep`` -> load rig (input ``load``). ``L0`` = ``tether.length_m`` always.
  These trace values win over a parameter file.
* One ``fmi2DoStep`` per sample interval (non-uniform sampling is fine).
* Inputs are reconstructed by a cubic through the samples: ``force`` by a cubic spline
  (``not-a-knot`` ends; ``periodic`` for periodic records), ``load`` by a shape-preserving PCHIP
  (load tests ramp and hold; a spline rings at the corners). A trace may say otherwise with the
  extra JSON key ``input_interpolation`` ("spline", "pchip" or "linear"). Before each step the sample value and
  the spline's 1st..3rd derivatives at that sample are handed to the FMU
  (``fmi2SetRealInputDerivatives``), so the FMU integrates the spline piece exactly.
* ``periodic_samples`` P: start from rest (x0 = v0 = 0), repeat the period's input until
  successive periods agree (change below ``periodic_tol`` times the output RMS, with the remaining
  transient extrapolated from the decay ratio; at most ``max_periods``), then simulate the record's
  length (a whole number of periods) and return that.

Speed: the FMU is extracted and its library loaded once per process; each run instantiates and
frees an instance. The stepping loop calls the C functions through ctypes with pre-built arrays
and raw addresses (no per-step allocation).
"""

from __future__ import annotations

import ctypes
import itertools
import math
import threading
from ctypes import c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from .fmu import Description, FMUError, extract, fmu_path, model_description  # noqa: F401 (re-export)
from .models import ModelSpec, check_parameters, parse_model
from .traces import Trace, TraceError, read_trace

__all__ = ["simulate", "SimResult", "SimulationError", "model_description", "fmu_path", "FMUError", "input_pieces"]

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
_STATUS = {0: "fmi2OK", 1: "fmi2Warning", 2: "fmi2Discard", 3: "fmi2Error", 4: "fmi2Fatal", 5: "fmi2Pending"}


class SimulationError(RuntimeError):
    """The FMU failed on a trace; ``str(e)`` is one line naming the trace and the time reached."""


@dataclass
class SimResult:
    time: np.ndarray               # the trace's time grid
    measured_column: str           # 'displacement' or 'elongation'
    predicted: np.ndarray          # the model's prediction of the measured column
    tension: np.ndarray
    model: ModelSpec
    parameters: dict               # every value set on the FMU (model parameters + trace values)
    warnings: list = field(default_factory=list)   # FMU warnings (logStatusWarning)
    periods: int | None = None     # periodic records: periods run before the returned record
    final_strain: float = float("nan")   # the FMU's 'strain' (elongation / L0) at the last sample

    def rms_error(self, measured: np.ndarray) -> float:
        return float(np.sqrt(np.mean((self.predicted - measured) ** 2)))


# ---------------------------------------------------------------------------------------------
# the loaded FMU (one per process and FMU file)
class _Engine:
    def __init__(self, path: Path):
        from fmpy.fmi2 import FMU2Slave

        self.path = path
        self.desc: Description = model_description(path)
        unzip, self.key = extract(path)
        self.unzip = unzip
        self.slave = FMU2Slave(guid=self.desc.guid, modelIdentifier=self.desc.model_identifier,
                               unzipDirectory=str(unzip), instanceName="tether")
        dll = self.slave.dll

        def fn(name, restype, *argtypes):
            f = dll[name]          # a fresh function object: fmpy's own stay untouched
            f.restype = restype
            f.argtypes = list(argtypes)
            return f

        self.instantiate = fn("fmi2Instantiate", c_void_p, ctypes.c_char_p, c_int, ctypes.c_char_p,
                              ctypes.c_char_p, c_void_p, c_int, c_int)
        self.free_instance = fn("fmi2FreeInstance", None, c_void_p)
        self.setup_experiment = fn("fmi2SetupExperiment", c_int, c_void_p, c_int, c_double, c_double, c_int, c_double)
        self.enter_init = fn("fmi2EnterInitializationMode", c_int, c_void_p)
        self.exit_init = fn("fmi2ExitInitializationMode", c_int, c_void_p)
        self.terminate = fn("fmi2Terminate", c_int, c_void_p)
        self.set_debug_logging = fn("fmi2SetDebugLogging", c_int, c_void_p, c_int, c_size_t, c_void_p)
        # array arguments as raw addresses (ints): no conversion cost per call
        self.set_real = fn("fmi2SetReal", c_int, c_void_p, c_void_p, c_size_t, c_void_p)
        self.set_integer = fn("fmi2SetInteger", c_int, c_void_p, c_void_p, c_size_t, c_void_p)
        self.set_boolean = fn("fmi2SetBoolean", c_int, c_void_p, c_void_p, c_size_t, c_void_p)
        self.get_real = fn("fmi2GetReal", c_int, c_void_p, c_void_p, c_size_t, c_void_p)
        self.set_input_derivatives = fn("fmi2SetRealInputDerivatives", c_int, c_void_p, c_void_p, c_size_t,
                                        c_void_p, c_void_p)
        self.do_step = fn("fmi2DoStep", c_int, c_void_p, c_double, c_double, c_int)
        self.get_real_status = fn("fmi2GetRealStatus", c_int, c_void_p, c_int, c_void_p)
        self.resource_uri = (Path(unzip) / "resources").as_uri().encode()


_engines: dict = {}
_engine_lock = threading.Lock()


def _engine() -> _Engine:
    path = fmu_path()
    st = path.stat()
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    with _engine_lock:
        eng = _engines.get(key)
        if eng is None:
            eng = _engines[key] = _Engine(path)
    return eng


# ---------------------------------------------------------------------------------------------
# FMU log messages, routed to the run that caused them (componentEnvironment = run id)
_logs: dict[int, list] = {}
_run_ids = itertools.count(1)


def _log_to_run(env, instance_name, status, category, message):
    sink = _logs.get(env or 0)
    if sink is not None:
        sink.append((int(status), (category or b"").decode("utf-8", "replace"),
                     (message or b"").decode("utf-8", "replace")))


_logger_thunk: list = []


def _make_callbacks(run_id: int):
    """The callback struct of one run (its componentEnvironment routes the FMU's messages to the
    run). Every run shares one logger thunk that lives as long as the process: fmpy's native proxy,
    which formats the variadic arguments, calls the one logger registered last, for every instance;
    a logger of its own per run, freed with the run, left the proxy calling freed code when another
    instance logged afterwards (a crash, SIGILL, in the tests)."""
    from fmpy import calloc, free
    from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                           fmi2CallbackLoggerTYPE)
    from fmpy.logging import addLoggerProxy

    with _engine_lock:
        if not _logger_thunk:
            _logger_thunk.append(fmi2CallbackLoggerTYPE(_log_to_run))
    cb = fmi2CallbackFunctions()
    cb.logger = _logger_thunk[0]
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    cb.componentEnvironment = run_id
    addLoggerProxy(ctypes.byref(cb))
    return cb


# ---------------------------------------------------------------------------------------------
INTERPOLATIONS = ("spline", "pchip", "linear")


def input_interpolation(trace) -> str:
    """How the trace's input is reconstructed between samples: the JSON's optional
    ``input_interpolation`` ("spline", "pchip" or "linear"; an extra key the format allows), else a
    cubic spline for ``force`` and a shape-preserving PCHIP for ``load``."""
    kind = trace.meta.get("input_interpolation") if isinstance(trace.meta, dict) else None
    if kind is None:
        return "pchip" if trace.input_column == "load" else "spline"
    if kind not in INTERPOLATIONS:
        raise TraceError(f"{trace.json_path}: key 'input_interpolation' = {kind!r}: expected one of "
                         f"{', '.join(INTERPOLATIONS)}")
    return kind


def record_period(t, P: int) -> float:
    """The period [s] of a periodic record of ``P`` samples per period on the time grid ``t``: the
    time from its first sample to the first of the second period, or (one period only) P / (P - 1)
    times the span of its samples."""
    return float(t[P] - t[0]) if len(t) > P else float(t[P - 1] - t[0]) * P / (P - 1)


def _linear_pieces(t: np.ndarray, y: np.ndarray, periodic_period: float | None):
    """(values, derivatives[n, 3]) of the straight line from each sample to the next."""
    if periodic_period is not None:
        t = np.append(t, t[0] + periodic_period)
        y = np.append(y, y[0])
    ders = np.zeros((len(t) - 1, 3))
    ders[:, 0] = np.diff(y) / np.diff(t)
    return np.ascontiguousarray(y[:-1], dtype=float), ders


def input_pieces(t, y, periodic_period, kind):
    """(values, derivatives[n, 3]) of the input's interpolant piece by piece from each sample, as
    the FMU and the engine are driven: ``kind`` "linear", "pchip" or the cubic spline (periodic
    over ``periodic_period`` where given). One rule for the FMU's run, the engine's experiments and
    discovery's thinning check."""
    if kind == "linear":
        return _linear_pieces(t, y, periodic_period)
    return _spline_pieces(t, y, periodic_period, monotone=kind == "pchip")


def _spline_pieces(t: np.ndarray, y: np.ndarray, periodic_period: float | None, monotone: bool = False):
    """(values, derivatives[n, 3]) of the cubic spline piece starting at each knot.

    Non-periodic: not-a-knot spline through (t, y); pieces for knots 0..n-2.
    Periodic: ``t``, ``y`` hold one period (P samples); the period ``periodic_period`` closes it.
    ``monotone``: a shape-preserving PCHIP instead (for loads: ramps and holds must not ring; a
    cubic spline through a ramp-and-hold load overshoots by hundreds of newtons at the corners).
    """
    from scipy.interpolate import CubicSpline, PchipInterpolator   # here: a run without input needs no scipy

    if monotone:
        tk, yk = (np.append(t, t[0] + periodic_period), np.append(y, y[0])) if periodic_period is not None else (t, y)
        cs = PchipInterpolator(tk, yk)
    elif periodic_period is not None:
        tk = np.append(t, t[0] + periodic_period)
        yk = np.append(y, y[0])
        cs = CubicSpline(tk, yk, bc_type="periodic")
    elif len(t) >= 3:
        cs = CubicSpline(t, y, bc_type="not-a-knot")
    else:  # two samples: the straight line
        cs = CubicSpline(t, y, bc_type="natural")
    c = cs.c  # c[0] s^3 + c[1] s^2 + c[2] s + c[3] on piece i
    ders = np.empty((c.shape[1], 3))
    ders[:, 0] = c[2]
    ders[:, 1] = 2.0 * c[1]
    ders[:, 2] = 6.0 * c[0]
    # the value at the knot is the sample itself (c[3] equals it up to rounding)
    n = c.shape[1]
    values = np.ascontiguousarray(y[:n], dtype=float)
    return values, np.ascontiguousarray(ders)


class _Run:
    """One FMU instance for one trace."""

    def __init__(self, eng: _Engine, trace_name: str):
        self.eng = eng
        self.trace_name = trace_name
        self.run_id = next(_run_ids)
        _logs[self.run_id] = self.log = []
        self.callbacks = _make_callbacks(self.run_id)
        self.comp = eng.instantiate(b"tether", 1, eng.desc.guid.encode(), eng.resource_uri,
                                    ctypes.addressof(self.callbacks), 0, 0)
        if not self.comp:
            self.close()
            raise SimulationError(f"{trace_name}: the FMU could not be instantiated{self._last_message()}")
        cats = (ctypes.c_char_p * 2)(b"logStatusWarning", b"logStatusDiscard")
        eng.set_debug_logging(self.comp, 1, 2, ctypes.addressof(cats))

    def close(self):
        if getattr(self, "comp", None):
            self.eng.free_instance(self.comp)
            self.comp = None
        _logs.pop(self.run_id, None)

    def _last_message(self) -> str:
        msgs = [m for (s, _, m) in self.log if s >= DISCARD]
        text = f": {msgs[-1]}" if msgs else ""
        warns = self.warnings()
        if warns:
            text += f" (after the FMU warned: {warns[0]})"
        return text

    def warnings(self) -> list[str]:
        return [m for (s, _, m) in self.log if s == WARNING]

    def check(self, status: int, what: str, t: float | None = None):
        if status > WARNING:
            at = "" if t is None else f" at t = {t:.9g} s"
            raise SimulationError(f"{self.trace_name}: {what} failed{at} ({_STATUS.get(status, status)})"
                                  f"{self._last_message()}")

    def set_values(self, values: Mapping[str, float | int | bool]):
        desc = self.eng.desc
        for name, v in values.items():
            var = desc.variables[name]
            vr = (c_uint * 1)(var.vr)
            if var.type == "Real":
                buf = (c_double * 1)(float(v))
                st = self.eng.set_real(self.comp, ctypes.addressof(vr), 1, ctypes.addressof(buf))
            elif var.type in ("Integer", "Enumeration"):
                buf = (c_int * 1)(int(v))
                st = self.eng.set_integer(self.comp, ctypes.addressof(vr), 1, ctypes.addressof(buf))
            elif var.type == "Boolean":
                buf = (c_int * 1)(1 if v else 0)
                st = self.eng.set_boolean(self.comp, ctypes.addressof(vr), 1, ctypes.addressof(buf))
            else:
                raise SimulationError(f"{self.trace_name}: cannot set {var.type} variable '{name}'")
            self.check(st, f"setting {name} = {v!r}")

    def last_successful_time(self, fallback: float) -> float:
        buf = c_double(fallback)
        if self.eng.get_real_status(self.comp, 2, ctypes.addressof(buf)) == OK:  # fmi2LastSuccessfulTime
            return buf.value
        return fallback


def _segment(run: _Run, t_start: float, h: list, values, ders, in_vr_addr, der_vr_addr, order_addr,
             out_vr_addr, out: np.ndarray, t_label=None):
    """Step len(h) times from t_start; read (measured, tension) into out[i] *before* step i.

    values/ders: per-step input value and derivatives (None for no input). Returns the end time.
    """
    eng = run.eng
    comp = run.comp
    do_step, get_real = eng.do_step, eng.get_real
    set_real, set_der = eng.set_real, eng.set_input_derivatives
    assert out.flags.c_contiguous and out.shape == (len(h), 2)
    out_addr = out.ctypes.data
    t = t_start
    n = len(h)
    if values is None:
        for i in range(n):
            get_real(comp, out_vr_addr, 2, out_addr + 16 * i)
            st = do_step(comp, t, h[i], 1)
            if st:
                _step_failed(run, st, t, h[i], t_label)
            t += h[i]
        return t
    v_addr = values.ctypes.data
    d_addr = ders.ctypes.data
    for i in range(n):
        get_real(comp, out_vr_addr, 2, out_addr + 16 * i)
        set_real(comp, in_vr_addr, 1, v_addr + 8 * i)
        set_der(comp, der_vr_addr, 3, order_addr, d_addr + 24 * i)
        st = do_step(comp, t, h[i], 1)
        if st:
            _step_failed(run, st, t, h[i], t_label)
        t += h[i]
    return t


def _step_failed(run: _Run, st: int, t: float, h: float, t_label):
    if st == WARNING:
        return
    reached = run.last_successful_time(t) if st == DISCARD else t
    where = f"t = {reached:.9g} s" if t_label is None else t_label(reached)
    raise SimulationError(f"{run.trace_name}: the FMU stopped at {where} "
                          f"(step {t:.9g} s -> {t + h:.9g} s returned {_STATUS.get(st, st)})"
                          f"{run._last_message()}")


def simulate(trace: Trace | str | Path, model: str | ModelSpec = "linear",
             params: Mapping[str, float] | None = None, *, periodic_tol: float = 1e-3,
             max_periods: int = 20, check: bool = True, nuisance: Mapping[str, float] | None = None) -> SimResult:
    """Simulate ``trace`` with ``model`` and ``params`` (FMU start values for the rest).

    ``params`` may name any FMU parameter (see :func:`tether.models.check_parameters`); the
    trace's own values for L0, m, g, x0, v0, line_density win. ``nuisance`` (tether.nuisance, e.g. a
    fit's FitResult.nuisance for this trace): m, x0, v0, last_reversal_beyond over the trace's, and the measurement applied
    as the engine applies it (input_gain, offset_input on the input, offset_measured on the
    prediction). Raises SimulationError if the FMU fails and FMUError if it is missing.
    """
    from .nuisance import STATE, drive_input, measured_output

    nuisance = dict(nuisance or {})
    if not isinstance(trace, Trace):
        trace = read_trace(trace)
    spec = parse_model(model) if isinstance(model, str) else model
    spec = spec.for_experiment(trace.experiment)
    eng = _engine()
    desc = eng.desc
    params = dict(params or {})
    if check:
        params = check_parameters(params, "parameters", desc)
    for k in ("rig", "stiffness", "damping", "hysteresis", "creep", "slack"):
        params.pop(k, None)

    periodic = trace.periodic_samples
    values: dict = dict(spec.switches)
    values.update(params)
    L0 = float(trace.length_m)
    values.pop("L0", None)
    trace_values: dict = {}
    if spec.rig == "payload":
        trace_values.update(m=float(trace.payload_mass_kg), g=float(trace.gravity_m_s2),
                            x0=0.0 if periodic else float(trace.initial_displacement_m),
                            v0=0.0 if periodic else float(trace.initial_velocity_m_s),
                            line_density=float(trace.line_density_kg_m))
        trace_values.update({k: float(nuisance[k]) for k in ("m", *STATE) if k in nuisance})
    values.update(trace_values)

    t = trace.time
    N = len(t)
    name = str(trace.stem)
    in_name = trace.input_column
    # the FMU output that simulates the measured column: the load rig's elongation is the output
    # total_elongation (the input variable elongation only reads it back, kept for old importers)
    out_names = ({"elongation": "total_elongation"}.get(trace.measured_column, trace.measured_column), "tension")

    # input reconstruction
    if periodic:
        P = periodic
        Tp = record_period(t, P)
        h = np.diff(t[:P]).tolist() + [Tp - float(t[P - 1] - t[0])]
        if in_name:
            in_values, in_ders = input_pieces(t[:P], trace.input[:P], Tp, input_interpolation(trace))
        else:
            in_values = in_ders = None
    else:
        h = np.diff(t).tolist()
        if in_name:
            in_values, in_ders = input_pieces(t, trace.input, None, input_interpolation(trace))
        else:
            in_values = in_ders = None

    if in_values is not None:
        in_values, in_ders = drive_input(in_values, in_ders, nuisance)

    notes: list[str] = []
    if periodic and in_name and N > periodic:
        per = trace.input.reshape(-1, periodic)
        dev = float(np.max(np.abs(per - per[0])))
        scale = float(np.max(np.abs(per[0]))) or 1.0
        if dev > 1e-9 * scale:
            notes.append(f"{trace.csv_path}: the '{in_name}' column is not periodic with periodic_samples = "
                         f"{periodic} (largest difference from the first period {dev:.3g}); the first period "
                         "drives the whole run")

    run = _Run(eng, name)
    try:
        # parameters and switches, then the inputs' start values
        run.check(eng.setup_experiment(run.comp, 0, 0.0, float(t[0]), 0, 0.0), "fmi2SetupExperiment")
        run.set_values(values)
        start_inputs = {"L0": L0}
        if in_name:
            start_inputs[in_name] = float(drive_input(trace.input[:1], None, nuisance)[0][0])
        run.set_values(start_inputs)
        run.check(eng.enter_init(run.comp), "fmi2EnterInitializationMode")
        run.check(eng.exit_init(run.comp), "fmi2ExitInitializationMode")

        vr_in = (c_uint * 1)(desc.vr(in_name) if in_name else 0)
        vr_der = (c_uint * 3)(*([desc.vr(in_name)] * 3 if in_name else [0, 0, 0]))
        order = (c_int * 3)(1, 2, 3)
        vr_out = (c_uint * 2)(desc.vr(out_names[0]), desc.vr(out_names[1]))
        addr = (ctypes.addressof(vr_in), ctypes.addressof(vr_der), ctypes.addressof(order),
                ctypes.addressof(vr_out))

        if not periodic:
            out = np.empty((N, 2))
            t_end = _segment(run, float(t[0]), h, in_values, in_ders, *addr, out[:N - 1])
            last = out[N - 1:]
            run.check(eng.get_real(run.comp, addr[3], 2, last.ctypes.data), "fmi2GetReal", t_end)
            periods = None
        else:
            P = periodic
            t0 = float(t[0])
            k = 0

            def label(reached):
                return (f"t = {reached:.9g} s of the simulation (period {1 + int((reached - t0) // Tp)} "
                        f"of the periodic run, record time {t0 + (reached - t0) % Tp:.9g} s)")

            prev = None
            prev_change = None
            tcur = t0
            buf = np.empty((P, 2))
            converged = False
            change = scale = float("nan")
            while k < max_periods:
                tcur = _segment(run, tcur, h, in_values, in_ders, *addr, buf, label)
                k += 1
                y = buf[:, 0].copy()
                if prev is not None:
                    change = float(np.sqrt(np.mean((y - prev) ** 2)))
                    scale = float(np.sqrt(np.mean(y ** 2)))
                    limit = periodic_tol * scale if scale > 0 else 0.0
                    remaining = change
                    if prev_change is not None and prev_change > 0 and change < prev_change:
                        r = change / prev_change
                        remaining = change * r / (1.0 - r)
                    if change <= limit and remaining <= limit:
                        converged = True
                        break
                    prev_change = change
                prev = y
            warnings_extra = []
            if not converged:
                warnings_extra.append(
                    f"{name}: periodic steady state not reached after {max_periods} periods "
                    f"(last change between periods {change:.3g}, output RMS {scale:.3g}); using the last periods")
            out = np.empty((N, 2))
            for j in range(N // P):
                tcur = _segment(run, tcur, h, in_values, in_ders, *addr, out[j * P:(j + 1) * P], label)
            periods = k
        strain = c_double(float("nan"))
        vr_strain = c_uint(desc.vr("strain"))
        run.check(eng.get_real(run.comp, ctypes.addressof(vr_strain), 1, ctypes.addressof(strain)), "fmi2GetReal")
        warnings = notes + run.warnings()
        if periodic and warnings_extra:
            warnings += warnings_extra
    finally:
        run.close()

    all_values = dict(values)
    all_values["L0"] = L0
    return SimResult(time=t.copy(), measured_column=trace.measured_column,
                     predicted=np.ascontiguousarray(measured_output(out[:, 0], nuisance)),
                     tension=np.ascontiguousarray(out[:, 1]),
                     model=spec, parameters=all_values, warnings=warnings, periods=periods,
                     final_strain=strain.value)
