"""tether discover: name the effects a trace shows that the linear baseline lacks."""

from __future__ import annotations

import argparse

from .common import positive_number

NAME = "discover"
HELP = "find the effects a trace shows that the linear baseline lacks, step by step, with evidence"
DESCRIPTION = """\
Start from the baseline of the trace format (linear spring, viscous damper, no slack; or --start
MODEL) and repeat: fit the model to TRACE; locate where it disagrees with the record (time windows
where the residual stands above the noise, which is estimated from the data itself, and the
regimes they fall in: loading/unloading, large/small amplitude, slack, long holds); fit the model
with each candidate effect the experiment can reveal added (nonlinear_stiffness, hysteresis,
nonlinear_damping, slack for vibration; nonlinear_stiffness, hysteresis, creep for load tests);
add the one that earns its parameters (BIC, the gap above the noise at least halved, and a
better prediction of the last 40 % of the record from a fit to the first 60 %); until the model is
within the noise or nothing earns its place. Then print a short account.

--json OUT.json gets effects (every effect of the vocabulary: present, absent or undetermined, its
weight and evidence), unexplained (the gap the final model leaves, in noise units, or null),
added_effects, rmse_initial, rmse_final (measured unit), noise_estimate, the steps (effect, where,
evidence, rmse_before, rmse_after) and final_params. OUT.json is itself a
parameter file of the discovered model: `tether simulate OTHER.csv --params OUT.json`.
--report DIR writes DIR/index.html: the record against each model in turn, the residuals with the
flagged windows, and the gap shrinking step by step.
--budget SECONDS bounds the run (default 900 s; long records at high rates with several effects
can need more): a step whose fits are not all done when it is spent adds nothing.
Every fit frees the record's nuisance parameters from the start model on (the offset of the
measured column; a forced record's initial state and effective mass, kept within
payload_mass_kg * (1 +- --mass-band REL), default the trace's mass_uncertainty_rel, else 0.3;
a free vibration's release point), so no effect is named for what they explain: OUT.json's
`nuisance` section reports each with its interval and how far it moved
(docs/nuisance-discovery.md). --no-nuisance keeps them at the record's values.

--each TRACE... --out-dir DIR runs one independent discovery per record, each a task on Dask (a
local cluster of one worker process per core, or --scheduler tcp://HOST:PORT): DIR/NAME.json per
record as it finishes, then DIR/summary.csv and DIR/summary.json, one row per record; --resume
keeps the records DIR already holds (the same record from the same start) and runs the rest.

Two records or more (TRACE TRACE...) are a campaign: records of one tether, discovered jointly. The
material law, damping, hysteresis and creep are shared; each record keeps its own length, mass,
gravity, initial state, noise and nuisance parameters. An effect is added when it earns its place
on the whole campaign by the one-record criteria (each record weighted by its own noise, the
held-out test on each record's held-out part). OUT.json adds `records` (per record its noise, its
error before and after every step, which step it revealed, the verdict on every effect for it)
and `contradicting`: the records the shared law misses while their own fit does far better (another
tether, a wrong mass, a unit error), also named on stderr (docs/campaign-discovery.md).

Exit status: 0 done; 2 bad input; 1 engine or FMU failure.
"""


def add_arguments(parser) -> None:
    parser.add_argument("trace", metavar="TRACE", nargs="?", help="NAME.csv, NAME.json or NAME")
    parser.add_argument("more", metavar="TRACE", nargs="*",
                        help="further records of the same tether: a campaign, discovered jointly")
    parser.add_argument("--start", metavar="MODEL", default="linear",
                        help="model to start from (default: linear, the trace format's baseline)")
    parser.add_argument("--json", metavar="OUT.json", help="discovery record to write (required with TRACE)")
    parser.add_argument("--each", metavar="TRACE", nargs="+",
                        help="one independent discovery per record, each a task on Dask; with --out-dir")
    parser.add_argument("--out-dir", metavar="DIR", help="--each: DIR/NAME.json per record, DIR/summary.csv")
    parser.add_argument("--resume", action="store_true", help="--each: keep the records DIR holds, run the rest")
    from .sweep import add_scheduler_argument
    add_scheduler_argument(parser)
    parser.add_argument("--report", metavar="DIR", help="write DIR/index.html with the story in plots")
    from .common import add_mass_band_argument
    add_mass_band_argument(parser, "the effective mass (freed on forced records)")
    parser.add_argument("--nuisance", action=argparse.BooleanOptionalAction, default=True,
                        help="free the record's nuisance parameters in every fit (the default): the measured "
                             "column's offset, a forced record's initial state and effective mass "
                             "(docs/nuisance-discovery.md); --no-nuisance keeps the record's values")
    parser.add_argument("--budget", metavar="SECONDS", type=positive_number("seconds"), default=None,
                        help="bound the run (default 900 s): a step not judged to the end when it is spent "
                             "adds nothing, and the account says so")



def run(args) -> int:
    from ..discover import DEFAULT_BUDGET, DiscoveryError, account, discover, discovery_document
    from ..models import parse_model
    from ..report import write_json_atomic
    from . import CLIError, RUN_ERROR
    from .common import check_output_path, check_report_dir, mass_band_argument, read_checked_trace
    from .console import Progress

    mass_band = mass_band_argument(args)
    if mass_band is not None and not args.nuisance:
        raise CLIError(f"--mass-band {args.mass_band}: the band bounds a freed mass, and --no-nuisance frees none; "
                       "drop one of the two")

    if args.each:
        from .discover_each import run_each
        return run_each(args)
    if args.trace is None or args.json is None:
        raise CLIError("give TRACE and --json OUT.json (or --each TRACE... --out-dir DIR)")
    if args.more:
        from .discover_campaign import run_campaign
        return run_campaign(args, mass_band)
    trace = read_checked_trace(args.trace)
    parse_model(args.start, trace.experiment)                # a bad model string fails before any fit
    out = check_output_path(args.json, trace, option="--json")
    report = check_report_dir(args.report)

    budget = DEFAULT_BUDGET if args.budget is None else args.budget
    with Progress("discover", budget, unit="s", deadline=True) as bar:
        try:
            d = discover(trace, start=args.start, progress=bar.line, budget=budget, mass_band=mass_band,
                         free_nuisance=args.nuisance)
        except DiscoveryError as e:
            raise CLIError(str(e), RUN_ERROR) from None
        except RuntimeError as e:
            raise CLIError(f"the discovery failed: {e}", RUN_ERROR) from None
    doc = discovery_document(d)
    # the files first: a closed stdout (| head) must not lose them
    write_json_atomic(out, doc)
    if report is not None:
        from ..discover_report import write_discovery_report

        write_discovery_report(report, d, doc)
    print(account(d))
    if report is not None:
        print(f"report: {report / 'index.html'}")
    print(f"record: {out} (also a --params file of the discovered model)")
    return 0
