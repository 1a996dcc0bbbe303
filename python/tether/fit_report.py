"""The report of a fit (``tether fit --report DIR``): DIR/index.html with plots, DIR/fit.json."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Sequence

import numpy as np

from .report import PAGE_STYLE, UNITS, plot_load_loop, pyplot, save_figure_atomic, write_json_atomic, write_text_atomic


def plot_trace_fit(trace, predicted: np.ndarray, rms: float, noise: float, model: str, path: Path) -> None:
    """Measured and fitted against time, and the residual with the noise band (+ the loop for load tests)."""
    plt = pyplot()
    col = trace.measured_column
    unit = UNITS.get(col, "")
    load_test = trace.input_column == "load"
    fig = plt.figure(figsize=(11 if load_test else 9, 6.2))
    gs = fig.add_gridspec(2, 2 if load_test else 1, height_ratios=[2, 1],
                          width_ratios=[1.6, 1] if load_test else [1])
    ax = fig.add_subplot(gs[0, 0])
    ax.plot(trace.time, trace.measured, ".", ms=2, color="0.55", label=f"measured {col}")
    ax.plot(trace.time, predicted, "-", lw=1.0, color="C0", label=f"fitted ({model})")
    ax.set_ylabel(f"{col} [{unit}]")
    ax.set_title(f"{trace.stem.name}: RMS error {rms:.3g} {unit} (noise from the data {noise:.2g} {unit})",
                 fontsize=10)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    ax2 = fig.add_subplot(gs[1, 0], sharex=ax)
    ax2.plot(trace.time, predicted - trace.measured, "-", lw=0.7, color="C3", label="fitted - measured")
    ax2.axhspan(-noise, noise, color="C2", alpha=0.15, label="± noise σ")
    ax2.set_xlabel("time [s]")
    ax2.set_ylabel(f"residual [{unit}]")
    ax2.legend(loc="best", fontsize=8)
    ax2.grid(alpha=0.3)
    if load_test:
        plot_load_loop(fig.add_subplot(gs[:, 1]), trace.measured, trace.input, predicted, "fitted", f"{col} [{unit}]", "load [N]")
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def plot_correlation(names: Sequence[str], corr: np.ndarray, flagged: Sequence[str], path: Path) -> None:
    plt = pyplot()
    k = len(names)
    fig, ax = plt.subplots(figsize=(1.2 + 0.75 * k, 1.0 + 0.65 * k))
    im = ax.imshow(np.asarray(corr), vmin=-1, vmax=1, cmap="RdBu_r")
    labels = [n + (" *" if n in flagged else "") for n in names]
    ax.set_xticks(range(k), labels, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(k), labels, fontsize=8)
    for i in range(k):
        for j in range(k):
            v = float(corr[i][j])
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7, color="w" if abs(v) > 0.6 else "k")
    fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    ax.set_title("correlation of the fitted parameters" + (" (* not determined)" if flagged else ""), fontsize=9)
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def write_fit_report(directory: str | Path, traces: Sequence, result) -> Path:
    """DIR/index.html (plots per trace, the correlation matrix, the identifiability report) and DIR/fit.json."""
    d = Path(directory)
    images = []
    for tr, pred, rms, noise in zip(traces, result.predictions, result.rms_per_trace, result.noise):
        img = f"plots/{tr.stem.name}.png"
        plot_trace_fit(tr, pred, rms, noise, result.model, d / img)
        images.append(img)
    corr_img = "plots/correlation.png"
    plot_correlation(result.free, result.correlation, result.unidentifiable, d / corr_img)
    write_json_atomic(d / "fit.json", result.as_dict())
    esc = html.escape
    rows = []
    for n in result.free:
        lo, hi = result.ci95[n]
        bad = n in result.unidentifiable
        rows.append(f"<tr{' class=bad' if bad else ''}><td class=l><code>{esc(n)}</code></td>"
                    f"<td>{result.values[n]:.6g}</td><td>{result.std_error[n]:.3g}</td>"
                    f"<td>[{lo:.6g}, {hi:.6g}]</td><td>{result.start.get(n, float('nan')):.6g}</td>"
                    f"<td class=l>{'not determined' if bad else ''}</td></tr>")
    held = "".join(f"<code>{esc(k)}</code> = {v:.6g}; " for k, v in result.parameters.items() if k not in result.free)
    nuisance = ""
    if result.nuisance:
        fitted = [n for n in result.nuisance if n in result.free]
        given = "; ".join(f"<code>{esc(n)}</code> = {v:.6g}" for n, v in result.nuisance.items() if n not in fitted)
        nuisance = ("<h2>Nuisance parameters</h2><p>What the record knows imperfectly about its experiment "
                    "(docs/nuisance.md); fitted ones are in the table above.</p>"
                    + (f"<pre>{esc(chr(10).join(result.nuisance_moved))}</pre>" if result.nuisance_moved else "")
                    + (f"<p>Given: {given}</p>" if given else ""))
    per = "".join(f"<tr><td class=l>{esc(n)}</td><td>{r:.4g}</td><td>{s:.3g}</td></tr>"
                  for n, r, s in zip(result.traces, result.rms_per_trace, result.noise))
    stages = "".join(f"<tr><td class=l>{esc(s['stage'])}</td><td class=l>{esc(', '.join(s['free']))}</td>"
                     f"<td>{s['rms']:.4g}</td><td>{s['evaluations']}</td><td>{s['seconds']:.1f}</td>"
                     f"<td class=l>{esc(s['message'])}</td></tr>" for s in result.stages)
    figs = "".join(f"<h3>{esc(tr.stem.name)}</h3><img src='{esc(img)}' alt='{esc(tr.stem.name)}'>"
                   for tr, img in zip(traces, images))
    page = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>tether fit: {esc(result.model)}</title><style>{PAGE_STYLE}</style></head>
<body><h1>Fit of <code>{esc(result.model)}</code></h1>
<p>{len(traces)} trace(s) fitted jointly in {result.seconds:.1f} s ({result.evaluations} simulations; engine:
{esc(result.message)}). Overall RMS error {result.rms:.4g}. Numbers: <a href="fit.json">fit.json</a>.</p>
<h2>Parameters</h2>
<table><tr><th>parameter</th><th>value</th><th>std error</th><th>95 % interval</th><th>start (from the data)</th><th></th></tr>
{''.join(rows)}</table>
<p>Held fixed: {held or 'nothing'}</p>
{nuisance}
<h2>Traces</h2>
<table><tr><th>trace</th><th>RMS error</th><th>noise σ estimated from the data</th></tr>{per}</table>
<h2>Identifiability</h2>
<pre>{esc(result.identifiability_report)}</pre>
<img src='{corr_img}' alt='correlation matrix'>
<h2>Stages</h2>
<table><tr><th>stage</th><th>free</th><th>RMS</th><th>simulations</th><th>seconds</th><th>stop</th></tr>{stages}</table>
<h2>Measured and fitted</h2>
{figs}
</body></html>
"""
    write_text_atomic(d / "index.html", page)
    return d / "index.html"
