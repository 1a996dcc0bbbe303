"""The account of a run: OUT.json (discovery_document), the terminal's account and the evidence texts."""

from __future__ import annotations

import math

import numpy as np

from ..traces import Trace
from .evidence import lowest_elongation, regimes, Window
from .judge import CRITERIA
from .nuisance import nuisance_lines, nuisance_section
from .records import CandidateResult, Discovery
from .verdicts import effect_verdicts, unexplained, verdict_lines


def ordinal(k: int) -> str:
    """1st, 2nd, 3rd, 4th, ... 11th, 12th, 13th, ... 21st"""
    return f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')}"


def _slack_seen_by(trace: Trace, win: CandidateResult) -> str:
    """The slack signature of a winning slack candidate, completed with what the refitted model
    sees: the model before the step can put the balance lower than the slack model does (a law
    bent to mimic the slack), and its signature alone would say nothing shows a slack tether next to
    the slack just named (a forced Iwan record with slack, 4 slack excursions in the generator)."""
    text = win.signature_text
    if win.signature > 0 or win.fit is None:
        return text
    sl = regimes(trace, win.fit).get("slack")
    lowest, ub = lowest_elongation(trace, win.fit)
    if sl is None or not sl.any() or ub is None:
        return text
    return (f"{text}; with slack and its refitted law (balance stretch {ub:.4g} m) the measured elongation is "
            f"below zero in {100 * np.mean(sl):.1f} % of the record (lowest {lowest + ub:+.4g} m)")


def _evidence(win: CandidateResult, windows: list) -> str:
    where = ""
    if windows:
        top = sorted(windows, key=lambda w: -w.share)[:2]
        where = "; the disagreement was largest in " + ", ".join(
            f"{w.start:.4g}-{w.end:.4g} s ({', '.join(w.regimes) or 'no single regime'})" for w in top)
    return f"{win.signature_text}{where}; refit with {win.effect}: {win.verdict}"


def _window_dict(w: Window, sigma: float) -> dict:
    d = w.as_dict()
    d["rms_over_noise"] = w.rms / sigma
    return d


def discovery_document(d: Discovery) -> dict:
    """The JSON record of a discovery run. Its top-level ``model`` and ``parameters`` make the file
    itself a ``--params`` file of the discovered model (``final_params`` holds the same)."""
    sigma = d.noise.sigma
    tr = d.trace
    unit = "m"
    steps = []
    for st in d.steps:
        if not st.effect or st.effect not in d.final.effects:
            continue
        steps.append({"effect": st.effect, "model_before": st.model_before, "model_after": st.model_after,
                      "where": [_window_dict(w, sigma) for w in st.windows],
                      "evidence": st.evidence, "rmse_before": st.rms_before, "rmse_after": st.rms_after,
                      "rmse_before_over_noise": st.rms_before / sigma, "rmse_after_over_noise": st.rms_after / sigma,
                      "heldout_rmse_before": st.heldout_before,
                      "candidates": [c.as_dict(sigma) for c in st.candidates]})
    rounds = [{"model": st.model_before, "rmse": st.rms_before, "rmse_over_noise": st.rms_before / sigma,
               "heldout_rmse": st.heldout_before, "windows": [_window_dict(w, sigma) for w in st.windows],
               "regimes": st.regimes, "candidates": [c.as_dict(sigma) for c in st.candidates],
               "added": st.effect} for st in d.steps]
    final = d.final
    final_params = {"model": final.model, "parameters": {k: float(v) for k, v in final.law_params.items()}}
    return {
        "format": "tether-discovery/1",
        "trace": str(tr.stem),
        "experiment": tr.experiment,
        "measured_column": tr.measured_column,
        "unit": unit,
        "samples": int(len(tr.time)),
        "searched_every": d.searched_every,
        "start_model": d.start_model,
        "added_effects": d.added_effects,
        "final_model": final.model,
        "rmse_initial": d.fits[0].rms,
        "rmse_final": final.rms,
        "noise_estimate": sigma,
        "noise_method": d.noise.method,
        "rmse_initial_over_noise": d.fits[0].rms / sigma,
        "rmse_final_over_noise": final.rms / sigma,
        "effects": effect_verdicts(d),
        "unexplained": unexplained(d),
        "heldout_from_s": d.heldout_start,
        "heldout_spans_s": [list(span) for span in d.heldout_spans],
        "steps": steps,
        "removed": [{"effect": r.effect, "model_before": r.model_before, "model_after": r.model_after,
                     "rmse_before": r.rms_before, "rmse_after": r.rms_after, "reason": r.reason}
                    for r in d.removals],
        "rounds": rounds,
        "refinements": [r.as_dict(sigma) for r in d.refinements],
        "shape_refined": list(final.shape),
        "nuisance": nuisance_section(tr, final, d.nuisance_freed),
        "stop_reason": d.stop_reason,
        "stages": list(d.stages),
        "seconds": d.seconds,
        "final_params": final_params,
        "model": final_params["model"],
        "parameters": final_params["parameters"],
    }


def nothing_named(rms_over_noise: float, missing: dict | None) -> str:
    """What a run that names no effect says of the start model: nothing is missing only where it
    reproduces the record within the noise."""
    if missing is not None:
        return "no effect named, but something remains unexplained (above)"
    if rms_over_noise <= CRITERIA.within_noise:
        return "no effect is missing from the start model"
    gap = math.sqrt(max(rms_over_noise ** 2 - 1.0, 0.0))
    return (f"no effect named; the start model misses the record at {rms_over_noise:.2f} x noise, a gap of "
            f"{gap:.2f} sigma: less than the noise itself, so nothing is reported unexplained")


def account(d: Discovery) -> str:
    """A short account for the terminal."""
    sigma = d.noise.sigma
    missing = unexplained(d)
    lines = verdict_lines(effect_verdicts(d), missing)
    lines += [f"{d.trace.name} ({d.trace.experiment}): noise {sigma:.3g} m, estimated from the data "
              f"({d.noise.method})",
              f"start: {d.start_model}, RMS error {d.fits[0].rms:.3g} m = {d.fits[0].rms / sigma:.2f} x noise"]
    if d.searched_every > 1:
        lines.append(f"searched on every {ordinal(d.searched_every)} sample of {len(d.trace.time)}; the errors below "
                     "are those of the whole record, the candidates' in the JSON those of the searched samples")
    for i, st in enumerate([s for s in d.steps if s.effect], 1):
        wins = sorted(st.windows, key=lambda w: -w.share)[:3]
        where = ", ".join(f"{w.start:.4g}-{w.end:.4g} s" for w in wins) or "spread over the record"
        lines.append(f"{i}. {st.effect}: RMS error {st.rms_before / sigma:.2f} -> {st.rms_after / sigma:.2f} x noise "
                     f"(model {st.model_after}); disagreement in {where}")
        lines.append(f"   evidence: {st.evidence}")
    for r in d.removals:
        lines.append(f"   removed {r.effect} again: {r.reason}")
    for r in d.refinements:
        if r.accepted and r.law:
            lines.append(f"law of {r.effect} replaced by its rival ({r.law}): {r.verdict}")
        elif r.accepted and r.restart:
            lines.append(f"idle elements of the Iwan bank restarted ({', '.join(r.parameters)}): {r.verdict}")
        elif r.accepted and r.finer:
            lines.append(f"the Iwan bank made finer: {r.verdict}")
        elif r.accepted:
            lines.append(f"shape of {r.effect} refined ({', '.join(r.parameters)}): {r.verdict}")
    if not d.added_effects:
        lines.append(nothing_named(d.final.rms / sigma, missing))
    lines.append(f"stopped: {d.stop_reason}")
    lines += nuisance_lines(nuisance_section(d.trace, d.final, d.nuisance_freed))
    lines.append(f"discovered: {', '.join(d.added_effects) or 'nothing'}; final model {d.final.model}, RMS error "
                 f"{d.final.rms:.3g} m = {d.final.rms / sigma:.2f} x noise ({d.seconds:.1f} s)")
    return "\n".join(lines)
