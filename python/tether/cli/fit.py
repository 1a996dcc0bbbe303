"""tether fit: fit a model's parameters to measured traces, with intervals and identifiability."""

from __future__ import annotations

import sys
import time
from pathlib import Path

NAME = "fit"
HELP = "fit a model's parameters to traces; write them with 95 % intervals as a --params file"
DESCRIPTION = """\
Fit the parameters of MODEL to one or more TRACEs jointly (one parameter set for all of them) with
the native identification engine, which runs the FMU's own physics exactly as the FMU does.

Start values come from the data (equation error with filtered derivatives for payload traces,
the static law and Kawabata's energies for load tests, linear least squares for creep), then a
staged Levenberg-Marquardt fit: the elastic law and viscous damping first, then everything free.
Each trace's L0, m, g, x0 and v0 come from its metadata and are not fitted.

--free names the parameters to fit (default: what the data of each trace's experiment can
determine for the model; `tether fit --help` lists the rule in the docs of tether.fit). With
--params FILE, the file's values are the starts of free parameters and the values of the others
(default: the FMU's start values).

Writes OUT (the --params form: {"model", "parameters", "intervals", "std_error", "correlation",
"unidentifiable", "rms"}), so `tether simulate/validate --params OUT` use the fit. The terminal
shows progress (stderr), then the table of values, standard errors, 95 % intervals and
unidentifiable flags, and the correlation matrix. --report DIR adds DIR/index.html (measured vs
fitted and the residual per trace, the correlation matrix, the identifiability report) and
DIR/fit.json.

Exit status: 0 fitted; 2 bad input (trace, model, parameter names, files); 1 engine or FMU failure.
"""


def add_arguments(parser) -> None:
    parser.add_argument("traces", metavar="TRACE", nargs="+", help="traces (NAME.csv, NAME.json or NAME)")
    parser.add_argument("--model", metavar="NAME",
                        help="model string: a preset (linear, cubic, simplified, kawabata, full) plus '+effect' "
                             "terms, e.g. linear+boucwen (default: the --params file's model)")
    parser.add_argument("--free", metavar="a1,a2,...",
                        help="comma-separated parameters to fit (default: those the data can determine)")
    parser.add_argument("--params", metavar="FILE.json",
                        help="parameter file: starts for the free parameters, values for the others")
    parser.add_argument("--out", metavar="PARAMS.json", required=True, help="fitted parameter file to write")
    parser.add_argument("--report", metavar="DIR", help="write DIR/index.html with plots and DIR/fit.json")
    parser.add_argument("--starts", metavar="N", type=int, default=1,
                        help="starts of the final stage: the data-based one, then N-1 random ones around it "
                             "(default 1)")


def run(args) -> int:
    from ..fit import FitError, fit_traces, write_fit_params
    from ..models import TRACE_PARAMETERS, parse_model, read_params
    from ..traces import read_trace
    from . import CLIError, RUN_ERROR
    from .common import check_output_path

    traces = [read_trace(p) for p in args.traces]            # read (and check) every trace first
    pf = read_params(args.params) if args.params else None
    model = args.model or (pf.model if pf is not None else None)
    if not model:
        raise CLIError("no model: give --model (e.g. --model linear+boucwen) or a --params file with a \"model\"")
    spec = parse_model(model)
    out = check_output_path(args.out)
    for tr in traces:
        if out.exists() and out.resolve() in (tr.csv_path.resolve(), tr.json_path.resolve()):
            raise CLIError(f"--out {args.out}: would overwrite the trace {tr.stem.name} itself; choose another file")
    report = Path(args.report) if args.report else None
    if report is not None and report.exists() and not report.is_dir():
        raise CLIError(f"--report {report}: exists and is not a directory")
    if args.starts < 1:
        raise CLIError(f"--starts {args.starts}: expected a whole number >= 1")
    free = None
    if args.free is not None:
        free = [n.strip() for n in args.free.split(",")]
        if not all(free):
            raise CLIError(f"--free '{args.free}': empty name; expected comma-separated parameter names, e.g. a1,a2")
    start, fixed = {}, {}
    if pf is not None:
        values = {k: v for k, v in pf.parameters.items() if k not in TRACE_PARAMETERS and k in spec.parameters}
        if free is not None:
            start = {k: v for k, v in values.items() if k in free}
            fixed = {k: v for k, v in values.items() if k not in free}
        else:
            from ..fit import default_free_parameters
            dflt = {n for tr in traces for n in default_free_parameters(spec, tr.experiment)}
            start = {k: v for k, v in values.items() if k in dflt}
            fixed = {k: v for k, v in values.items() if k not in dflt}

    names = ", ".join(tr.stem.name for tr in traces)
    t0 = time.time()
    started = []

    def progress(p):
        if not started:     # after the names are checked: an error stays one line
            started.append(1)
            sys.stderr.write(f"fitting {spec.canonical} to {names}\n")
        sys.stderr.write(f"  {p}\n")
        sys.stderr.flush()

    try:
        result = fit_traces(traces, spec, free=free, start=start, fixed=fixed, progress=progress,
                            n_starts=args.starts)
    except FitError as e:
        raise CLIError(f"--free: {e}" if args.free is not None and "free parameter" in str(e) else str(e)) from None
    except RuntimeError as e:
        raise CLIError(f"the fit failed: {e}", RUN_ERROR) from None
    sys.stderr.write(f"done in {time.time() - t0:.1f} s, {result.evaluations} simulations: {result.message}\n")

    print(result_table(result))
    write_fit_params(out, result)
    if report is not None:
        from ..fit_report import write_fit_report
        write_fit_report(report, traces, result)
        print(f"report: {report / 'index.html'} (numbers: {report / 'fit.json'})")
    print(f"parameters: {out}")
    return 0


def result_table(r) -> str:
    """The terminal summary: parameter table, correlation matrix, RMS per trace, identifiability."""
    head = ["parameter", "value", "std error", "95 % interval", ""]
    rows = []
    for n in r.free:
        lo, hi = r.ci95[n]
        rows.append([n, f"{r.values[n]:.6g}", f"{r.std_error[n]:.3g}", f"[{lo:.6g}, {hi:.6g}]",
                     "UNIDENTIFIABLE" if n in r.unidentifiable else ""])
    w = [max(len(h), *(len(x[i]) for x in rows)) for i, h in enumerate(head)]
    fmt = "  ".join("{:<%d}" % k for k in w)
    lines = [f"model {r.model}: RMS error {r.rms:.4g} over {len(r.traces)} trace(s)", fmt.format(*head).rstrip(),
             fmt.format(*("-" * k for k in w[:-1]), "").rstrip()]
    lines += [fmt.format(*x).rstrip() for x in rows]
    held = {k: v for k, v in r.parameters.items() if k not in r.free}
    if held:
        lines.append("held fixed: " + ", ".join(f"{k} = {v:.6g}" for k, v in held.items()))
    lines.append("")
    lines.append("correlation matrix:")
    cw = max(8, max(len(n) for n in r.free) + 1)
    lines.append(" " * cw + "".join(f"{n:>{cw}}" for n in r.free))
    for i, n in enumerate(r.free):
        lines.append(f"{n:<{cw}}" + "".join(f"{r.correlation[i][j]:>{cw}.3f}" for j in range(len(r.free))))
    lines.append("")
    for name, rms, noise in zip(r.traces, r.rms_per_trace, r.noise):
        lines.append(f"{name}: RMS error {rms:.4g} (noise estimated from the data {noise:.3g})")
    lines.append("")
    lines.append(r.identifiability_report)
    return "\n".join(lines)
