"""Helpers shared by subcommands: model/parameter resolution, checks of inputs and outputs, atomic output."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Sequence

if TYPE_CHECKING:       # imported where used: `tether --help` loads neither numpy nor the models
    from ..models import ModelSpec, ParamsFile
    from ..traces import Trace


def add_model_arguments(parser) -> None:
    parser.add_argument("--model", metavar="NAME",
                        help="model string: a preset (linear, cubic, simplified, kawabata, full) plus "
                             "'+effect' terms, e.g. linear+boucwen (default: the --params file's model, "
                             "else linear)")
    parser.add_argument("--params", metavar="FILE.json",
                        help="parameter file: {\"model\": ..., \"parameters\": {name: value}} or "
                             "{name: value}; FMU start values for the rest. The trace's length, mass, "
                             "gravity and initial state (L0, m, g, x0, v0) win over the file")


def resolve_model(args, trace: Trace | None = None) -> tuple[ModelSpec, dict, ParamsFile | None]:
    """(model spec, parameters, params file) from --model/--params; --model wins over the file."""
    from ..models import parse_model, read_params

    pf = read_params(args.params) if args.params else None
    if args.model:
        spec = parse_model(args.model)
    elif pf is not None and pf.model:
        spec = parse_model(pf.model)
    else:
        spec = parse_model("linear")
    if trace is not None:
        spec = spec.for_experiment(trace.experiment)
    return spec, (dict(pf.parameters) if pf else {}), pf


def check_output_path(out: str, trace: Trace | None = None, option: str = "--out") -> Path:
    """The path to write ``out`` at: a regular file or a new name in an existing writable folder.

    A directory, a device, a FIFO, anything on /proc, /sys or /dev, or the trace itself is refused
    (CLIError, exit 2) before any work; a symbolic link is followed (the file it names is replaced).
    """
    import os

    from ..filecheck import output_problem
    from . import CLIError

    problem = output_problem(out)
    if problem is not None:
        raise CLIError(f"{option} {out}: {problem}")
    p = Path(os.path.realpath(out))
    if trace is not None and p in (trace.csv_path.resolve(), trace.json_path.resolve()):
        raise CLIError(f"{option} {out}: would overwrite the trace itself; choose another file")
    return p


def check_report_dir(report: str | None, option: str = "--report") -> Path | None:
    """The folder to write a report into (made if missing); CLIError if it cannot be one."""
    if report is None:
        return None
    from ..filecheck import output_dir_problem
    from . import CLIError

    problem = output_dir_problem(report)
    if problem is not None:
        raise CLIError(f"{option} {report}: {problem}")
    return Path(report)


def read_checked_trace(path, **options) -> Trace:
    """:func:`tether.traces.read_trace` (with ``options``), then :func:`check_trace_values`: a trace
    the FMU can run."""
    from ..traces import read_trace

    trace = read_trace(path, **options)
    check_trace_values(trace)
    return trace


#: the trace metadata this tool accepts, beyond the FMU's declared min/max: (FMU name, JSON key,
#: lowest, highest, unit). Outside them a run only ends in an FMU failure (a strain past +-1 at
#: t = 0, a step size CVODE cannot represent), which is the input's fault: exit 2, not 1.
TRACE_LIMITS = (
    ("L0", "tether.length_m", 1e-6, 1e6, "m"),
    ("m", "payload_mass_kg", 1e-6, 1e6, "kg"),
    ("g", "gravity_m_s2", 0.0, 100.0, "m/s2"),
    ("v0", "initial_velocity_m_s", -1e3, 1e3, "m/s"),
)


def check_trace_values(trace: Trace) -> None:
    """The trace's length, mass, gravity and initial state inside the FMU's declared ranges and
    :data:`TRACE_LIMITS`, and the initial displacement within the FMU's strain range (|x0| <= L0).

    A value the FMU would refuse or run away from (a length of 1e-300 m, a mass of 1e300 kg) is a
    bad input (ParamsError, exit 2) that names the trace's key, not an FMU failure.
    """
    from ..models import ParamsError, check_parameters

    values = {"L0": trace.length_m, "m": trace.payload_mass_kg, "g": trace.gravity_m_s2,
              "x0": trace.initial_displacement_m, "v0": trace.initial_velocity_m_s}
    keys = {"L0": "tether.length_m", "m": "payload_mass_kg", "g": "gravity_m_s2", "x0": "initial_displacement_m",
            "v0": "initial_velocity_m_s"}
    where = str(trace.json_path)
    for name, value in values.items():
        if value is None:
            continue
        try:
            check_parameters({name: value}, where)
        except ParamsError as e:
            raise ParamsError(str(e).replace(f"key '{name}'", f"key '{keys[name]}' (the FMU's {name})", 1)) from None
    for name, key, lo, hi, unit in TRACE_LIMITS:
        v = values[name]
        if v is not None and not lo <= v <= hi:
            raise ParamsError(f"{where}: key '{key}': value {v:g} is outside [{lo:g}, {hi:g}] {unit}, the range "
                              "this tool simulates")
    if trace.rig == "payload" and abs(trace.initial_displacement_m) > trace.length_m:
        raise ParamsError(f"{where}: initial displacement {trace.initial_displacement_m:g} m (key "
                          f"'initial_displacement_m', else the first displacement sample) is more than the tether's "
                          f"length {trace.length_m:g} m: a strain beyond +-1, which the FMU cannot simulate")


def write_csv_atomic(path: Path, names: Sequence[str], columns: Sequence) -> None:
    """Write columns as CSV (full double precision), atomically (see :mod:`tether.atomic`)."""
    import numpy as np

    from ..atomic import write_with

    data = np.column_stack([np.asarray(c, dtype=float) for c in columns])

    def fill(f):
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")

    write_with(path, fill)


def positive_number(what: str):
    """An argparse ``type`` for a finite number > 0; the message names what the number is."""
    def parse(text: str) -> float:
        import argparse
        import math

        try:
            v = float(text)
        except ValueError:
            v = float("nan")
        if not (math.isfinite(v) and v > 0):
            raise argparse.ArgumentTypeError(f"expected a positive number ({what}), got {text!r}")
        return v
    return parse


def add_mass_band_argument(parser, what: str = "a free m") -> None:
    """--mass-band REL (tether fit, tether discover): the band of the effective payload mass."""
    parser.add_argument("--mass-band", metavar="REL", dest="mass_band",
                        help=f"keep {what} within payload_mass_kg * (1 +- REL), 0 <= REL < 1 (default: the "
                             "trace's mass_uncertainty_rel, else 0.3; docs/nuisance.md)")


def mass_band_argument(args) -> float | None:
    """The checked --mass-band value (None if not given); CLIError (exit 2) for a bad one."""
    from ..nuisance import check_mass_band
    from . import CLIError

    if getattr(args, "mass_band", None) is None:
        return None
    try:
        return check_mass_band(args.mass_band)
    except ValueError as e:
        raise CLIError(str(e)) from None
