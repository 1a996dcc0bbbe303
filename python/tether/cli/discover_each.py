"""tether discover --each TRACE... --out-dir DIR: one independent discovery per record, each a
task on Dask (the embedded local cluster, or --scheduler), with a summary table. --resume keeps
the records DIR already holds (the same record from the same start) and runs the rest.

DIR/NAME.json is each record's discovery (as ``tether discover --json`` writes it), written as the
record finishes; DIR/summary.csv and DIR/summary.json hold one row per record: the effects named,
the errors before and after in units of the noise, and why the search stopped.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

SUMMARY_COLUMNS = ("trace", "experiment", "added_effects", "final_model", "noise_estimate", "rmse_initial",
                   "rmse_final", "final_over_noise", "present", "undetermined", "unexplained_gap_noise",
                   "stop_reason")


def discover_record(trace, start: str, budget: float | None, mass_band: float | None = None,
                    free_nuisance: bool = True) -> dict:
    """One record's discovery document (runs on a worker)."""
    from ..discover import discover, discovery_document

    d = discover(trace, start=start, mass_band=mass_band, free_nuisance=free_nuisance,
                 **({} if budget is None else {"budget": budget}))
    return discovery_document(d)


def _with_verdict(doc: dict, verdict: str) -> str:
    """The effects OUT.json's ``effects`` gives ``verdict``, joined by '+'."""
    return "+".join(e for e, v in (doc.get("effects") or {}).items() if v.get("verdict") == verdict)


def summary_row(name: str, experiment: str, doc: dict) -> dict:
    unexplained = doc.get("unexplained") or {}
    return {"trace": name, "experiment": experiment, "added_effects": "+".join(doc.get("added_effects") or []),
            "final_model": doc.get("final_model", ""), "noise_estimate": doc.get("noise_estimate"),
            "rmse_initial": doc.get("rmse_initial"), "rmse_final": doc.get("rmse_final"),
            "final_over_noise": doc.get("rmse_final_over_noise"), "present": _with_verdict(doc, "present"),
            "undetermined": _with_verdict(doc, "undetermined"), "unexplained_gap_noise": unexplained.get("gap_noise"),
            "stop_reason": doc.get("stop_reason", "")}


def run_each(args) -> int:
    from ..report import write_json_atomic
    from . import warn
    from .sweep import cluster_map

    from .common import mass_band_argument

    mass_band = mass_band_argument(args)
    traces, out = _check(args)
    names = [t.name for t in traces]
    docs = _done_before(out, traces, args.start) if args.resume else {}
    todo = [i for i in range(len(traces)) if i not in docs]
    if docs:
        warn(f"--resume: {len(docs)} of {len(traces)} records done before ({out}/NAME.json), {len(todo)} to run")

    def finished(k: int, doc: dict) -> None:
        write_json_atomic(out / f"{names[todo[k]]}.json", doc)
        docs[todo[k]] = doc

    if todo:
        cluster_map(args.scheduler, discover_record, [(traces[i], args.start, args.budget, mass_band, args.nuisance) for i in todo],
                    "record",
                    each=finished)
    rows = [summary_row(t.name, t.experiment, docs[i]) for i, t in enumerate(traces)]
    _write_summary(out, rows)
    print(summary_table(rows))
    print(f"records: {out}/NAME.json; summary: {out / 'summary.csv'}")
    return 0


def _check(args):
    """(traces, output folder), every argument and record checked before any work."""
    from ..models import parse_model
    from ..traces import read_trace
    from . import CLIError

    if args.trace is not None or args.json is not None:
        raise CLIError("--each: give the records after --each and --out-dir DIR, not TRACE or --json")
    if args.report is not None:
        raise CLIError("--each: --report is for one record; each record's discovery is in DIR/NAME.json")
    if not args.out_dir:
        raise CLIError("--each: give --out-dir DIR for the records' discoveries and the summary")
    traces = [read_trace(p) for p in args.each]              # read (and check) every record first
    names = [t.name for t in traces]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise CLIError(f"--each: two records named {dup[0]}; their DIR/{dup[0]}.json would collide")
    for t in traces:
        parse_model(args.start, t.experiment)
    out = Path(args.out_dir)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--out-dir {out}: exists and is not a directory")
    return traces, out


def _done_before(out: Path, traces, start: str) -> dict:
    """index -> discovery of the records DIR/NAME.json already holds: the same record (path and
    samples) from the same start model."""
    import json

    done = {}
    for i, t in enumerate(traces):
        try:
            doc = json.loads((out / f"{t.name}.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        same = (isinstance(doc, dict) and doc.get("start_model") == start and doc.get("samples") == len(t.time)
                and Path(str(doc.get("trace", ""))).resolve() == Path(t.stem).resolve())
        if same:
            done[i] = doc
    return done


def _write_summary(out: Path, rows) -> None:
    from ..atomic import write_with
    from ..report import write_json_atomic

    write_json_atomic(out / "summary.json", {"format": "tether-discover-each/1", "records": rows})

    def fill(f):
        w = csv.writer(f, lineterminator="\n")
        w.writerow(SUMMARY_COLUMNS)
        w.writerows([[_cell(r[c]) for c in SUMMARY_COLUMNS] for r in rows])

    write_with(out / "summary.csv", fill)


def _cell(v) -> str:
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    return "" if v is None else str(v)


def summary_table(rows) -> str:
    head = ["trace", "effects named", "start x noise", "final x noise", "stopped"]
    body = []
    for r in rows:
        n = r["noise_estimate"] or float("nan")
        body.append([r["trace"], r["added_effects"] or "(none)", f"{(r['rmse_initial'] or float('nan')) / n:.2f}",
                     f"{r['final_over_noise'] or float('nan'):.2f}", str(r["stop_reason"])[:60]])
    w = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    fmt = "  ".join("{:<%d}" % k for k in w)
    return "\n".join([fmt.format(*head).rstrip(), fmt.format(*("-" * k for k in w)).rstrip()]
                     + [fmt.format(*b).rstrip() for b in body])
