"""Reports a person opens: plots (PNG), a page (HTML) and the numbers (JSON), written atomically."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Sequence

import numpy as np


def write_text_atomic(path: Path, text: str) -> None:
    from .atomic import write_text

    write_text(path, text)


def write_json_atomic(path: Path, doc) -> None:
    """Strict JSON (what jq and every other parser reads): a number that is not finite (a held-out
    error never asked, a fit that failed) is written as null."""
    write_text_atomic(path, json.dumps(_finite(doc), indent=2, default=_jsonable, allow_nan=False) + "\n")


def _finite(o):
    if isinstance(o, np.ndarray):
        return _finite(o.tolist())
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, (float, np.floating)) and not math.isfinite(float(o)):
        return None
    return o


def _jsonable(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


def save_figure_atomic(fig, path: Path) -> None:
    from .atomic import replace_with

    replace_with(path, lambda tmp: fig.savefig(tmp, dpi=100, format="png"))


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


UNITS = {"displacement": "m", "elongation": "m", "force": "N", "load": "N", "tension": "N"}


def plot_validation(v, path: Path) -> None:
    """Measured and simulated against time, the residual (with the stated noise band), and for load
    tests the tension-elongation loop."""
    plt = pyplot()
    tr = v.trace
    col = tr.measured_column
    load_test = tr.input_column == "load"
    ncols = 2 if load_test else 1
    fig = plt.figure(figsize=(11 if load_test else 9, 6.2))
    gs = fig.add_gridspec(2, ncols, height_ratios=[2, 1], width_ratios=[1.6, 1] if load_test else [1])
    ax = fig.add_subplot(gs[0, 0])
    ax.plot(tr.time, tr.measured, ".", ms=2, color="0.55", label=f"measured {col}")
    ax.plot(tr.time, v.result.predicted, "-", lw=1.1, color="C0", label=f"simulated ({v.model})")
    ax.set_ylabel(f"{col} [m]")
    ax.set_title(f"{tr.stem.name}: RMS error {v.rms:.3g} m, R² {v.r2:.6f}", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    ax2 = fig.add_subplot(gs[1, 0], sharex=ax)
    ax2.plot(tr.time, v.residual, "-", lw=0.8, color="C3", label="simulated - measured")
    if v.noise_sigma:
        ax2.axhspan(-v.noise_sigma, v.noise_sigma, color="C2", alpha=0.15, label=f"±σ noise ({v.noise_sigma:.2g} m)")
    ax2.axvline(v.max_error_time, color="k", lw=0.6, ls=":")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel("residual [m]")
    ax2.legend(loc="best", fontsize=8)
    ax2.grid(alpha=0.3)
    if load_test:
        plot_load_loop(fig.add_subplot(gs[:, 1]), tr.measured, tr.input, v.result.predicted, "simulated",
                       "elongation [m]", "load (tension) [N]")
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def _fmt(x, spec=".3g"):
    if x is None:
        return "–"
    if isinstance(x, bool):
        return "yes" if x else "NO"
    return format(x, spec)


def validation_table(rows: Sequence[dict]) -> str:
    """The terminal table."""
    from .traces import COLUMN_UNITS

    units = {COLUMN_UNITS.get(r.get("measured_column"), "?") for r in rows}
    u = f" [{units.pop()}]" if len(units) == 1 else " [unit of the trace]"
    head = ["trace", "model", f"RMS error{u}", "NRMSE [-]", "R^2 [-]", f"max error{u}", "at [s]", f"noise σ{u}",
            "within noise"]
    lines = [[r["trace"].split("/")[-1], r["model"], _fmt(r["rms_error"]), _fmt(r["normalized_rms_error"]),
              _fmt(r["r2"], ".6f"), _fmt(r["max_error"]), _fmt(r["max_error_time"], ".4g"),
              _fmt(r["noise_sigma"], ".2g"), _fmt(r["within_noise"])] for r in rows]
    if rows and "within_tolerance" in rows[0]:
        head.append("within tolerance")
        for line, r in zip(lines, rows):
            line.append(_fmt(r["within_tolerance"]))
    widths = [max(len(h), *(len(l[i]) for l in lines)) if lines else len(h) for i, h in enumerate(head)]
    fmt = "  ".join("{:<%d}" % w for w in widths)
    out = [fmt.format(*head), fmt.format(*("-" * w for w in widths))]
    out += [fmt.format(*l) for l in lines]
    return "\n".join(line.rstrip() for line in out)


PAGE_STYLE = """
body { font-family: sans-serif; max-width: 1150px; margin: 2em auto; color: #222; }
table { border-collapse: collapse; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #eef; } td.l { text-align: left; }
.bad { background: #fdd; } .good { background: #dfd; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.5em 0 1.5em; }
code { background: #f4f4f4; padding: 0 0.2em; }
"""


def validation_page(rows: Sequence[dict], images: Sequence[str], title: str, intro: str) -> str:
    esc = html.escape
    trs = []
    for r in rows:
        cls = "" if r["within_noise"] is None else (' class="good"' if r["within_noise"] else ' class="bad"')
        trs.append(
            f"<tr{cls}><td class=l><a href='#{esc(r['trace'].split('/')[-1])}'>{esc(r['trace'].split('/')[-1])}</a></td>"
            f"<td class=l>{esc(r['experiment'])}</td><td class=l><code>{esc(r['model'])}</code></td>"
            f"<td>{_fmt(r['rms_error'])}</td><td>{_fmt(r['normalized_rms_error'])}</td><td>{_fmt(r['r2'], '.6f')}</td>"
            f"<td>{_fmt(r['max_error'])}</td><td>{_fmt(r['max_error_time'], '.4g')}</td>"
            f"<td>{_fmt(r['noise_sigma'], '.2g')}</td><td>{_fmt(r['within_noise'])}</td></tr>")
    figs = []
    for r, img in zip(rows, images):
        name = r["trace"].split("/")[-1]
        warn = "".join(f"<p>FMU warning: {esc(w)}</p>" for w in r["warnings"])
        figs.append(f"<h3 id='{esc(name)}'>{esc(name)}</h3><p>model <code>{esc(r['model'])}</code> "
                    f"({esc(r['model_source'])}); RMS error {_fmt(r['rms_error'])} m, largest error "
                    f"{_fmt(r['max_error'])} m at t = {_fmt(r['max_error_time'], '.4g')} s.</p>{warn}"
                    f"<img src='{esc(img)}' alt='{esc(name)}'>")
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{esc(title)}</title><style>{PAGE_STYLE}</style></head>
<body><h1>{esc(title)}</h1><p>{intro}</p>
<table><tr><th>trace</th><th>experiment</th><th>model</th><th>RMS error [m]</th><th>NRMSE</th><th>R²</th>
<th>max error [m]</th><th>at [s]</th><th>noise σ [m]</th><th>within noise</th></tr>
{''.join(trs)}</table>
<p>NRMSE: RMS error divided by the standard deviation of the measurement. "Within noise": the RMS
error is at most {1.2}× the noise σ the trace states (synthetic reference traces state theirs).</p>
{''.join(figs)}
</body></html>
"""


def plot_load_loop(ax, measured, load, predicted, label: str, xlabel: str, ylabel: str) -> None:
    """The tension-elongation loop of a load test: measured points and the model's curve."""
    ax.plot(measured, load, ".", ms=2, color="0.55", label="measured")
    ax.plot(predicted, load, "-", lw=1.0, color="C0", label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title("tension-elongation loop", fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
