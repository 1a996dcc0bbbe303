"""The report of a discovery run (``tether discover --report DIR``): DIR/index.html, plots, and
DIR/discovery.json (the same record as --json)."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from .discover import ordinal
from .discover.judge import CRITERIA
from .report import PAGE_STYLE, pyplot, save_figure_atomic, write_json_atomic, write_text_atomic


def plot_models(d, path: Path) -> None:
    """The record against each model in turn, each with its residual and the flagged windows."""
    plt = pyplot()
    tr = d.trace
    sigma = d.noise.sigma
    col = tr.measured_column
    load_test = tr.input_column == "load"
    from .discover import disagreement

    fits = d.fits
    k = len(fits)
    fig = plt.figure(figsize=(12 if load_test else 10, 3.6 * k + 0.4))
    gs = fig.add_gridspec(2 * k, 2 if load_test else 1, height_ratios=[2, 1] * k,
                          width_ratios=[1.7, 1] if load_test else [1])
    t = np.asarray(tr.time, float)
    for i, f in enumerate(fits):
        ax = fig.add_subplot(gs[2 * i, 0])
        ax.plot(t, tr.measured, ".", ms=1.5, color="0.55", label=f"measured {col}")
        ax.plot(t, f.predicted, "-", lw=0.9, color=f"C{i}", label=f"model {f.model}")
        title = "start" if i == 0 else f"model {i + 1}"
        ax.set_title(f"{title}: {f.label}, RMS error {f.rms:.3g} m = {f.rms / sigma:.2f} × noise", fontsize=9)
        ax.set_ylabel(f"{col} [m]")
        ax.legend(loc="upper right", fontsize=7)
        ax.grid(alpha=0.3)
        ax2 = fig.add_subplot(gs[2 * i + 1, 0], sharex=ax)
        r = f.predicted - tr.measured
        ax2.plot(t, r, "-", lw=0.6, color="C3", label="model - measured")
        ax2.axhspan(-sigma, sigma, color="C2", alpha=0.2, label=f"± noise σ ({sigma:.2g} m, from the data)")
        if i < k - 1 or f.rms > 1.1 * sigma:
            for j, w in enumerate(disagreement(tr, f, sigma)):
                ax2.axvspan(w.start, w.end, color="orange", alpha=0.25,
                            label="residual above the noise" if j == 0 else None)
        for j, (a, b) in enumerate(d.heldout_spans or [(d.heldout_start, float(t[-1]))]):
            ax2.axvspan(a, b, color="0.5", alpha=0.12, lw=0, label="held out" if j == 0 else None)
        ax2.set_ylabel("residual [m]")
        ax2.legend(loc="upper right", fontsize=7)
        ax2.grid(alpha=0.3)
        if i == k - 1:
            ax2.set_xlabel("time [s]  (grey: the samples the held-out test predicts)")
        if load_test:
            ax3 = fig.add_subplot(gs[2 * i:2 * i + 2, 1])
            ax3.plot(tr.measured, tr.input, ".", ms=1.5, color="0.55", label="measured")
            ax3.plot(f.predicted, tr.input, "-", lw=0.9, color=f"C{i}", label=f.model)
            ax3.set_xlabel("elongation [m]")
            ax3.set_ylabel("load [N]")
            ax3.legend(loc="lower right", fontsize=7)
            ax3.grid(alpha=0.3)
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def plot_gap(d, path: Path) -> None:
    """RMS error over the noise, step by step, with every candidate tried in each round."""
    plt = pyplot()
    sigma = d.noise.sigma
    fig, ax = plt.subplots(figsize=(8, 4.2))
    xs = list(range(len(d.fits)))
    ax.plot(xs, [f.rms / sigma for f in d.fits], "o-", color="C0", lw=2, label="model (whole record)")
    held = [s.heldout_before / sigma for s in d.steps] + [r.heldout_after / sigma for r in d.refinements if r.accepted]
    if len(held) == len(xs):
        ax.plot(xs, held, "s--", color="C1", label="held-out part (fit on the first part)")
    for i, st in enumerate(d.steps):
        for c in st.candidates:
            y = c.rms / sigma
            if not np.isfinite(y):
                continue
            ax.plot(i + 0.5, y, "x" if not c.accepted else "o", color="C2" if c.accepted else "C3", ms=7)
            ax.annotate(c.effect.replace("_", " "), (i + 0.5, y), fontsize=7, xytext=(4, 0),
                        textcoords="offset points")
    ax.axhline(1.0, color="k", lw=0.8, label="noise level")
    ax.set_yscale("log")
    labels = [f.label.replace(" (", "\n(") for f in d.fits]
    ax.set_xticks(xs, labels, fontsize=8, rotation=15)
    ax.set_ylabel("RMS error / noise σ")
    ax.set_title("the gap, step by step (crosses: candidates that did not earn their parameters)", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    save_figure_atomic(fig, path)
    plt.close(fig)


def _f(x, spec=".3g"):
    return "–" if x is None or (isinstance(x, float) and not np.isfinite(x)) else format(x, spec)


#: a verdict's row class on the page: present green, absent plain, undetermined grey
_VERDICT_CLASS = {"present": "good", "absent": "", "undetermined": "undetermined"}


def verdicts_html(doc: dict) -> str:
    """The verdict on every effect (OUT.json's ``effects``) and the unexplained part, in words."""
    esc = html.escape
    rows = "".join(
        f"<tr class='{_VERDICT_CLASS[v['verdict']]}'><td class=l><b>{esc(e)}</b></td><td class=l>{esc(v['verdict'])}"
        f"</td><td>{_f(v['weight'], '.2f')}</td><td class=l>{esc(v['evidence'])}</td></tr>"
        for e, v in doc["effects"].items())
    un = doc["unexplained"]
    if un is not None:
        said = f"<p class=bad><b>Unexplained</b> ({un['gap_noise']:.2f} × the noise): {esc(un['text'])}</p>"
    else:
        said = f"<p>{esc(nothing_missing(doc))}</p>"
    return ("<h2>The effects</h2><p>Present: named in the final model. Absent: the record can reveal it, and it "
            "was tested and did not earn its place. Undetermined: the experiment or this record cannot reveal it, "
            "or it was not tested to the end. Weight: how strongly the data prefer the model with the effect to "
            "the one without it, 1 / (1 + exp(ΔBIC / 2)) from its last decisive test (– where none).</p>"
            "<table><tr><th>effect</th><th>verdict</th><th>weight</th><th>evidence</th></tr>"
            f"{rows}</table>\n{said}")


def nothing_missing(doc: dict) -> str:
    """What the page says where nothing is unexplained: the final model within the noise, or its gap
    less than the noise."""
    r = doc["rmse_final_over_noise"]
    if r <= CRITERIA.within_noise:
        return f"Nothing remains unexplained: the final model reproduces the record within the noise ({r:.2f} × noise)."
    return (f"Nothing is reported unexplained: the final model misses the record at {r:.2f} × noise, a gap above "
            "the noise smaller than the noise itself.")


def _step_rows(doc: dict) -> str:
    """The table rows of the steps: each effect added, its model, the error before and after, where."""
    esc = html.escape
    rows = []
    for i, s in enumerate(doc["steps"], 1):
        where = "; ".join(f"{w['start_s']:.4g}–{w['end_s']:.4g} s ({esc(', '.join(w['regimes']) or '–')})"
                          for w in sorted(s["where"], key=lambda w: -w["share_of_excess"])[:4])
        rows.append(f"<tr><td>{i}</td><td class=l><b>{esc(s['effect'])}</b></td><td class=l><code>"
                    f"{esc(s['model_after'])}</code></td><td>{s['rmse_before_over_noise']:.2f}</td>"
                    f"<td>{s['rmse_after_over_noise']:.2f}</td><td class=l>{where or '–'}</td>"
                    f"<td class=l>{esc(s['evidence'])}</td></tr>")
    return "".join(rows)


def _round_html(i: int, r: dict, doc: dict, sigma: float) -> str:
    """One round of the search: its model, where the residual stands out, its candidates, its verdict."""
    esc = html.escape
    cands = "".join(
        f"<tr class={'good' if c['accepted'] else 'bad'}><td class=l>{esc(c['effect'])}</td>"
        f"<td class=l><code>{esc(c['model'])}</code></td><td>{c['added_parameters']}</td>"
        f"<td>{_f(c['rmse_over_noise'], '.2f')}</td><td>{_f(c['heldout_rmse_over_noise'], '.2f')}</td>"
        f"<td>{_f(c['bic_change'], '.0f')}</td><td>{c['signature']:.2f}</td>"
        f"<td class=l>{esc(c['signature_text'])}</td><td class=l>{esc(c['verdict'])}</td></tr>"
        for c in r["candidates"])
    reg = "".join(f"<tr><td class=l>{esc(k)}</td><td>{100 * v['samples']:.0f} %</td>"
                  f"<td>{v['rms_over_noise']:.2f}</td><td>{100 * v['share_of_excess']:.0f} %</td></tr>"
                  for k, v in r["regimes"].items())
    wins = ", ".join(f"{w['start_s']:.4g}–{w['end_s']:.4g} s" for w in r["windows"][:12]) or "none"
    more = f" (and {len(r['windows']) - 12} more)" if len(r["windows"]) > 12 else ""
    head = f"Round {i + 1}: <code>{esc(r['model'])}</code>, RMS error {r['rmse_over_noise']:.2f} × noise " \
           f"(held-out {r['heldout_rmse'] / sigma:.2f} × noise)"
    body = f"<p>Windows where the residual stands above the noise: {esc(wins)}{more}.</p>" \
           f"<table><tr><th>regime</th><th>samples</th><th>RMS / σ</th><th>share of the excess</th></tr>{reg}</table>"
    if cands:
        body += ("<table><tr><th>candidate</th><th>model</th><th>added parameters</th><th>RMS / σ</th>"
                 "<th>held-out RMS / σ</th><th>ΔBIC</th><th>signature</th><th>what the residual shows</th>"
                 f"<th>verdict</th></tr>{cands}</table>")
    verdict = f"<p>Added: <b>{esc(r['added'])}</b>.</p>" if r["added"] else f"<p>Stopped: {esc(doc['stop_reason'])}</p>"
    return f"<h3>{head}</h3>{body}{verdict}"


def _refinements_html(doc: dict, sigma: float) -> str:
    """The section on the named laws' shapes, rivals and reseeds ("" where none was tried)."""
    esc = html.escape
    refined = "".join(
        f"<tr class={'good' if r['accepted'] else 'bad'}><td class=l>{esc(r['effect'])}</td>"
        f"<td class=l>{esc(_refinement_terms(r))}</td>"
        f"<td>{_f(r['rmse_before_over_noise'], '.2f')}</td>"
        f"<td>{_f(r['rmse_after_over_noise'], '.2f')}</td><td>{_f(r['heldout_rmse_before'] / sigma, '.2f')}</td>"
        f"<td>{_f(r['heldout_rmse_after'] / sigma, '.2f')}</td><td>{_f(r['bic_change'], '.0f')}</td>"
        f"<td class=l>{esc(r['verdict'])}</td></tr>" for r in doc["refinements"])
    if not refined:
        return ""
    return ("<h2>The shape of the named laws</h2><p>With the effects named, the shape terms of their laws "
            "were freed one group at a time (kept when the BIC falls and the held-out part does not get "
            "worse; the best group wins), and a hysteresis named before another effect was fitted again "
            "with its rival law in its place, kept on the same terms. An Iwan bank still above the noise had "
            "its idle elements restarted (kept on a lower error), then was made finer, sixteen elements for "
            "eight (kept on the same terms as a shape). This changes no effect's name.</p>"
            "<table><tr><th>effect</th>"
            "<th>terms freed</th><th>RMS / σ before</th><th>after</th><th>held-out RMS / σ before</th>"
            f"<th>after</th><th>ΔBIC</th><th>verdict</th></tr>{refined}</table>")


def discovery_page(d, doc: dict, images: dict) -> str:
    esc = html.escape
    sigma = d.noise.sigma
    tr = d.trace
    steps = _step_rows(doc)
    rounds = [_round_html(i, r, doc, sigma) for i, r in enumerate(doc["rounds"])]
    refined = _refinements_html(doc, sigma)
    nuisance = nuisance_html(doc.get("nuisance"))
    added = ", ".join(doc["added_effects"]) or "nothing"
    every = int(doc.get("searched_every", 1))
    searched = "" if every == 1 else (
        f"<p>A long record: the search ran on every {ordinal(every)} sample of {doc['samples']}, and its "
        "model was then fitted to the whole record. The models in turn, the steps and the plots show the "
        "whole record's errors; the rounds' candidates show those of the searched samples.</p>\n")
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>Discovery: {esc(tr.name)}</title><style>{PAGE_STYLE}
td.l {{ max-width: 30em; }} .undetermined {{ color: #666; }}</style></head>
<body><h1>Discovery on {esc(tr.name)} ({esc(tr.experiment)})</h1>
{verdicts_html(doc)}
<p>Start model <code>{esc(doc['start_model'])}</code>, RMS error {doc['rmse_initial']:.3g} m
({doc['rmse_initial_over_noise']:.2f} × the noise). Noise estimated from the data: {sigma:.3g} m
({esc(doc['noise_method'])}). <b>Discovered: {esc(added)}</b>; final model <code>{esc(doc['final_model'])}</code>,
RMS error {doc['rmse_final']:.3g} m = {doc['rmse_final_over_noise']:.2f} × the noise. {doc['seconds']:.1f} s.</p>
{searched}<p>Numbers: <a href="discovery.json">discovery.json</a> (also a <code>--params</code> file of the final model:
<code>tether simulate OTHER.csv --params discovery.json</code>).</p>
<h2>The steps</h2>
<table><tr><th>#</th><th>effect</th><th>model after</th><th>RMS / σ before</th><th>after</th>
<th>where the disagreement was</th><th>evidence</th></tr>{steps or '<tr><td colspan=7>no step: no effect named</td></tr>'}</table>
{nuisance}
<h2>The gap, step by step</h2><img src="{esc(images['gap'])}" alt="gap">
<h2>The record against each model</h2>
<p>Each model in turn: the record and the model's prediction; below, the residual with the noise band
and the windows where it stands above the noise (orange). The dotted line is where the held-out part
begins: the candidate fits used for the held-out test saw only the record before it.</p>
<img src="{esc(images['models'])}" alt="models">
<h2>Every round</h2>{''.join(rounds)}
<p>Stopped: {esc(doc['stop_reason'])}</p>
{refined}
</body></html>
"""


def nuisance_html(section: dict | None) -> str:
    """The nuisance parameters of the final model (discover.nuisance_section): what the record
    states, the fitted value with its 95 % interval, how far it moved; and what was kept and why."""
    if not section:
        return ""
    esc = html.escape
    rows = "".join(
        f"<tr class={'bad' if v['moved'] else 'good'}><td class=l>{esc(n)}</td><td>{v['start']:.6g}</td>"
        f"<td>{v['value']:.6g}</td><td>" + (f"{v['interval'][0]:.6g} – {v['interval'][1]:.6g}" if v["interval"]
                                             else "–") + "</td>"
        f"<td>{v['change']:+.4g}" + (f" ({100 * v['change_relative']:+.1f} %)" if v["change_relative"] is not None
                                      else "") + "</td>"
        f"<td>{_f(v['change_interval_widths'], '+.2f')}</td><td>{'moved' if v['moved'] else 'no' if v['interval'] else '–'}</td></tr>"
        for n, v in section["parameters"].items())
    kept = "".join(f"<li><code>{esc(n)}</code>: {esc(why)}</li>" for n, why in section["not_freed"].items())
    band = section.get("mass_band_kg")
    band_text = (f" The effective mass was free in {band[0]:.4g}–{band[1]:.4g} kg (±{100 * section['mass_band_rel']:.0f} % "
                 "of the trace's payload mass)." if band and "m" in section["parameters"] else "")
    return ("<h2>Nuisance parameters</h2><p>Free in every fit from the start model on, so that no effect is "
            "named for what they explain. Start: what the record states (its mass, its initial state; offsets 0). "
            f"Moved: the 95 % interval leaves the start out.{band_text}</p>"
            "<table><tr><th>parameter</th><th>record</th><th>fitted</th><th>95 % interval</th><th>change</th>"
            f"<th>in interval widths</th><th>moved</th></tr>{rows or '<tr><td colspan=7>none freed</td></tr>'}</table>"
            + (f"<p>Kept at the record's value:</p><ul>{kept}</ul>" if kept else ""))


def _refinement_terms(r: dict) -> str:
    """What a last-stage row did and the terms it freed or set."""
    terms = " ".join(r["parameters"])
    if r.get("law"):
        return f"law {r['law']}: {terms}"
    if r.get("restart"):
        return f"idle elements restarted: {terms}"
    if r.get("finer"):
        return f"finer bank, {len(r['parameters'])} terms added: {terms}"
    return terms


def write_discovery_report(report: Path, d, doc: dict) -> None:
    report = Path(report)
    images = {"models": "models.png", "gap": "gap.png"}
    plot_models(d, report / images["models"])
    plot_gap(d, report / images["gap"])
    write_json_atomic(report / "discovery.json", doc)
    write_text_atomic(report / "index.html", discovery_page(d, doc, images))
