"""ctypes binding of the native identification engine (``libtether_identify.so``, fmu_src/identify).

The engine runs the FMU's own physics (the same C sources, linked as ``tether_core``) in batch and
fits parameters by Levenberg-Marquardt. Parameters and outputs are named as in modelDescription.xml.

Library lookup (:func:`tether.resources.identify_library_candidates`): env ``KT_IDENTIFY_LIB``;
else the one installed inside the package; else ``<repo>/build/fmu_src/identify/libtether_identify.so``
(where the top-level CMake build puts it), then ``<repo>/build/libtether_identify.so``.

    from tether.identify_native import Experiment, simulate, fit
    e = Experiment(time, settings={"rig": 2, "stiffness": 2, "m": 4.3, "L0": 16, "x0": -0.1669},
                   measured=x)
    r = fit([e], {"a1": (100, 1e5, 1000), ...})
"""

from __future__ import annotations

import ctypes as C
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

__all__ = ["Experiment", "FitResult", "MEASUREMENT_DEFAULTS", "PROGRESS", "experiment_from_trace", "library", "parameter_names", "parameter_start", "simulate", "fit", "deadlines", "DeadlinePassed", "bouc_wen_path",
           "spline_derivatives", "INPUT_NONE", "INPUT_FORCE", "INPUT_LOAD"]

INPUT_NONE, INPUT_FORCE, INPUT_LOAD = 0, 1, 2
#: the engine's KT_IDENTIFY_API_VERSION this binding is written for
API_VERSION = 10
#: parameter kinds of the engine's table (identify.h KT_PAR_*)
KIND_REAL, KIND_SWITCH, KIND_INPUT, KIND_MEASUREMENT = 0, 1, 2, 3
#: the measurement parameters of an experiment (identify.h KT_PAR_MEASUREMENT) and their defaults:
#: the model is driven by input_gain * recorded input + offset_input (its derivatives by input_gain
#: times the recorded ones) and the measured column is the model's output + offset_measured
MEASUREMENT_DEFAULTS = {"offset_measured": 0.0, "offset_input": 0.0, "input_gain": 1.0}
SCALE = {"auto": 0, "log": 1, "linear": 2}
#: kt_fit_options.central_differences: forward differences throughout (FORWARD), central throughout
#: (CENTRAL), or forward until the last stage stops and then central differences polish the optimum
#: and give the statistics (POLISH_CENTRAL, the engine's default; docs/fit-convergence.md)
FORWARD, CENTRAL, POLISH_CENTRAL = 0, 1, 2

_DP = C.POINTER(C.c_double)
_IP = C.POINTER(C.c_int)


class _Experiment(C.Structure):
    _fields_ = [
        ("n_settings", C.c_int), ("setting_names", C.POINTER(C.c_char_p)), ("setting_values", _DP),
        ("n", C.c_int), ("time", _DP),
        ("input_kind", C.c_int), ("input", _DP), ("input_der", _DP),
        ("output", C.c_char_p), ("measured", _DP), ("weight", C.c_double),
        ("periodic_samples", C.c_int), ("periodic_tol", C.c_double), ("periodic_max_periods", C.c_int),
        ("sample_weight", _DP),
    ]


class _Options(C.Structure):
    _fields_ = [
        ("max_iterations", C.c_int), ("ftol", C.c_double), ("xtol", C.c_double), ("gtol", C.c_double),
        ("fd_step", C.c_double), ("central_differences", C.c_int), ("n_starts", C.c_int),
        ("start_spread", C.c_double), ("seed", C.c_uint), ("n_threads", C.c_int), ("rtol", C.c_double),
        ("singular_rel_tol", C.c_double), ("max_rel_std", C.c_double), ("stat_tol", C.c_double),
        ("output_stride", C.c_int), ("horizon_stages", C.c_int), ("verbose", C.c_int),
        ("progress", C.c_void_p), ("progress_ctx", C.c_void_p),
        ("deadline_monotonic", C.c_double), ("deadline_cpu", C.c_double), ("deadline_thread_cpu", C.c_double),
        ("continuous_input", C.c_int), ("broyden_updates", C.c_int), ("max_rhs_evaluations", C.c_double),
        ("crawl_factor", C.c_double),
    ]


#: int progress(ctx, start, stage, n_stages, iteration, cost, evaluations); nonzero stops the fit
PROGRESS = C.CFUNCTYPE(C.c_int, C.c_void_p, C.c_int, C.c_int, C.c_int, C.c_int, C.c_double, C.c_long)


class _Result(C.Structure):
    _fields_ = [
        ("values", _DP), ("covariance", _DP), ("std_error", _DP), ("ci_low", _DP), ("ci_high", _DP),
        ("correlation", _DP), ("singular_values", _DP), ("singular_vectors", _DP),
        ("direction_flags", _IP), ("unidentifiable", _IP),
        ("cost_history", _DP), ("cost_history_capacity", C.c_int), ("cost_history_length", C.c_int),
        ("cost", C.c_double), ("rms", C.c_double), ("sigma2", C.c_double), ("condition", C.c_double),
        ("n_residuals", C.c_int), ("dof", C.c_int), ("evaluations", C.c_int),
        ("jacobian_evaluations", C.c_int), ("iterations", C.c_int),
        ("best_start", C.c_int), ("status", C.c_int), ("seconds", C.c_double), ("cpu_seconds", C.c_double),
        ("message", C.c_char * 256), ("report", C.c_char * 4096), ("rhs_evaluations", C.c_longlong),
    ]


_lib = None


def _candidates() -> list[Path]:
    from .resources import identify_library_candidates

    return identify_library_candidates()


from .resources import SETUP_HINT  # noqa: E402


def library() -> C.CDLL:
    """The loaded engine (raises FileNotFoundError naming the places looked at)."""
    global _lib
    if _lib is not None:
        return _lib
    cands = _candidates()
    path = next((p for p in cands if p.is_file()), None)
    if path is None:
        raise FileNotFoundError("libtether_identify.so not found (looked at: " + ", ".join(map(str, cands)) +
                                "); " + SETUP_HINT + ", or set KT_IDENTIFY_LIB")
    lib = C.CDLL(str(path))
    lib.kt_api_version.restype = C.c_int
    lib.kt_parameter_count.restype = C.c_int
    lib.kt_parameter_name.restype = C.c_char_p
    lib.kt_parameter_name.argtypes = [C.c_int, _IP]
    lib.kt_parameter_index.argtypes = [C.c_char_p]
    lib.kt_parameter_start.restype = C.c_double
    lib.kt_parameter_start.argtypes = [C.c_char_p]
    lib.kt_last_error.restype = C.c_char_p
    lib.kt_last_simulation_work.restype = C.c_longlong
    lib.kt_simulate_outputs.argtypes = [C.POINTER(_Experiment), C.c_int, C.POINTER(C.c_char_p), _DP, C.c_int,
                                        C.POINTER(C.c_char_p), _DP]
    lib.kt_fit_default_options.argtypes = [C.POINTER(_Options)]
    lib.kt_fit.argtypes = [C.POINTER(_Experiment), C.c_int, C.c_int, C.POINTER(C.c_char_p), _DP, _DP, _DP, _IP,
                           C.POINTER(_Options), C.POINTER(_Result)]
    lib.kt_bouc_wen_path.argtypes = [C.c_double, C.c_double, C.c_double, _DP, C.c_int, C.c_int, _DP]
    lib.kt_simulation_cache_bytes.restype = C.c_longlong
    lib.kt_simulation_cache_bytes.argtypes = [C.c_longlong]
    lib.kt_simulation_cache_counts.argtypes = [C.POINTER(C.c_longlong), C.POINTER(C.c_longlong)]
    if lib.kt_api_version() != API_VERSION:
        raise RuntimeError(f"{path}: API version {lib.kt_api_version()}, this binding expects {API_VERSION} "
                           "(rebuild it with `cmake --build build`)")
    _lib = lib
    return lib


def parameter_names(kind: int | None = None) -> list[str]:
    """Names the engine accepts (kind 0 Real parameters, 1 switches, 2 the input L0, 3 the
    measurement parameters offset_measured, offset_input, input_gain; None = all)."""
    lib = library()
    out = []
    for i in range(lib.kt_parameter_count()):
        k = C.c_int()
        name = lib.kt_parameter_name(i, C.byref(k)).decode()
        if kind is None or k.value == kind:
            out.append(name)
    return out


def parameter_start(name: str) -> float:
    return library().kt_parameter_start(name.encode())


def _dbl(a: np.ndarray | None):
    return None if a is None else a.ctypes.data_as(_DP)


def _names(names: Sequence[str]):
    arr = (C.c_char_p * max(1, len(names)))(*[n.encode() for n in names])
    return arr


def bouc_wen_path(x, A: float, beta: float, gamma: float, periodic: bool = False) -> np.ndarray:
    """z of the Bouc-Wen law with n = 1, dz/dx = A - |z| (gamma + beta sgn(dx z)), along the
    displacement path x from z = 0, integrated exactly between samples (physics/boucwen.c,
    boucwen_path). periodic: the path is closed and run twice, the second pass returned."""
    xs = np.ascontiguousarray(x, dtype=float)
    if xs.ndim != 1 or len(xs) < 1:
        raise ValueError(f"bouc_wen_path: x must be a non-empty 1-D array, got shape {xs.shape}")
    z = np.empty_like(xs)
    if library().kt_bouc_wen_path(float(A), float(beta), float(gamma), _dbl(xs), len(xs), int(bool(periodic)),
                                  _dbl(z)) != 0:
        raise ValueError(library().kt_last_error().decode())
    return z


def spline_derivatives(time: np.ndarray, values: np.ndarray, periodic: bool = False) -> np.ndarray:
    """n x 3 derivatives (orders 1..3) at the samples of the not-a-knot (or periodic) cubic spline
    through the samples; what an importer passes to fmi2SetRealInputDerivatives."""
    from scipy.interpolate import CubicSpline

    t = np.asarray(time, float)
    v = np.asarray(values, float)
    if periodic:
        dt = t[1] - t[0]
        cs = CubicSpline(np.append(t, t[-1] + dt), np.append(v, v[0]), bc_type="periodic")
    else:
        cs = CubicSpline(t, v)
    return np.column_stack([cs(t, 1), cs(t, 2), cs(t, 3)])


@dataclass
class Experiment:
    """One experiment: time grid, settings (name -> value), input, output name and measurement."""

    time: np.ndarray
    settings: Mapping[str, float] = field(default_factory=dict)
    input_kind: int = INPUT_NONE
    input: np.ndarray | None = None
    input_der: np.ndarray | None = None   # n x 3; None with an input: cubic spline derivatives
    output: str = "displacement"
    measured: np.ndarray | None = None
    weight: float = 1.0
    periodic_samples: int = 0
    periodic_tol: float = 0.0
    periodic_max_periods: int = 0
    sample_weight: np.ndarray | None = None   # n factors on the residuals; 0 leaves a sample out of a fit

    def _struct(self, keep: list) -> _Experiment:
        t = np.ascontiguousarray(self.time, dtype=float)
        names = list(self.settings)
        vals = np.ascontiguousarray([float(self.settings[n]) for n in names], dtype=float)
        s = _Experiment()
        s.n_settings = len(names)
        name_array = _names(names)
        keep.append(name_array)
        s.setting_names = C.cast(name_array, C.POINTER(C.c_char_p)) if names else None
        s.setting_values = _dbl(vals)
        s.n = len(t)
        s.time = _dbl(t)
        s.input_kind = int(self.input_kind)
        inp = der = None
        if self.input_kind != INPUT_NONE:
            inp = np.ascontiguousarray(self.input, dtype=float)
            if inp.shape != t.shape:
                raise ValueError(f"input has {inp.size} samples, time has {t.size}")
            der = self.input_der
            if der is None:
                der = spline_derivatives(t, inp, periodic=self.periodic_samples > 0 and self.periodic_samples == len(t))
            der = np.ascontiguousarray(der, dtype=float)
            if der.shape != (len(t), 3):
                raise ValueError(f"input_der has shape {der.shape}, expected ({len(t)}, 3)")
        s.input = _dbl(inp)
        s.input_der = _dbl(der)
        s.output = self.output.encode()
        meas = None if self.measured is None else np.ascontiguousarray(self.measured, dtype=float)
        if meas is not None and meas.shape != t.shape:
            raise ValueError(f"measured has {meas.size} samples, time has {t.size}")
        s.measured = _dbl(meas)
        s.weight = float(self.weight)
        s.periodic_samples = int(self.periodic_samples or 0)
        s.periodic_tol = float(self.periodic_tol)
        s.periodic_max_periods = int(self.periodic_max_periods)
        sw = None if self.sample_weight is None else np.ascontiguousarray(self.sample_weight, dtype=float)
        if sw is not None and (sw.shape != t.shape or not np.all(np.isfinite(sw)) or np.any(sw < 0)):
            raise ValueError(f"sample_weight must be {t.size} finite factors >= 0")
        s.sample_weight = _dbl(sw)
        keep.extend([t, vals, inp, der, meas, sw, s.output])
        return s


def experiment_from_trace(trace, settings: Mapping[str, float] | None = None, weight: float = 1.0) -> Experiment:
    """An Experiment for a checked trace (tether.traces.Trace): rig, input, measured column, L0,
    payload mass, line density, gravity, initial state and periodic_samples from the trace; `settings` adds the
    model's switches and fixed parameters (e.g. {"stiffness": 2, "damping": 2, "hysteresis": 3})."""
    payload = trace.experiment in ("free_vibration", "forced")
    st: dict[str, float] = {"rig": 2 if payload else 3, "L0": float(trace.length_m), "g": float(trace.gravity_m_s2)}
    if payload:
        st.update(m=float(trace.payload_mass_kg), x0=float(trace.initial_displacement_m),
                  v0=float(trace.initial_velocity_m_s), line_density=float(trace.line_density_kg_m))
    st.update(settings or {})
    kind = {None: INPUT_NONE, "force": INPUT_FORCE, "load": INPUT_LOAD}[trace.input_column]
    P = int(trace.periodic_samples or 0)
    inp = None if kind == INPUT_NONE else np.asarray(trace.input, float)
    der = None
    if inp is not None:
        if P:
            one = spline_derivatives(trace.time[:P], inp[:P], periodic=True)
            der = np.tile(one, (len(inp) // P, 1))
        else:
            der = spline_derivatives(trace.time, inp)
    return Experiment(np.asarray(trace.time, float), settings=st, input_kind=kind, input=inp, input_der=der,
                      output=trace.measured_column, measured=np.asarray(trace.measured, float), weight=weight,
                      periodic_samples=P)


def payload_masses(trace) -> tuple[float, float]:
    """(M_w, M_eff) of a payload trace: the mass whose weight M_w g the balance carries,
    m + w L0 / 2, and the mass the payload's acceleration sees (the FMU's effective_mass, read from
    the engine); both m for a massless line (docs/models.md, "The line's own mass")."""
    m, w, L0 = float(trace.payload_mass_kg), float(trace.line_density_kg_m), float(trace.length_m)
    if w == 0.0:
        return m, m
    e = Experiment(np.array([0.0, 1.0]), settings={"rig": 2, "m": m, "L0": L0, "line_density": w, "g": 0.0})
    return m + 0.5 * w * L0, float(simulate(e, outputs=["effective_mass"])[0, 0])


def simulate(exp: Experiment, params: Mapping[str, float] | None = None,
             outputs: Sequence[str] | None = None) -> np.ndarray:
    """The experiment's output at its samples (n,), or n x len(outputs) if outputs are given.
    params may hold the measurement parameters (MEASUREMENT_DEFAULTS): the engine drives the model
    with input_gain * input + offset_input and adds offset_measured to the measured column."""
    lib = library()
    keep: list = []
    s = exp._struct(keep)
    params = dict(params or {})
    names = list(params)
    vals = np.ascontiguousarray([float(params[n]) for n in names], dtype=float)
    outs = list(outputs) if outputs else [exp.output]
    out = np.empty((len(exp.time), len(outs)))
    rc = lib.kt_simulate_outputs(C.byref(s), len(names), _names(names), _dbl(vals), len(outs), _names(outs),
                                 _dbl(out))
    _work.done = simulation_work() + int(lib.kt_last_simulation_work())
    if rc != 0:
        raise RuntimeError("kt_simulate: " + lib.kt_last_error().decode())
    return out[:, 0] if outputs is None else out


_work = threading.local()


def simulation_work() -> int:
    """The evaluations of the model's equations that this thread's :func:`simulate` calls have made
    so far: the unit of the fit option ``max_rhs_evaluations``, a cap on a fit's work that, unlike a
    CPU-time deadline, stops the same fit at the same point however busy the machine is."""
    return getattr(_work, "done", 0)


def simulation_cache_bytes(bytes_: int) -> int:
    """Bound the engine's simulation cache to ``bytes_`` (0: off, and emptied); returns the bound
    before. The engine keeps the simulations it made (256 MiB of them to begin with) and reads one
    back where a fit or :func:`simulate` asks for it again: the same bits, its work counted as
    its own."""
    return int(library().kt_simulation_cache_bytes(int(bytes_)))


def simulation_cache_counts() -> tuple[int, int]:
    """(read back, made): the engine's simulations since the process started."""
    reused, made = C.c_longlong(0), C.c_longlong(0)
    library().kt_simulation_cache_counts(C.byref(reused), C.byref(made))
    return reused.value, made.value


@dataclass
class FitResult:
    names: list[str]
    values: np.ndarray
    std_error: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    singular_values: np.ndarray
    singular_vectors: np.ndarray     # column i = direction i (scaled parameters)
    direction_flags: np.ndarray
    unidentifiable: list[str]        # names of parameters in undetermined directions
    report: str                      # the undetermined directions, one line each
    cost_history: np.ndarray
    cost: float
    rms: float
    sigma2: float
    condition: float
    n_residuals: int
    dof: int
    evaluations: int
    iterations: int
    best_start: int
    status: int
    message: str
    seconds: float
    #: of ``evaluations``, the simulations of finite-difference Jacobian columns
    jacobian_evaluations: int = 0
    #: CPU seconds of the fit (the calling thread's and the engine's helper threads')
    cpu_seconds: float = 0.0
    #: the fit's work: evaluations of the model's equations over all its simulations (the unit of
    #: the option max_rhs_evaluations)
    rhs_evaluations: int = 0

    def as_dict(self) -> dict[str, float]:
        return dict(zip(self.names, map(float, self.values)))


class DeadlinePassed(RuntimeError):
    """A fit stopped at one of its deadlines (see :func:`deadlines`) or its work cap;
    ``clock`` is "wall", "cpu" or "work"."""

    def __init__(self, message: str, clock: str):
        super().__init__(message)
        self.clock = clock


def deadlines(wall_seconds: float | None = None, cpu_seconds: float | None = None,
              thread_cpu_seconds: float | None = None) -> dict:
    """Options for :func:`fit` that stop it ``wall_seconds`` of wall time, ``cpu_seconds`` of
    this process's CPU time (all threads) or ``thread_cpu_seconds`` of the calling thread's CPU
    time (with n_threads=1: the fit's own, whatever runs beside it) from now; None = no limit."""
    import time

    out = {}
    if thread_cpu_seconds is not None:
        out["deadline_thread_cpu"] = (time.clock_gettime(time.CLOCK_THREAD_CPUTIME_ID)
                                      + max(float(thread_cpu_seconds), 1e-9))
    if wall_seconds is not None:
        out["deadline_monotonic"] = time.clock_gettime(time.CLOCK_MONOTONIC) + max(float(wall_seconds), 1e-9)
    if cpu_seconds is not None:
        out["deadline_cpu"] = time.clock_gettime(time.CLOCK_PROCESS_CPUTIME_ID) + max(float(cpu_seconds), 1e-9)
    return out


def fit(experiments: Sequence[Experiment], free: Mapping[str, tuple], *, scaling: Mapping[str, str] | None = None,
        **options) -> FitResult:
    """Fit the free parameters (name -> (lower, upper, start)) to all experiments jointly.

    options: any field of kt_fit_options (max_iterations, ftol, xtol, gtol, fd_step,
    central_differences, n_starts, start_spread, seed, n_threads, rtol, singular_rel_tol,
    max_rel_std, stat_tol, output_stride, horizon_stages, continuous_input, broyden_updates, crawl_factor,
    verbose,
    deadline_monotonic,
    deadline_cpu and deadline_thread_cpu (readings of time.CLOCK_MONOTONIC,
    time.CLOCK_PROCESS_CPUTIME_ID and the calling thread's time.CLOCK_THREAD_CPUTIME_ID, see
    :func:`deadlines`; the fit raises DeadlinePassed, a RuntimeError "kt_fit: stopped: the ...
    deadline passed", once one passes, even inside an iteration), max_rhs_evaluations (a cap on
    the fit's work, see :func:`simulation_work`; DeadlinePassed with clock "work"), and
    ``progress``: a callable f(start, stage, n_stages, iteration, cost, evaluations) called after
    every LM iteration; a true return value stops the fit (RuntimeError), an exception it raises
    stops the fit and is raised again here."""
    lib = library()
    progress = options.pop("progress", None)
    keep: list = []
    arr = (_Experiment * len(experiments))()
    for i, e in enumerate(experiments):
        if e.measured is None:
            raise ValueError(f"experiment {i}: no measured samples")
        arr[i] = e._struct(keep)
    names = list(free)
    k = len(names)
    lo = np.ascontiguousarray([float(free[n][0]) for n in names])
    hi = np.ascontiguousarray([float(free[n][1]) for n in names])
    st = np.ascontiguousarray([float(free[n][2]) for n in names])
    sc = np.ascontiguousarray([SCALE[(scaling or {}).get(n, "auto")] for n in names], dtype=np.int32)
    o = _Options()
    lib.kt_fit_default_options(C.byref(o))
    for key, v in options.items():
        if key not in dict(_Options._fields_):
            raise TypeError(f"fit: unknown option '{key}'")
        setattr(o, key, v)
    raised: list = []
    if progress is not None:
        def _progress(_ctx, start, stage, n_stages, iteration, cost, evaluations):
            try:
                return 1 if progress(start, stage, n_stages, iteration, cost, evaluations) else 0
            except BaseException as exc:  # noqa: BLE001 - re-raised after kt_fit returns
                raised.append(exc)
                return 1
        callback = PROGRESS(_progress)
        keep.append(callback)
        o.progress = C.cast(callback, C.c_void_p)
    vals, se, cl, ch, sv = (np.zeros(k) for _ in range(5))
    cov, cor, vec = (np.zeros((k, k)) for _ in range(3))
    dfl = np.zeros(k, dtype=np.int32)
    unid = np.zeros(k, dtype=np.int32)
    hist = np.zeros(10000)
    r = _Result()
    r.values, r.std_error, r.ci_low, r.ci_high = _dbl(vals), _dbl(se), _dbl(cl), _dbl(ch)
    r.covariance, r.correlation, r.singular_values, r.singular_vectors = _dbl(cov), _dbl(cor), _dbl(sv), _dbl(vec)
    r.direction_flags, r.unidentifiable = dfl.ctypes.data_as(_IP), unid.ctypes.data_as(_IP)
    r.cost_history, r.cost_history_capacity = _dbl(hist), len(hist)
    rc = lib.kt_fit(arr, len(experiments), k, _names(names), _dbl(lo), _dbl(hi), _dbl(st), sc.ctypes.data_as(_IP),
                    C.byref(o), C.byref(r))
    if raised:
        raise raised[0]
    if rc < 0:
        msg = "kt_fit: " + lib.kt_last_error().decode().removeprefix("kt_fit: ")
        # the engine's messages of a passed deadline (Limits::message in simulate.cpp)
        for clock, text in (("wall", "stopped: the wall-time deadline passed"),
                            ("cpu", "stopped: the CPU-time deadline passed"),
                            ("work", "stopped: the work cap passed")):
            if text in msg:
                raise DeadlinePassed(msg, clock)
        raise RuntimeError(msg)
    return FitResult(
        names=names, values=vals, std_error=se, ci_low=cl, ci_high=ch, covariance=cov, correlation=cor,
        singular_values=sv, singular_vectors=vec, direction_flags=dfl.astype(bool),
        unidentifiable=[n for n, f in zip(names, unid) if f], report=r.report.decode(),
        cost_history=hist[:r.cost_history_length].copy(), cost=r.cost, rms=r.rms, sigma2=r.sigma2,
        condition=r.condition, n_residuals=r.n_residuals, dof=r.dof, evaluations=r.evaluations,
        iterations=r.iterations, best_start=r.best_start, status=r.status, message=r.message.decode(),
        seconds=r.seconds, jacobian_evaluations=r.jacobian_evaluations, cpu_seconds=r.cpu_seconds,
        rhs_evaluations=int(r.rhs_evaluations))
