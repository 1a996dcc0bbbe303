"""tether validate: run the FMU on measured traces and report how well the model reproduces them."""

from __future__ import annotations

import time
from pathlib import Path

from .common import add_model_arguments, positive_number

NAME = "validate"
HELP = "simulate traces with the FMU and report RMS error, NRMSE, R^2 and the largest error, with plots"
DESCRIPTION = """\
Simulate each TRACE (NAME.csv + NAME.json, the stem, or a directory of traces) with the
KevlarTether FMU and report per trace: the RMS error, the normalized RMS error (RMS error over the
standard deviation of the measurement), R^2, the largest error and its time, and whether the error
is within the noise the trace states (the project's synthetic reference traces state theirs).

Without TRACE it validates everything in reference_results/. Without --model and --params a
synthetic trace runs with the model that generated it, any other trace with the linear baseline.

Writes a table to the terminal, DIR/validation.json and DIR/index.html with a plot per trace
(measured and simulated against time, the residual, and for load tests the tension-elongation
loop).

--tolerance bounds the normalized RMS error (NRMSE: the RMS error over the standard deviation of
the measured column; 0.05 by default, i.e. 5 % of the measurement's spread, about R^2 >= 0.9975).
Exit status: 0 every trace within the tolerance; 1 any trace outside it, or the FMU missing or
failed; 2 bad input.
"""

#: the default bound on the normalized RMS error (RMS error / standard deviation of the measurement)
DEFAULT_TOLERANCE = 0.05


def add_arguments(parser) -> None:
    parser.add_argument("traces", metavar="TRACE", nargs="*", help="traces or directories (default: reference_results/)")
    add_model_arguments(parser)
    parser.add_argument("--report", metavar="DIR", default="reports/validate",
                        help="report directory (default: reports/validate)")
    from .sweep import add_scheduler_argument
    add_scheduler_argument(parser)
    parser.add_argument("--tolerance", metavar="NRMSE", type=positive_number("a normalized RMS error"), default=DEFAULT_TOLERANCE,
                        help="largest normalized RMS error (RMS error / standard deviation of the measurement) "
                             f"a trace may have; any trace above it makes the exit status 1 (default {DEFAULT_TOLERANCE})")



def run(args) -> int:
    from ..models import parse_model, read_params
    from ..report import plot_validation, validation_page, validation_table, write_json_atomic, write_text_atomic
    from ..traces import COLUMN_UNITS
    from ..validate import find_traces, validate_trace
    from . import CLIError, RUN_ERROR, warn
    from .common import check_report_dir, read_checked_trace
    from .console import Progress

    from ..resources import reference_results_dir

    paths = args.traces or [reference_results_dir()]
    stems = find_traces(paths)
    if not stems:
        raise CLIError(f"no traces found in {', '.join(str(p) for p in paths)} (a trace is NAME.csv with NAME.json)")
    traces = [read_checked_trace(s) for s in stems]  # read (and check) all before any simulation
    pf = read_params(args.params) if args.params else None
    model = args.model or (pf.model if pf is not None and pf.model else None)
    if model is not None:
        parse_model(model)                           # fail early on a bad model string
    if pf is not None and model is None:
        model = "linear"
    params = dict(pf.parameters) if pf else None
    report = check_report_dir(args.report)
    # a fit's or a discovery's nuisance parameters belong to the traces they were fitted on
    def nuisance_of(tr):
        from ..nuisance import of_params_file
        return of_params_file(pf.extra, tr) if pf else None

    rows, images = [], []
    t_all = time.time()
    if args.scheduler:                               # every trace a task on the cluster
        from .sweep import cluster_map
        done = cluster_map(args.scheduler, validate_trace, [(tr, model, params, nuisance_of(tr)) for tr in traces],
                           "trace")
    with Progress("validate", len(traces), unit="trace") as bar:
        for i, tr in enumerate(traces, 1):
            t0 = time.time()
            v = done[i - 1] if args.scheduler else validate_trace(tr, model, params, nuisance_of(tr))
            row = v.as_dict()
            row["within_tolerance"] = bool(v.nrmse <= args.tolerance)
            row["unit"] = COLUMN_UNITS[tr.measured_column]     # of rms_error, max_error, noise_sigma
            rows.append(row)
            img = f"plots/{tr.stem.name}.png"
            plot_validation(v, report / img)
            images.append(img)
            bar.line(f"[{i}/{len(traces)}] {tr.stem.name}: RMS error {v.rms:.3g} m, NRMSE {v.nrmse:.3g} "
                     f"({time.time() - t0:.1f} s)")
            bar.update(i, tr.stem.name)
            for w in v.result.warnings:
                warn(f"{tr.stem.name}: {w}")
    doc = {"format": "tether-validation/1", "tolerance": {"on": "normalized_rms_error", "max": args.tolerance},
           "traces": rows}
    write_json_atomic(report / "validation.json", doc)
    page = validation_page(rows, images, "KevlarTether validation",
                           f"{len(rows)} traces validated with the KevlarTether FMU in {time.time() - t_all:.1f} s.")
    write_text_atomic(report / "index.html", page)
    print(validation_table(rows))      # after the files: a closed stdout (| head) must not lose them
    bad = [r["trace"].split("/")[-1] for r in rows if r["within_noise"] is False]
    print(f"report: {report / 'index.html'} (numbers: {report / 'validation.json'})")
    if bad:
        print(f"outside their stated noise: {', '.join(bad)}")
    outside = [(r["trace"].split("/")[-1], r["normalized_rms_error"]) for r in rows if not r["within_tolerance"]]
    if outside:
        print(f"outside the tolerance (NRMSE <= {args.tolerance:g}): "
              + ", ".join(f"{n} (NRMSE {e:.3g})" for n, e in outside))
        return RUN_ERROR
    print(f"all {len(rows)} within the tolerance (NRMSE <= {args.tolerance:g})")
    return 0
