"""tether simulate: run one trace through the FMU and write the prediction."""

from __future__ import annotations

from .common import add_model_arguments, check_output_path, read_checked_trace, resolve_model, write_csv_atomic

NAME = "simulate"
HELP = "simulate a trace with a model and write time, the predicted measured column and tension"
DESCRIPTION = """\
Simulate TRACE (NAME.csv + NAME.json, give either file or the stem) with the KevlarTether FMU and
write OUT.csv with the columns time, the predicted measured column (displacement for
free_vibration/forced, elongation for load_unload/creep) and tension, on the trace's time grid.
The measured column may be absent (an input-only trace: a pure prediction).

The trace sets L0 (tether.length_m) and, for the payload rig, m, g, x0 and v0; these win over
--params. Everything not given keeps the FMU's start value. Output is written atomically: on any
error no OUT file is created or changed.

Exit status: 0 ok; 2 bad trace, model, parameter file or arguments; 1 FMU missing or failed.
"""


def add_arguments(parser) -> None:
    parser.add_argument("trace", metavar="TRACE", help="NAME.csv, NAME.json or NAME")
    add_model_arguments(parser)
    parser.add_argument("--out", metavar="OUT.csv", required=True, help="output CSV file")


def run(args) -> int:
    from ..run import simulate
    from . import warn

    trace = read_checked_trace(args.trace, require_measured=False)   # input-only traces: a pure prediction
    spec, params, pf = resolve_model(args, trace)
    out = check_output_path(args.out, trace)
    from ..nuisance import of_params_file
    result = simulate(trace, spec, params, nuisance=of_params_file(pf.extra, trace) if pf else None)
    for w in result.warnings:
        warn(w)
    write_csv_atomic(out, ["time", result.measured_column, "tension"],
                     [result.time, result.predicted, result.tension])
    return 0
