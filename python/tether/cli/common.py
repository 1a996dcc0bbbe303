"""Helpers shared by subcommands: model/parameter resolution, atomic output."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from ..models import ModelSpec, ParamsFile, parse_model, read_params
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


def check_output_path(out: str, trace: Trace | None = None) -> Path:
    from . import CLIError

    p = Path(out)
    if p.is_dir():
        raise CLIError(f"--out {out}: is a directory; expected a file name such as prediction.csv")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise CLIError(f"--out {out}: directory {parent} does not exist")
    if trace is not None and p.exists():
        rp = p.resolve()
        if rp in (trace.csv_path.resolve(), trace.json_path.resolve()):
            raise CLIError(f"--out {out}: would overwrite the trace itself; choose another file")
    return p


def write_csv_atomic(path: Path, names: Sequence[str], columns: Sequence[np.ndarray]) -> None:
    """Write columns as CSV (full double precision), atomically (see :mod:`tether.atomic`)."""
    from ..atomic import write_with

    data = np.column_stack([np.asarray(c, dtype=float) for c in columns])

    def fill(f):
        f.write(",".join(names) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.17g")

    write_with(path, fill)
