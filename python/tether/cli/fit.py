"""tether fit: fit a model's parameters to measured traces, with intervals and identifiability."""

from __future__ import annotations

import time

NAME = "fit"
HELP = "fit a model's parameters to traces; write them with 95 % intervals as a --params file"
DESCRIPTION = """\
Fit the parameters of MODEL to one or more TRACEs jointly (one parameter set for all of them) with
the native identification engine, which runs the FMU's own physics exactly as the FMU does.

Start values come from the data (equation error with filtered derivatives for payload traces,
the static law and Kawabata's energies for load tests, linear least squares for creep), then a
staged Levenberg-Marquardt fit: the elastic law and viscous damping first, then everything free.
Each trace's L0 and g come from its metadata; so do m, x0 and v0 unless --free names them.

Nuisance parameters (docs/nuisance.md) may be freed beside the law's: m (the effective payload
mass, kept within payload_mass_kg * (1 +- --mass-band)), x0, v0 (a forced record that starts in
motion) and last_reversal_beyond (with the Iwan bank: where that motion last reversed, beyond the
span [-|x0|, |x0|]), creep_preload_age (a load-rig record with creep: how long its first load had
hung before it), iwan_relaxed_load (a load-rig record with the Iwan bank: the load it was last unloaded
at before the record), offset_measured (measured column = model + offset), offset_input and input_gain (the
model is driven by input_gain * recorded input + offset_input). What a record cannot determine
is refused: m on a free vibration (every force scales with the mass) or a load-rig record, m
together with input_gain (one nuisance in two forms), x0/v0 on a periodic or load-rig record,
last_reversal_beyond in a model without the Iwan bank, creep_preload_age in a model without creep,
iwan_relaxed_load in a model without the Iwan bank, and both on the payload rig or where the first
load is 0.
The table then says which nuisance parameters moved from their start, and by how much.

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
    from .common import add_mass_band_argument
    add_mass_band_argument(parser)
    parser.add_argument("--starts", metavar="N", type=int, default=1,
                        help="starts of the final stage: the data-based one, then N-1 random ones around it "
                             "(default 1)")


def run(args) -> int:
    from ..fit import FitError, fit_traces, write_fit_params
    from ..models import TRACE_PARAMETERS, parse_model, read_params
    from . import CLIError, RUN_ERROR
    from .common import check_output_path, check_report_dir, mass_band_argument, read_checked_trace
    from .console import Progress, note

    mass_band = mass_band_argument(args)

    traces = [read_checked_trace(p) for p in args.traces]    # read (and check) every trace first
    pf = read_params(args.params) if args.params else None
    model = args.model or (pf.model if pf is not None else None)
    if not model:
        raise CLIError("no model: give --model (e.g. --model linear+boucwen) or a --params file with a \"model\"")
    spec = parse_model(model)
    out = check_output_path(args.out)
    for tr in traces:
        if out in (tr.csv_path.resolve(), tr.json_path.resolve()):
            raise CLIError(f"--out {args.out}: would overwrite the trace {tr.stem.name} itself; choose another file")
    report = check_report_dir(args.report)
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
    unit = _measured_unit(traces)
    t0 = time.time()
    with Progress("fit", 1.0) as bar:
        def progress(p):
            if p.iteration < 0:      # a stage starts (after the names are checked: an error stays one line)
                if p.stage_index == 0:
                    bar.line(f"fitting {spec.canonical} to {names}")
                bar.line(f"  {p}")
            else:
                bar.update(fit_fraction(p, args.starts), _status(p, unit))

        try:
            result = fit_traces(traces, spec, free=free, start=start, fixed=fixed, progress=progress,
                                n_starts=args.starts, mass_band=mass_band)
        except FitError as e:
            raise CLIError(f"--free: {e}" if args.free is not None and "free parameter" in str(e) else str(e)) from None
        except RuntimeError as e:
            raise CLIError(f"the fit failed: {e}", RUN_ERROR) from None
    note(f"done in {time.time() - t0:.1f} s, {result.evaluations} simulations: {result.message}")

    # the files first: a closed stdout (| head -1) must not lose them
    write_fit_params(out, result)
    if report is not None:
        from ..fit_report import write_fit_report
        write_fit_report(report, traces, result)
    print(result_table(result, _units(result, traces)))
    if report is not None:
        print(f"report: {report / 'index.html'} (numbers: {report / 'fit.json'})")
    print(f"parameters: {out}")
    return 0


def fit_fraction(p, n_starts: int = 1) -> float:
    """How far a fit is (0..1) at progress report ``p``: stages in equal shares, each split among its
    starts and horizon stages, and an iteration taking 15 % of what is left of its share (an estimate:
    the number of iterations is not known ahead; a fit takes some 5 to 30)."""
    share = 1.0 / p.n_stages
    done = p.stage_index * share
    if p.iteration < 0:
        return done
    starts = n_starts if p.stage_index == p.n_stages - 1 else 1
    h, n_h = (int(x) for x in p.horizon.split("/")) if p.horizon else (1, 1)
    piece = share / (starts * n_h)
    done += piece * (min(p.start, starts - 1) * n_h + (h - 1))
    return done + piece * (1.0 - 0.85 ** (p.iteration + 1))


def _status(p, unit: str) -> str:
    return f"stage {p.stage_index + 1}/{p.n_stages}, iteration {p.iteration + 1}, RMS {p.rms:.3g} {unit}".rstrip()


def _measured_unit(traces) -> str:
    """The unit of the traces' measured columns (the RMS error's), "" if they differ."""
    from ..traces import COLUMN_UNITS

    units = {COLUMN_UNITS.get(tr.measured_column, "") for tr in traces}
    return units.pop() if len(units) == 1 else ""


def _units(result, traces) -> dict:
    """name -> unit of every parameter in the result (modelDescription.xml), and "rms" -> the
    measured column's unit."""
    from ..fmu import model_description

    variables = model_description().variables
    # "1" is modelDescription.xml's unit of a pure number: shown as none
    units = {n: variables[n].unit if n in variables and variables[n].unit != "1" else "" for n in result.parameters}
    units["rms"] = _measured_unit(traces)
    # the nuisance parameters: m, x0, v0 as the FMU's; the offsets in their columns' units
    from ..traces import COLUMN_UNITS

    for n in result.nuisance:
        if n in variables:
            units[n] = variables[n].unit
        elif n == "offset_measured":
            units[n] = units["rms"]
        elif n == "offset_input":
            found = {COLUMN_UNITS.get(tr.input_column or "", "") for tr in traces}
            units[n] = found.pop() if len(found) == 1 else ""
    return units


def result_table(r, units: dict | None = None) -> str:
    """The terminal summary: parameter table (with units), correlation matrix, RMS per trace,
    identifiability."""
    units = units or {}
    u_rms = f" {units['rms']}" if units.get("rms") else ""
    head = ["parameter", "unit", "value", "std error", "95 % interval", ""]
    rows = []
    for n in r.free:
        lo, hi = r.ci95[n]
        rows.append([n, units.get(n) or "-", f"{r.values[n]:.6g}", f"{r.std_error[n]:.3g}", f"[{lo:.6g}, {hi:.6g}]",
                     "UNIDENTIFIABLE" if n in r.unidentifiable else ""])
    w = [max(len(h), *(len(x[i]) for x in rows)) for i, h in enumerate(head)]
    fmt = "  ".join("{:<%d}" % k for k in w)
    lines = [f"model {r.model}: RMS error {r.rms:.4g}{u_rms} over {len(r.traces)} trace(s)",
             fmt.format(*head).rstrip(), fmt.format(*("-" * k for k in w[:-1]), "").rstrip()]
    lines += [fmt.format(*x).rstrip() for x in rows]
    held = {k: v for k, v in r.parameters.items() if k not in r.free}
    if held:
        lines.append("held fixed: " + ", ".join(f"{k} = {v:.6g}" + (f" {units[k]}" if units.get(k) else "")
                                                for k, v in held.items()))
    lines.append("")
    lines.append("correlation matrix:")
    cw = max(8, max(len(n) for n in r.free) + 1)
    lines.append(" " * cw + "".join(f"{n:>{cw}}" for n in r.free))
    for i, n in enumerate(r.free):
        lines.append(f"{n:<{cw}}" + "".join(f"{r.correlation[i][j]:>{cw}.3f}" for j in range(len(r.free))))
    lines.append("")
    for name, rms, noise in zip(r.traces, r.rms_per_trace, r.noise):
        lines.append(f"{name}: RMS error {rms:.4g}{u_rms} (noise estimated from the data {noise:.3g}{u_rms})")
    if r.nuisance_moved:
        lines.append("")
        lines.append("nuisance parameters (start -> fitted, change in widths of the 95 % interval):")
        lines += ["  " + ln for ln in r.nuisance_moved]
    lines.append("")
    lines.append(r.identifiability_report)
    return "\n".join(lines)
