"""The last stage: the shape terms of the named laws (SHAPE_TERMS), freed one group at a time."""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ..traces import Trace
from .fitting import _heldout, _side_by_side, ModelFit
from .judge import CRITERIA, _shape_heldout_asked, _shape_judged, bic_change
from .laws import _law_of, SHAPE_TERMS
from .records import Refinement
from .scales import _Scales
from .starts import _damping_table_start, _shape_start


def _knots_unseen(part: Trace, extra: Sequence[str], starts: Sequence[dict | None]) -> tuple:
    """The damping table's knots beyond the displacements of the record's first part: a fit of the
    part cannot see them, yet a knot just past its reach still moves the cubic's slope inside it,
    and freed there it took values that wrecked the prediction of the held-out part (forced multisine,
    Gaussian c(x): whole record 1.00 x noise, held-out 7.7 x against 3.3 x without the table). They
    stay at the whole record's values, as the unseen knots of a straight-line table did."""
    knots = [k for k in extra if k.startswith("c_table_") and k != "c_table_dx"]
    dx = float((starts[0] or {}).get("c_table_dx", 0.0)) if starts else 0.0
    if not knots or not dx > 0 or part.rig != "payload":
        return ()
    reach = float(np.max(np.abs(np.asarray(part.measured, float))))
    return tuple(k for k in knots if int(k.rsplit("_", 1)[1]) * dx > reach)


def shape_starts(trace: Trace, spec, params: dict, group: Sequence[str], sc: _Scales) -> list[dict]:
    """Starts of a fit with the shape terms ``group`` free from the model ``spec`` at ``params``: the
    model as it is (starts._shape_start) and, for the damping table, the table of the equation
    error beside it (starts._damping_table_start)."""
    flat = _shape_start(params, group, sc)
    if not any(g.startswith("c_table_") for g in group):
        return [flat]
    ee = _damping_table_start(trace, spec, params, flat["c_table_dx"])
    return [flat] if ee is None else [flat, {**flat, **ee}]


def _shape_groups(cur: ModelFit, skip=frozenset()) -> list:
    """(effect, group) of the shape terms of the named laws (SHAPE_TERMS), less the effects in skip."""
    return [(e, g) for e in cur.effects if e not in skip for g in SHAPE_TERMS.get((e, _law_of(cur.spec, e)), ())]


def refine_shapes(trace: Trace, part: Trace, held_out: np.ndarray, cur: ModelFit, cur_held: float, sigma: float, fit,
                  sc: _Scales, say: Callable[[str], None], skip=frozenset()):
    """The last stage: the effects are named; where the model still misses the record, free the
    shape terms of a named effect's law (SHAPE_TERMS), one group at a time from the final model.
    A group is kept when it lowers the BIC on the whole record and does not worsen the prediction
    of the held-out part by a fit to the first part (asked only where that prediction can judge:
    CRITERIA.shape_heldout_informative); the best such group wins. ``skip``: effects whose law was refined
    before. Returns the model (refined or not), its held-out error and the Refinement records."""
    n = len(trace.time)
    groups = [(e, g) for e, g in _shape_groups(cur, skip) if not set(g) <= set(cur.shape)]
    if cur.rms <= CRITERIA.within_noise * sigma or not groups:
        return cur, cur_held, []
    out, best = [], None
    # the groups' fits are independent: side by side
    group_fits = _side_by_side(lambda eg, alone: fit(trace, cur.spec, cur.effects,
                                                     shape_starts(trace, cur.spec, cur.params, eg[1], sc), extra=eg[1],
                                                     own_thread=alone), groups)
    bics = [bic_change(cur, fm, n) for fm in group_fits]
    # the held-out fits of the groups that lower the BIC, where that prediction can judge: side by side
    asked = [i for i, fm in enumerate(group_fits) if fm.ok and bics[i] < 0.0 and fm.rms < cur.rms
             and _shape_heldout_asked(cur.rms, cur_held, fm.rms, sigma)]
    part_fits = dict(zip(asked, _side_by_side(
        lambda i, alone: fit(part, cur.spec, cur.effects, [group_fits[i].params], extra=groups[i][1],
                             own_thread=alone), asked)))
    for i, ((effect, group), fm) in enumerate(zip(groups, group_fits)):
        if not fm.ok:
            out.append(Refinement(effect, group, cur.rms, float("inf"), cur_held, float("nan"), float("inf"), False,
                                  f"the fit failed: {fm.message}"))
            say(f"  shape of {effect} ({' '.join(group)}): not kept: the fit failed: {fm.message}")
            continue
        bic = bics[i]
        held = float("nan")
        if i in part_fits:
            pf = part_fits[i]
            held = _heldout(trace, cur.spec, pf.params, held_out) if pf.ok else float("inf")
        ok, verdict = _shape_judged(cur.rms, fm.rms, bic, cur_held, held, sigma,
                                    f"BIC changes by {bic:+.1f}: the terms do not earn their place")
        r = Refinement(effect, tuple(group), cur.rms, fm.rms, cur_held, held, bic, ok, verdict,
                       {k: float(fm.params[k]) for k in group})
        out.append(r)
        say(f"  shape of {effect} ({' '.join(group)}): {'kept' if ok else 'not kept'}: {verdict}")
        if ok and (best is None or bic < best[0].bic_change):
            best = (r, fm)
    if best is None:
        return cur, cur_held, out
    for r in out:                               # one group wins; the others stay on record as tried
        if r.accepted and r is not best[0]:
            r.accepted = False
            r.verdict += f"; {' '.join(best[0].parameters)} did better"
    return best[1], best[0].heldout_after, out
