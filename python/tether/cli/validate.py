"""tether validate: run the FMU on measured traces and report how well the model reproduces them."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from .common import add_model_arguments

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
loop). Exit status: 0 all traces simulated; 2 bad input; 1 FMU missing or failed.
"""



def add_arguments(parser) -> None:
    parser.add_argument("traces", metavar="TRACE", nargs="*", help="traces or directories (default: reference_results/)")
    add_model_arguments(parser)
    parser.add_argument("--report", metavar="DIR", default="reports/validate",
                        help="report directory (default: reports/validate)")
    from .sweep import add_scheduler_argument
    add_scheduler_argument(parser)


def run(args) -> int:
    from ..models import parse_model, read_params
    from ..report import plot_validation, validation_page, validation_table, write_json_atomic, write_text_atomic
    from ..traces import read_trace
    from ..validate import find_traces, validate_trace
    from . import CLIError, warn

    from ..resources import reference_results_dir

    paths = args.traces or [reference_results_dir()]
    stems = find_traces(paths)
    if not stems:
        raise CLIError(f"no traces found in {', '.join(str(p) for p in paths)} (a trace is NAME.csv with NAME.json)")
    traces = [read_trace(s) for s in stems]          # read (and check) all before any simulation
    pf = read_params(args.params) if args.params else None
    model = args.model or (pf.model if pf is not None and pf.model else None)
    if model is not None:
        parse_model(model)                           # fail early on a bad model string
    if pf is not None and model is None:
        model = "linear"
    params = dict(pf.parameters) if pf else None

    report = Path(args.report)
    if report.exists() and not report.is_dir():
        raise CLIError(f"--report {report}: exists and is not a directory")
    rows, images = [], []
    t_all = time.time()
    if args.scheduler:                               # every trace a task on the cluster
        from .sweep import cluster_map
        done = cluster_map(args.scheduler, validate_trace, [(tr, model, params) for tr in traces], "trace")
    for i, tr in enumerate(traces, 1):
        t0 = time.time()
        sys.stderr.write(f"[{i}/{len(traces)}] {tr.stem.name} ... ")
        sys.stderr.flush()
        v = done[i - 1] if args.scheduler else validate_trace(tr, model, params)
        row = v.as_dict()
        rows.append(row)
        img = f"plots/{tr.stem.name}.png"
        plot_validation(v, report / img)
        images.append(img)
        sys.stderr.write(f"RMS error {v.rms:.3g} m ({time.time() - t0:.1f} s)\n")
        for w in v.result.warnings:
            warn(f"{tr.stem.name}: {w}")
    table = validation_table(rows)
    print(table)
    doc = {"format": "tether-validation/1", "traces": rows}
    write_json_atomic(report / "validation.json", doc)
    page = validation_page(rows, images, "KevlarTether validation",
                           f"{len(rows)} traces validated with the KevlarTether FMU in {time.time() - t_all:.1f} s.")
    write_text_atomic(report / "index.html", page)
    bad = [r["trace"].split("/")[-1] for r in rows if r["within_noise"] is False]
    print(f"report: {report / 'index.html'} (numbers: {report / 'validation.json'})")
    if bad:
        print(f"outside their stated noise: {', '.join(bad)}")
    return 0
