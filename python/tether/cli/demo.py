"""tether demo: the main job on the bundled data, leaving a report to open."""

from __future__ import annotations

import html
import time
from pathlib import Path

NAME = "demo"
HELP = "validate the FMU against the bundled traces and the Bouc-Wen benchmark, run a discovery; write a report"
DESCRIPTION = """\
The main job on the bundled data:
  1. validate the KevlarTether FMU against every synthetic reference trace of the paper's
     experiments (reference_results/), each with the model that generated it;
  2. simulate the Bouc-Wen benchmark (datasets/boucwen, bundled) with its nominal
     parameters (reference_results/boucwen_nominal.json) and compare with the published results;
  3. run a discovery (tether discover) on reference_results/discovery/freevib_hidden, a free
     vibration record from the tests' independent generator with two effects hidden in it, and
     set what it named beside the truth the trace's JSON keeps (which discovery does not read);
and write DIR/index.html linking everything (default DIR: reports/demo).
"""

# published RMS errors on test_multisine (datasets/boucwen/README.md)
PUBLISHED = [
    ("third-order linear model", 1.5e-4),
    ("PNLSS, polynomial degree 2 (34 parameters)", 5.4e-5),
    ("dynoNet", 4.5e-5),
    ("PNLSS, degrees 3-5-7 (217 parameters)", 1.2e-5),
    ("neural state-space model (2021)", 7.2e-6),
]


def add_arguments(parser) -> None:
    parser.add_argument("--report", metavar="DIR", default="reports/demo", help="report directory (default: reports/demo)")


def run(args) -> int:
    from ..models import read_params
    from ..report import write_text_atomic
    from ..resources import dataset_dir, reference_results_dir
    from ..run import simulate
    from .common import check_report_dir
    from .console import note
    from .validate import run as run_validate

    report = check_report_dir(args.report)
    t0 = time.time()
    print("== 1. validation of the FMU against the bundled reference traces")

    a = _validate_arguments(["--report", str(report / "validate")])
    status = run_validate(a)         # 1 if a reference trace is outside the tolerance: the demo says so

    print("\n== 2. the Bouc-Wen benchmark with its nominal parameters")
    bench_rows = []
    data = dataset_dir("boucwen")
    nominal = reference_results_dir() / "boucwen_nominal.json"
    if data.is_dir() and nominal.is_file():
        pf = read_params(nominal)
        for name in ("test_multisine", "test_sinesweep"):
            t1 = time.time()
            r = simulate(data / name, pf.model, pf.parameters)
            from ..traces import read_trace

            rms = r.rms_error(read_trace(data / name).measured)
            note(f"{name}: {time.time() - t1:.1f} s")
            bench_rows.append((name, rms))
            print(f"  {name}: RMS error {rms:.3g} m (model {pf.model}, nominal parameters)")
    else:
        print(f"  skipped: {data} or {nominal} not found (an incomplete installation)")

    print("\n== 3. discovery on a record with hidden effects")
    disc = _discovery(report)

    esc = html.escape
    rows = "".join(f"<tr><td class=l>{esc(n)}</td><td>{v:.2g}</td></tr>" for n, v in PUBLISHED)
    ours = "".join(f"<tr class=good><td class=l>KevlarTether FMU, physical model with nominal parameters: "
                   f"<code>{esc(n)}</code></td><td>{v:.2g}</td></tr>" for n, v in bench_rows)
    page = f"""<!DOCTYPE html><html><head><meta charset="utf-8"><title>KevlarTether demo</title>
<style>body{{font-family:sans-serif;max-width:1000px;margin:2em auto}} table{{border-collapse:collapse}}
td,th{{border:1px solid #ccc;padding:.25em .6em;text-align:right}} td.l{{text-align:left}} .good{{background:#dfd}}</style>
</head><body><h1>KevlarTether demo report</h1>
<p>Made by <code>tether demo</code> in {time.time() - t0:.0f} s.</p>
<h2>1. Validation against the paper's experiments (synthetic reference traces)</h2>
<p><a href="validate/index.html">The validation report</a>: every trace simulated with the FMU, with
its error, the noise it states, and plots (<a href="validate/validation.json">numbers as JSON</a>).</p>
<h2>2. Bouc-Wen benchmark (Noël and Schoukens 2016)</h2>
<table><tr><th>model</th><th>RMS error on the record [m]</th></tr>{rows}{ours}</table>
<p>Published results are on <code>test_multisine</code>. The FMU runs the benchmark's own equations
(linear spring and damper plus a Bouc-Wen force, in the payload rig without gravity or slack), so
it sits at the level of the true equations (2.3e-7 m), far below the black-box models.</p>
{disc}
</body></html>
"""
    write_text_atomic(report / "index.html", page)
    print(f"\nreport: {report / 'index.html'}")
    return status


def _discovery(report: Path) -> str:
    """Step 3: tether discover on the bundled record; returns the report section (HTML)."""
    from ..resources import reference_results_dir

    from ..discover import DEFAULT_BUDGET, account, discover, discovery_document
    from ..discover_report import write_discovery_report
    from ..traces import read_trace
    from .console import Progress

    esc = html.escape
    discovery_trace = reference_results_dir() / "discovery" / "freevib_hidden"
    trace = read_trace(discovery_trace)
    with Progress("discover", DEFAULT_BUDGET, unit="s", deadline=True) as bar:
        d = discover(trace, progress=lambda line: bar.line("  " + line), budget=DEFAULT_BUDGET)
    doc = discovery_document(d)
    out = report / "discovery"
    write_discovery_report(out, d, doc)
    print(account(d))
    hidden = sorted(trace.meta.get("hidden", {}).get("revealed", []))
    named = doc["added_effects"]
    verdict = "the same set" if sorted(named) == hidden else "NOT the hidden set"
    print(f"  hidden in the record: {', '.join(hidden) or 'nothing'}; named: {', '.join(named) or 'nothing'} ({verdict})")
    steps = "".join(f"<li><b>{esc(s['effect'])}</b>: RMS error {s['rmse_before_over_noise']:.2f} &rarr; "
                    f"{s['rmse_after_over_noise']:.2f} &times; noise</li>" for s in doc["steps"])
    return f"""<h2>3. Discovery: which effect does the linear model lack?</h2>
<p><code>tether discover reference_results/discovery/freevib_hidden</code> started from the linear
baseline on a free-vibration record made by the tests' independent generator (its own laws and
integrator, not the FMU's), with noise {doc['noise_estimate']:.2g} m estimated from the data.</p>
<ol>{steps}</ol>
<p>Hidden in the record: <b>{esc(', '.join(hidden) or 'nothing')}</b>; named: <b>{esc(', '.join(named) or 'nothing')}</b>
({verdict}). RMS error {doc['rmse_initial_over_noise']:.1f} &rarr; {doc['rmse_final_over_noise']:.2f} &times; noise
in {doc['seconds']:.0f} s. <a href="discovery/index.html">The discovery report</a>: the record
against each model in turn, the residuals with the flagged windows, the gap step by step
(<a href="discovery/discovery.json">the record as JSON</a>, also a <code>--params</code> file of the
discovered model).</p>
"""


def _validate_arguments(argv: list[str]):
    """`tether validate`'s own parser on ARGV: every option the demo does not give keeps its default."""
    import argparse

    from . import validate

    parser = argparse.ArgumentParser(prog="tether validate")
    validate.add_arguments(parser)
    return parser.parse_args(argv)
