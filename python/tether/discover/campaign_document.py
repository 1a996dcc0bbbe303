"""A campaign discovery's OUT.json (campaign_document) and its account for the terminal
(campaign_account): the one-record document's keys where they mean the same (added_effects,
steps, final_params, a --params file at the top level), plus ``records`` (one entry per record:
its noise, its error at the start, after every step and at the end, the effects it revealed and
the verdict on every effect for it) and ``contradicting``."""

from __future__ import annotations

from ..models import EFFECTS
from .campaign import CampaignDiscovery, Record
from .judge import CRITERIA
from .laws import unrevealed
from .records import effects_added


def _over(x, r: Record):
    return None if x is None else x / r.sigma


def _campaign_verdicts(d: CampaignDiscovery) -> dict:
    """Every effect of the vocabulary on the campaign: present (the step that added it and who
    revealed it), absent (some record can reveal it and it did not earn its place) or undetermined
    (no record of the campaign can reveal it, or a step could not tell it from another: _not_earned)."""
    out = {}
    added = {s.effect: (k, s) for k, s in enumerate(d.steps, 1) if s.effect and s.effect in d.final.effects}
    removed = {x.effect: x for x in d.removals if x.effect not in d.final.effects}
    for e in EFFECTS:
        why_not = {r.name: unrevealed(r.trace, e) for r in d.records}
        if e in d.final.effects and e not in added:
            out[e] = {"verdict": "present", "evidence": f"in the start model {d.start_model}: assumed, not tested"}
        elif e in added:
            k, s = added[e]
            out[e] = {"verdict": "present",
                      "evidence": (f"added in step {k} ({s.model_before} -> {s.model_after}): campaign RMS error "
                                   f"{s.rms_before:.2f} -> {s.rms_after:.2f} x noise; revealed by "
                                   f"{', '.join(s.revealed_by)} ({s.revealed_how})"),
                      "revealed_by": list(s.revealed_by)}
        elif e in removed:
            out[e] = {"verdict": "absent", "evidence": f"added, then removed: {removed[e].reason}"}
        elif all(why_not.values()):
            out[e] = {"verdict": "undetermined",
                      "evidence": "no record of the campaign can reveal it: " + "; ".join(
                          f"{n}: {w}" for n, w in why_not.items())}
        else:
            out[e] = _not_earned(d, e)
    return out


def _not_earned(d: CampaignDiscovery, e: str) -> dict:
    """The verdict on an effect some record can reveal that the final model does not hold: absent,
    or undetermined where the last step that fitted it found another effect tied with it."""
    tested = [c for s in d.steps for c in s.candidates if c.effect == e]
    if tested and tested[-1].tied_with:
        return {"verdict": "undetermined",
                "evidence": f"the campaign does not tell it from {tested[-1].tied_with}: {tested[-1].verdict}"}
    if tested:
        ev = f"tested on the campaign, not earned: {tested[-1].verdict}"
    elif d.final.ok and all(x <= CRITERIA.within_noise * r.sigma for x, r in zip(d.final.rms_records, d.records)):
        ev = "every record is reproduced within the noise without it"
    else:
        ev = f"not tested: {d.stop_reason}"
    return {"verdict": "absent", "evidence": ev}


def _record_verdicts(d: CampaignDiscovery, i: int, campaign: dict) -> dict:
    """Every effect for record ``i``: undetermined where the record cannot reveal it (whatever the
    campaign says), else the campaign's verdict, with what this record showed of it."""
    r = d.records[i]
    out = {}
    for e, v in campaign.items():
        why = unrevealed(r.trace, e)
        step = next(((k, s) for k, s in enumerate(d.steps, 1) if s.effect == e and e in d.final.effects), None)
        if why:
            out[e] = {"verdict": "undetermined", "campaign": v["verdict"], "evidence": f"this record cannot reveal it: {why}"}
        elif step is not None:
            k, s = step
            b, a = s.records_before[i] / r.sigma, s.records_after[i] / r.sigma
            here = r.name in s.revealed_by
            out[e] = {"verdict": "present", "campaign": v["verdict"], "revealed_here": here,
                      "evidence": (f"{'revealed here' if here else 'carried by the campaign'} in step {k}: RMS error "
                                   f"{b:.2f} -> {a:.2f} x noise")}
        else:
            out[e] = {"verdict": v["verdict"], "campaign": v["verdict"], "evidence": v["evidence"]}
    return out


def campaign_document(d: CampaignDiscovery) -> dict:
    final = d.final
    campaign = _campaign_verdicts(d)
    steps = []
    for k, s in enumerate(d.steps, 1):
        win = next((c for c in s.candidates if c.accepted), None)
        steps.append({
            "effect": s.effect, "model_before": s.model_before, "model_after": s.model_after,
            "rmse_before_over_noise": s.rms_before, "rmse_after_over_noise": s.rms_after,
            "revealed_by": s.revealed_by, "revealed_how": s.revealed_how,
            "evidence": win.verdict if win else None,
            "current_refit": s.refit,
            "retests": [{"effect": t.effect, "bic_change": t.bic_change, "kept": t.kept, "verdict": t.verdict,
                         "beside": t.beside}
                        for t in s.retests],
            "records": [{"trace": r.name, "rmse_before": b, "rmse_after": a,
                         "rmse_before_over_noise": b / r.sigma, "rmse_after_over_noise": _over(a, r),
                         "revealed": r.name in s.revealed_by}
                        for r, b, a in zip(d.records, s.records_before, s.records_after or [None] * len(d.records))],
            "candidates": [{"effect": c.effect, "model": c.fit.model, "added_parameters": c.added_parameters,
                            "rmse_over_noise": c.fit.rms, "heldout_rmse_over_noise": c.heldout_rms,
                            "bic_change": c.bic_change, "records_bic_change": c.records_bic_change,
                            "accepted": c.accepted, "verdict": c.verdict}
                           for c in s.candidates]})
    records = []
    for i, r in enumerate(d.records):
        init, fin = d.fits[0].rms_records[i], final.rms_records[i]
        records.append({
            "trace": str(r.trace.stem), "name": r.name, "experiment": r.trace.experiment,
            "measured_column": r.trace.measured_column, "samples": r.n,
            "noise_estimate": r.sigma, "noise_method": r.noise.method,
            "rmse_initial": init, "rmse_final": fin,
            "rmse_initial_over_noise": init / r.sigma, "rmse_final_over_noise": fin / r.sigma,
            "heldout_from_s": float(r.trace.time[r.first]),
            "steps": [{"effect": s.effect, "rmse_before": s.records_before[i],
                       "rmse_after": None if s.records_after is None else s.records_after[i],
                       "revealed": r.name in s.revealed_by} for s in d.steps if s.effect],
            "revealed": effects_added([s for s in d.steps if s.effect and r.name in s.revealed_by], final.effects),
            "effects": _record_verdicts(d, i, campaign),
            "nuisance": {n: {"stated": v_stated, "value": float(final.nz[i][n])}
                         for n, v_stated in _stated(r).items() if n in final.nz[i]},
            "contradicting": any(c["name"] == r.name for c in d.contradicting),
            "alone": d.alone.get(r.name),
        })
    final_params = {"model": final.model, "parameters": {k: float(v) for k, v in final.params.items()}}
    return {
        "format": "tether-campaign-discovery/1",
        "traces": [str(r.trace.stem) for r in d.records],
        "start_model": d.start_model,
        "added_effects": d.added_effects,
        "final_model": final.model,
        "rmse_initial_over_noise": d.fits[0].rms,
        "rmse_final_over_noise": final.rms,
        "effects": campaign,
        "steps": steps,
        "removals": [{"effect": x.effect, "model_before": x.model_before, "model_after": x.model_after,
                      "rmse_before_over_noise": x.rms_before, "rmse_after_over_noise": x.rms_after, "reason": x.reason}
                     for x in d.removals],
        "refinements": [x.as_dict(1.0) for x in d.refinements],   # errors in noise units (the campaign's)
        "records": records,
        "contradicting": d.contradicting,
        "stop_reason": d.stop_reason,
        "seconds": d.seconds,
        "final_params": final_params,
        "model": final_params["model"],
        "parameters": final_params["parameters"],
    }


def _stated(r: Record) -> dict:
    from .. import nuisance as NZ

    return NZ.stated_values(r.trace)


def campaign_account(d: CampaignDiscovery) -> str:
    """A short account for the terminal."""
    lines = [f"campaign of {len(d.records)} records, start {d.start_model}:"]
    for i, r in enumerate(d.records):
        lines.append(f"  {r.name} ({r.trace.experiment}): noise {r.sigma:.3g} m, RMS error "
                     f"{d.fits[0].rms_records[i] / r.sigma:.2f} -> {d.final.rms_records[i] / r.sigma:.2f} x noise")
    for k, s in enumerate([s for s in d.steps if s.effect], 1):
        lines.append(f"{k}. {s.effect}: campaign RMS error {s.rms_before:.2f} -> {s.rms_after:.2f} x noise (model "
                     f"{s.model_after}); revealed by {', '.join(s.revealed_by)}")
    for x in d.removals:
        lines.append(f"removed {x.effect}: {x.reason}")
    for c in d.contradicting:
        lines.append(f"contradicting record {c['name']}: {c['why']}")
    lines.append(f"stopped: {d.stop_reason}")
    lines.append(f"discovered: {', '.join(d.added_effects) or 'nothing'}; final model {d.final.model}, campaign RMS "
                 f"error {d.final.rms:.2f} x noise ({d.seconds:.1f} s)")
    return "\n".join(lines)
