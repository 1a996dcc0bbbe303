"""The report of a campaign discovery (``tether discover A B ... --report DIR``): DIR/index.html
with the story per step across the records (a small panel per record: the record against the
model before and after the step, and the residual of each against the record's noise), the
table of which record revealed what, and DIR/discovery.json (the same record as --json)."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from .report import PAGE_STYLE, pyplot, save_figure_atomic, write_json_atomic, write_text_atomic


def plot_step(d, k: int, path: Path) -> None:
    """Step ``k`` (0: the start model alone) across the records: per record, the measured column
    with the model before and after the step (the start model: the model alone), and both
    residuals against +- its noise."""
    plt = pyplot()
    recs = d.records
    if k == 0:
        fits = [(d.fits[0], "start " + d.fits[0].model, "C0")]
    else:
        s = d.steps[k - 1]
        fits = [(s.fit_before, "before: " + s.model_before, "C0")]
        if s.fit_after is not None:
            fits.append((s.fit_after, "after: " + s.model_after, "C1"))
    fig, axes = plt.subplots(2, len(recs), figsize=(4.2 * len(recs), 5.0), squeeze=False,
                             gridspec_kw={"height_ratios": [2, 1]})
    for i, r in enumerate(recs):
        t = np.asarray(r.trace.time, float)
        if r.trace.experiment == "creep":
            t = t / 3600.0
        ax, ax2 = axes[0, i], axes[1, i]
        ax.plot(t, r.trace.measured, ".", ms=1.2, color="0.6", label="measured")
        for f, label, color in fits:
            if not f.ok:
                continue
            ax.plot(t, f.predicted[i], "-", lw=0.8, color=color, label=f"{label} ({f.rms_records[i] / r.sigma:.2f}×σ)")
            ax2.plot(t, f.predicted[i] - r.trace.measured, "-", lw=0.5, color=color)
        revealed = k > 0 and r.name in d.steps[k - 1].revealed_by
        ax.set_title(f"{r.name} ({r.trace.experiment})" + (": revealed it" if revealed else ""), fontsize=8,
                     color="C3" if revealed else "k")
        ax.legend(fontsize=6, loc="upper right")
        ax.grid(alpha=0.3)
        ax2.axhspan(-r.sigma, r.sigma, color="C2", alpha=0.2)
        ax2.set_xlabel("time [h]" if r.trace.experiment == "creep" else "time [s]", fontsize=8)
        ax2.grid(alpha=0.3)
        if i == 0:
            ax.set_ylabel("measured [m]", fontsize=8)
            ax2.set_ylabel("residual [m] (band: ± noise)", fontsize=8)
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def _cell(x, spec=".2f") -> str:
    return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


def campaign_page(doc: dict, images: list) -> str:
    esc = html.escape
    names = [r["name"] for r in doc["records"]]
    head = "".join(f"<th>{esc(n)}<br><small>{esc(r['experiment'])}</small></th>"
                   for n, r in zip(names, doc["records"]))
    table = []
    for k, s in enumerate([s for s in doc["steps"] if s["effect"]], 1):
        cells = "".join(
            f"<td class={'good' if x['revealed'] else ''}>{_cell(x['rmse_before_over_noise'])} → "
            f"{_cell(x['rmse_after_over_noise'])}{' <b>revealed</b>' if x['revealed'] else ''}</td>"
            for x in s["records"])
        table.append(f"<tr><td>{k}</td><td class=l><b>{esc(s['effect'])}</b></td>{cells}"
                     f"<td class=l>{esc(s['revealed_how'])}</td></tr>")
    verdicts = "".join(
        f"<tr><td class=l>{esc(e)}</td><td class=l><b>{esc(v['verdict'])}</b></td>"
        + "".join(f"<td class=l>{esc(r['effects'][e]['verdict'])}</td>" for r in doc["records"])
        + "</tr>" for e, v in doc["effects"].items())
    recs = "".join(
        f"<tr class={'bad' if r['contradicting'] else ''}><td class=l>{esc(r['name'])}</td><td class=l>"
        f"{esc(r['experiment'])}</td><td>{r['samples']}</td><td>{r['noise_estimate']:.3g}</td>"
        f"<td>{r['rmse_initial_over_noise']:.2f}</td><td>{r['rmse_final_over_noise']:.2f}</td>"
        f"<td class=l>{esc(', '.join(r['revealed']) or '–')}</td></tr>" for r in doc["records"])
    removed = "".join(f"<p>Removed <b>{esc(x['effect'])}</b> ({esc(x['model_before'])} → {esc(x['model_after'])}): "
                      f"{esc(x['reason'])}</p>" for x in doc.get("removals", []))
    contra = "".join(f"<p class=bad><b>{esc(c['name'])} contradicts the other records</b>: {esc(c['why'])}</p>"
                     for c in doc["contradicting"])
    figs = "".join(f"<h3>{esc(title)}</h3><img src='{esc(img)}' alt='{esc(title)}'>" for title, img in images)
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>campaign discovery</title>
<style>{PAGE_STYLE} td.good{{background:#e3f4e3}} tr.bad td, p.bad{{background:#fbe3e3}}</style></head><body>
<h1>Discovery over a campaign of {len(names)} records</h1>
<p>Start model <code>{esc(doc['start_model'])}</code>; discovered <b>{esc(', '.join(doc['added_effects']) or 'nothing')}
</b>; final model <code>{esc(doc['final_model'])}</code>, campaign RMS error {doc['rmse_initial_over_noise']:.2f} →
{doc['rmse_final_over_noise']:.2f} × noise. Stopped: {esc(doc['stop_reason'])}.</p>
{contra}
<h2>The records</h2>
<table><tr><th>record</th><th>experiment</th><th>samples</th><th>noise [m]</th><th>start [×σ]</th>
<th>final [×σ]</th><th>revealed</th></tr>{recs}</table>
<h2>Which record revealed what</h2>
<p>Each record's RMS error over its own noise before → after the step; <i>revealed</i>: the effect earns its
place on that record alone by the one-record rule.</p>
<table><tr><th>step</th><th>effect</th>{head}<th>how</th></tr>{''.join(table)}</table>
{removed}
<h2>Every effect</h2>
<table><tr><th>effect</th><th>campaign</th>{head}</tr>{verdicts}</table>
<h2>The story, step by step</h2>{figs}
</body></html>
"""


def write_campaign_report(report: Path, d, doc: dict) -> None:
    report = Path(report)
    images = []
    for k in range(len(d.steps) + 1):
        if k and d.steps[k - 1].effect is None and d.steps[k - 1].fit_after is None:
            continue
        name = f"step{k}.png"
        plot_step(d, k, report / name)
        title = "the start model" if k == 0 else f"step {k}: {d.steps[k - 1].effect}"
        images.append((title, name))
    write_json_atomic(report / "discovery.json", doc)
    write_text_atomic(report / "index.html", campaign_page(doc, images))
