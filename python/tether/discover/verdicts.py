"""The verdict on every effect of the vocabulary (OUT.json's ``effects``) and what the final model
leaves unexplained (``unexplained``), read from what a run recorded: its steps, their candidates
and re-tests, and the final model. No fit is run here. docs/discovery.md, "Verdicts", gives the
rules."""

from __future__ import annotations

import math

from ..models import EFFECTS, parse_model
from .evidence import disagreement, lowest_elongation, regimes, slack_reach
from .judge import CRITERIA, _gap, leaves_unexplained
from .laws import unrevealed
from .records import Discovery, Retest


def bic_weight(bic_change: float) -> float | None:
    """How strongly the data prefer the model with an effect to the one without it, from the BIC
    change with it: 1 / (1 + exp(dBIC / 2)), the posterior weight of the two models under equal
    prior odds; 0.5 where the BIC does not tell them apart. None where no change was computed."""
    if bic_change is None or math.isnan(bic_change):
        return None
    x = 0.5 * bic_change
    if x > 700.0:
        return 0.0
    return 1.0 / (1.0 + math.exp(x))


def _verdict(verdict: str, evidence: str, bic_change: float | None = None) -> dict:
    return {"verdict": verdict, "weight": bic_weight(bic_change), "evidence": evidence}


def _tests_of(d: Discovery, effect: str) -> list:
    """The effect's tests in the order they ran: (step number, step, candidate or Retest), one
    candidate per step (of two laws, the accepted or the lower BIC)."""
    out = []
    for k, st in enumerate(d.steps, 1):
        own = [c for c in st.candidates if c.effect == effect]
        if own:
            out.append((k, st, min(own, key=lambda c: (not c.accepted, c.bic_change))))
        out += [(k, st, r) for r in st.retests if r.effect == effect]
    return out


def _beside(d: Discovery, k: int, r: Retest) -> str:
    """What a re-test of step k was run beside: the step's new effect, or what the Retest says."""
    return r.beside or d.steps[k - 1].effect


def _within_noise(d: Discovery) -> bool:
    return d.final.rms <= CRITERIA.within_noise * d.noise.sigma


def _present(d: Discovery, effect: str, base: tuple) -> dict:
    if effect in base:
        return _verdict("present", f"in the start model {d.start_model}: assumed, not tested")
    k, st = next((k, st) for k, st in reversed(list(enumerate(d.steps, 1))) if st.effect == effect)
    win = next((c for c in st.candidates if c.effect == effect and c.accepted), None)
    if win is None:                             # (a record without its candidates: the step's evidence)
        text, bic = f"added in step {k} ({st.model_before} -> {st.model_after}): {st.evidence}", None
    else:
        text, bic = f"added in step {k} ({st.model_before} -> {st.model_after}): {win.verdict}", win.bic_change
    for j, _, r in _tests_of(d, effect):
        if j > k and isinstance(r, Retest):
            text += f"; tested again in step {j} beside {_beside(d, j, r)}, kept: {r.verdict}"
            bic = r.bic_change
    return _verdict("present", text, bic)


def _never_tested(d: Discovery, effect: str) -> dict:
    if _within_noise(d):
        return _verdict("absent", f"not fitted: the model {d.final.model} reproduces the record within the noise "
                                  f"({d.final.rms / d.noise.sigma:.2f} x noise) without it, nothing is left for it "
                                  "to explain")
    return _verdict("undetermined", f"never tested: {d.stop_reason}")


def _outranked(d: Discovery, effect: str, k: int, c) -> dict:
    passed = f"set aside in step {k} for {c.outranked_by}: {c.verdict}"
    if _within_noise(d):
        return _verdict("absent", f"{passed}; beside {c.outranked_by} the model reproduces the record within the noise "
                                  f"({d.final.rms / d.noise.sigma:.2f} x noise), nothing is left for {effect}")
    return _verdict("undetermined", f"{passed}, and it was not tested again: {d.stop_reason}")


def _last_test(d: Discovery, effect: str) -> dict:
    """An effect the record can reveal and the final model lacks: from its last test."""
    tests = _tests_of(d, effect)
    if not tests:
        return _never_tested(d, effect)
    k, st, t = tests[-1]
    if isinstance(t, Retest) and not t.kept:    # named earlier, removed in step k
        return _verdict("absent", f"named in an earlier step, removed in step {k} beside {_beside(d, k, t)}: "
                                  f"{t.verdict}", t.bic_change)
    if isinstance(t, Retest):
        return _verdict("undetermined", f"kept when tested again in step {k}, but not in the final model "
                                        f"{d.final.model}")
    if st.cut_short:
        return _verdict("undetermined", f"its fit in step {k} was not judged to the end: {d.stop_reason}")
    if not math.isfinite(t.bic_change):
        return _verdict("undetermined", f"its fit in step {k} did not finish ({t.verdict})" + _earlier(d, effect, k))
    if t.tied_with:
        return _verdict("undetermined", f"in step {k} it passes, and {t.tied_with} does as well: the record does not "
                                        f"tell the two apart ({t.verdict})", t.bic_change)
    if t.outranked_by:
        return _outranked(d, effect, k, t)
    return _verdict("absent", f"refused in step {k} (the model {t.label}: RMS error {t.rms / d.noise.sigma:.2f} x "
                              f"noise, from {st.rms_before / d.noise.sigma:.2f}): {t.verdict}" + _at_the_noise(d),
                    t.bic_change)


def _at_the_noise(d: Discovery) -> str:
    """'' or, where the final model reproduces the record within the noise, that it does so without
    the effect (a refusal beside fewer effects is then confirmed by the final model)."""
    if not _within_noise(d):
        return ""
    return f"; the final model {d.final.model} reproduces the record within the noise without it " \
           f"({d.final.rms / d.noise.sigma:.2f} x noise)"


def _earlier(d: Discovery, effect: str, k: int) -> str:
    """The effect's last test before step k whose fit finished, in words ('' where none)."""
    done = [(j, c) for j, _, c in _tests_of(d, effect) if j < k and math.isfinite(c.bic_change)]
    if not done:
        return ""
    j, c = done[-1]
    return f"; in step {j}, beside fewer effects: {c.verdict}"


def _slack_out_of_reach(d: Discovery) -> str | None:
    """Why this record cannot reveal slack: it never goes below the slack threshold of the final
    model; None where it does, or where the model gives no threshold."""
    lowest, ub = lowest_elongation(d.trace, d.final)
    if ub is None or lowest + ub < 0:
        return None
    return f"{slack_reach(d.trace, d.final)}: slack cannot act in this record"


def effect_verdicts(d: Discovery) -> dict[str, dict]:
    """Every effect of the vocabulary -> {"verdict": "present" | "absent" | "undetermined",
    "weight": the BIC weight of its last decisive test (bic_weight) or None, "evidence": why}."""
    base = tuple(parse_model(d.start_model, d.trace.experiment).effects)
    out = {}
    for e in EFFECTS:
        if e in d.final.effects:
            out[e] = _present(d, e, base)
        elif (why := unrevealed(d.trace, e)) is not None:
            out[e] = _verdict("undetermined", why)
        elif e == "slack" and (why := _slack_out_of_reach(d)) is not None:
            out[e] = _verdict("undetermined", why)
        else:
            out[e] = _last_test(d, e)
    return out


def unexplained(d: Discovery) -> dict | None:
    """Where the final model misses the record by CRITERIA.unexplained_gap sigma or more: the gap,
    as rmse_final / noise, and in words where it is largest and why the search stopped; else None."""
    sigma, final = d.noise.sigma, d.final
    if not leaves_unexplained(final.rms, sigma):
        return None
    gap = _gap(final.rms, sigma)
    windows = sorted(disagreement(d.trace, final, sigma, regimes(d.trace, final)), key=lambda w: -w.share)[:2]
    where = "; the residual is largest in " + ", ".join(
        f"{w.start:.4g}-{w.end:.4g} s ({', '.join(w.regimes) or 'no single regime'})" for w in windows) if windows else ""
    return {"gap_noise": final.rms / sigma,
            "text": f"the final model {final.model} misses the record at {final.rms / sigma:.2f} x noise, a gap of "
                    f"{gap / sigma:.2f} sigma above the noise (unexplained from {CRITERIA.unexplained_gap:g} sigma): "
                    f"the record shows something this model's effects and laws do not explain{where}; the search "
                    f"stopped: {d.stop_reason}"}


def verdict_lines(effects: dict, unexplained_: dict | None) -> list[str]:
    """The verdicts and the unexplained part, for the terminal."""
    lines = ["effects (weight: how strongly the data prefer the model with it, from the BIC):"]
    for e, v in effects.items():
        w = "  - " if v["weight"] is None else f"{v['weight']:.2f}"
        lines.append(f"  {e:<20} {v['verdict']:<12} {w}  {v['evidence']}")
    if unexplained_ is not None:
        lines.append(f"unexplained: {unexplained_['text']}")
    return lines
