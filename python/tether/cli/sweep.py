"""tether sweep: many runs of one trace on Dask, one row of summary outputs per run."""

from __future__ import annotations

import time
from pathlib import Path

NAME = "sweep"
HELP = "run a trace over a grid of parameters or draws from a fit's uncertainty, on Dask; one row per run"
DESCRIPTION = """\
Simulate TRACE many times: over the full-factorial grid of the --vary specs (NAME=LO:HI:N, N values
from LO to HI; the first varies slowest), or with --samples N parameter sets drawn from the fit in
--params (the P.json `tether fit --out` writes: a multivariate normal of its values, standard errors
and correlations, in the scale the fit used, kept inside the parameters' bounds; --seed).

Varied names: the FMU's parameters, the trace's own L0, m, g, x0, v0, line_density (a varied one
wins over the trace's), and force_scale or load_scale, a factor on the trace's input.

OUT.csv gets one row per run: run, the varied values, then max_tension, min_tension,
peak_displacement (or peak_elongation; largest magnitude), rms_displacement (or rms_elongation),
slack_time (seconds slack), final_elongation, rmse (against the measured column). Rows are written
as runs finish; when all are in, OUT.csv is put in run order. OUT.csv.sweep.json beside it records
what the sweep is: a killed sweep goes on with --resume (same arguments) without redoing its
finished rows, and ends with the same file (a finished one runs nothing: its --report is redone).
The first and the last run are tried here before anything is written; a later run the FMU refuses
gets a row of NaN outputs and a warning naming its error, and the sweep goes on.
--series DIR writes every run's time series (DIR/run_NNNNNN.parquet: time, the measured column,
tension). --report DIR writes DIR/index.html: the prediction band (5/50/95 %) against the
measurement (with --samples, each run carries the fit's noise) and the distributions of the outputs;
its series go to --series, else to DIR/series.

Runs on Dask: without --scheduler, a local cluster of one worker process per core (--workers N to
choose); --scheduler tcp://HOST:PORT uses the cluster whose scheduler is there (its workers need
this package; the FMU is sent to them). The rows are the same bit for bit whatever the cluster.

Exit status: 0 done; 2 bad input; 1 FMU, simulation or cluster failure.
"""


def add_arguments(parser) -> None:
    from .common import add_model_arguments

    parser.add_argument("trace", metavar="TRACE", help="NAME.csv, NAME.json or NAME")
    add_model_arguments(parser)
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--vary", metavar="NAME=LO:HI:N", action="append",
                      help="a grid axis (repeat for a full-factorial grid), e.g. --vary a1=900:1500:8")
    what.add_argument("--samples", metavar="N", type=int,
                      help="N parameter sets drawn from the fit in --params (its std_error and correlation)")
    parser.add_argument("--seed", metavar="INT", type=int, default=0, help="seed of --samples (default 0)")
    parser.add_argument("--out", metavar="OUT.csv", required=True, help="rows to write")
    parser.add_argument("--series", metavar="DIR", help="write every run's time series as Parquet into DIR")
    parser.add_argument("--report", metavar="DIR", help="write DIR/index.html: prediction band and distributions")
    parser.add_argument("--resume", action="store_true", help="go on with the killed sweep in OUT.csv")
    add_scheduler_argument(parser)
    parser.add_argument("--workers", metavar="N", type=int,
                        help="worker processes of the local cluster (default: one per core)")


def add_scheduler_argument(parser) -> None:
    """--scheduler, shared by sweep, validate and discover --each."""
    parser.add_argument("--scheduler", metavar="ADDRESS", type=_address,
                        help="Dask scheduler to run on, tcp://HOST:PORT ('local': a local cluster of one "
                             "worker process per core)")


def _address(text: str) -> str:
    import argparse

    from ..campaign import CampaignError, check_address

    try:
        return check_address(text)
    except CampaignError as e:
        raise argparse.ArgumentTypeError(str(e).split(": ", 1)[1]) from None


def cluster_map(scheduler, fn, arg_tuples, label: str, each=None) -> list:
    """:func:`tether.campaign.map_on_cluster` for a subcommand: a cluster that cannot be reached
    is one line and status 1."""
    from ..campaign import CampaignError, map_on_cluster
    from . import CLIError, RUN_ERROR

    try:
        return map_on_cluster(scheduler, fn, arg_tuples, label=label, each=each)
    except CampaignError as e:
        raise CLIError(str(e), RUN_ERROR) from None


def run(args) -> int:
    from ..campaign import CampaignError, dask_client, stderr_progress
    from ..sweep import execute
    from ..sweep_output import RowsFile, SweepFileError
    from ..traces import read_trace
    from . import CLIError, RUN_ERROR, warn
    from .common import check_output_path, resolve_model

    trace = read_trace(args.trace)
    spec, base, pf = resolve_model(args, trace)
    out = check_output_path(args.out, trace)
    series, report = _folders(args)
    if args.workers is not None and (args.workers < 1 or args.scheduler not in (None, "local")):
        raise CLIError(f"--workers {args.workers}: expected a whole number >= 1, for the local cluster only")
    plan = _plan(args, trace, spec, base, pf)
    per_run = _try_corners(plan)

    rows = RowsFile(out, plan.columns, plan.fingerprint())
    try:
        done = rows.resume() if args.resume else set()
    except SweepFileError as e:
        raise CLIError(str(e)) from None
    todo = _todo(len(plan.runs), done, series)
    stderr_progress(f"sweep of {trace.name} with {plan.model}: {len(plan.runs)} runs of {', '.join(plan.names)}"
                    + (f"; {len(done)} done before, {len(todo)} to run" if args.resume else ""))
    t_all = time.perf_counter()
    failed: dict = {}
    try:
        if todo:
            with dask_client(args.scheduler, args.workers, stderr_progress) as client:
                if not args.resume:
                    rows.start()                 # OUT is replaced only once the cluster is there
                failed = execute(plan, client, rows, todo, series, per_run, stderr_progress)
    except CampaignError as e:
        raise CLIError(str(e), RUN_ERROR) from None
    finally:
        rows.close()
    rows.finish()
    stderr_progress(f"{len(todo)} runs in {time.perf_counter() - t_all:.1f} s")
    print(f"rows: {out} ({len(plan.runs)} runs)")
    if failed:
        warn(f"{len(failed)} run(s) failed, their rows hold NaN (run {min(failed)}: {failed[min(failed)]})")
    if report is not None:
        write_report(plan, pf, series, report, out)
    return 0


def _folders(args) -> tuple[Path | None, Path | None]:
    """(--series, --report) folders; a report keeps its series in DIR/series unless --series says."""
    from . import CLIError

    series = Path(args.series) if args.series else None
    report = Path(args.report) if args.report else None
    for opt, folder in (("--series", series), ("--report", report)):
        if folder is not None and folder.exists() and not folder.is_dir():
            raise CLIError(f"{opt} {folder}: exists and is not a directory")
    if report is not None and series is None:
        series = report / "series"
    return series, report


def _plan(args, trace, spec, base, pf):
    from ..sweep import SweepError, grid_plan, sample_plan
    from . import CLIError

    try:
        if args.samples is None:
            return grid_plan(trace, spec, base, args.vary)
        if pf is None:
            raise CLIError("--samples: give the fit's parameter file with --params P.json (from `tether fit --out`)")
        return sample_plan(trace, spec, base, pf.extra, args.samples, args.seed, str(pf.path))
    except SweepError as e:
        raise CLIError(str(e)) from None


def _try_corners(plan) -> float:
    """Run the first and the last run here (a grid's low and high corners): a value the FMU refuses
    fails now, in one line, before any output. Returns the second's time: the time of a run."""
    from ..sweep import run_one

    run_one(plan.trace, plan.model, plan.base, dict(zip(plan.names, plan.runs[0])))
    t0 = time.perf_counter()
    run_one(plan.trace, plan.model, plan.base, dict(zip(plan.names, plan.runs[-1])))
    return time.perf_counter() - t0


def _todo(n_runs: int, done: set, series: Path | None) -> list[int]:
    """The runs to do: those not done, and those done whose series is missing where one is asked."""
    from ..sweep_output import series_path

    if series is not None:
        series.mkdir(parents=True, exist_ok=True)
        done = {i for i in done if series_path(series, i).is_file()}
    return [i for i in range(n_runs) if i not in done]


def write_report(plan, pf, series: Path, report: Path, out: Path) -> None:
    import numpy as np

    from ..sweep_output import read_series
    from ..sweep_report import fit_noise, write_sweep_report

    table = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)
    ran = [i for i in range(len(plan.runs)) if np.all(np.isfinite(table[i, 1 + len(plan.names):-1]))]
    Y = np.vstack([read_series(series, i, plan.trace.measured_column) for i in ran])   # a failed run has none
    sigma = fit_noise(pf.extra if pf is not None and "samples" in plan.description else None, plan.trace.name)
    figures = write_sweep_report(report, plan.trace, Y, sigma, plan.columns, table, 1 + len(plan.names),
                                 f"Sweep of {plan.trace.name} with {plan.model}")
    if figures["coverage"] is not None:
        print(f"band: {100 * figures['coverage']:.1f} % of the measured samples inside 5-95 %"
              + (f" (noise {sigma:.3g})" if sigma > 0 else ""))
    print(f"report: {report / 'index.html'}")
