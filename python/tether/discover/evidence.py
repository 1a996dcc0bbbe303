"""Where and how the model disagrees with the record: the regimes, the windows of disagreement,
the regime table and the signatures each effect leaves in the residual."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..traces import Trace
from .fitting import ModelFit
from .laws import CANDIDATES
from .samples import true_runs


@dataclass
class Window:
    start: float                  # [s]
    end: float
    rms: float                    # RMS residual in the window (measured unit)
    share: float                  # share of the record's excess squared residual (above the noise)
    regimes: list                 # regimes that cover most of the window

    def as_dict(self) -> dict:
        return {"start_s": self.start, "end_s": self.end, "rms": self.rms, "rms_over_noise": None,
                "share_of_excess": self.share, "regimes": list(self.regimes)}


def _moving_mean(v: np.ndarray, w: int) -> np.ndarray:
    w = max(1, min(int(w), len(v)))
    c = np.concatenate([[0.0], np.cumsum(v)])
    out = np.empty(len(v))
    h = w // 2
    for_i = np.arange(len(v))
    lo = np.clip(for_i - h, 0, len(v))
    hi = np.clip(for_i - h + w, 0, len(v))
    out[:] = (c[hi] - c[lo]) / np.maximum(hi - lo, 1)
    return out


def running_max(v: np.ndarray, w: int) -> np.ndarray:
    """out[i] = max(v[i - w//2 : i - w//2 + w]) clipped to the array (scipy.ndimage's
    maximum_filter1d, mode 'reflect', exactly), in O(n) by prefix and suffix maxima of blocks of w."""
    v = np.asarray(v, float)
    n, w = len(v), max(1, int(w))
    m = -(-(n + w) // w)
    pad = np.full(m * w, -np.inf)
    pad[w // 2:w // 2 + n] = v
    blocks = pad.reshape(m, w)
    prefix = np.maximum.accumulate(blocks, axis=1).ravel()
    suffix = np.maximum.accumulate(blocks[:, ::-1], axis=1)[:, ::-1].ravel()
    # padded window [i, i + w - 1]: the end of one block and the start of the next
    i = np.arange(n)
    return np.maximum(suffix[i], prefix[i + w - 1])


def _window_length(trace: Trace) -> int:
    """Samples in a disagreement window: about one period of the response (payload rig), or 1 %
    of the record with at least 20 samples (load rig)."""
    n = len(trace.time)
    if trace.rig == "payload":
        from ..fit.kinematics import dominant_frequency as fdom

        f = fdom(np.asarray(trace.time, float), np.asarray(trace.measured, float))
        dt = float(np.median(np.diff(trace.time)))
        return int(min(max(1.0 / (f * dt), 20), n / 4))
    return int(min(max(0.01 * n, 20), n / 4))


def regimes(trace: Trace, fit: ModelFit | None = None) -> dict[str, np.ndarray]:
    """Boolean masks of the regimes of the record.

    Payload rig: ``loading`` (the tether stretches, x' > 0) and ``unloading``; ``large amplitude``
    (the local swing is more than half the record's largest) and ``small amplitude``; ``slack``
    (the elongation u_b + x, with the current model's balance stretch u_b, is below zero).
    Load rig: ``loading`` / ``unloading`` (the load rises / falls), ``hold`` (the load stays put
    for at least 2 % of the record), ``high load`` (above half the largest) and ``low load``."""
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    n = len(t)
    w = _window_length(trace)
    out: dict[str, np.ndarray] = {}
    if trace.rig == "payload":
        ys = _moving_mean(y, max(3, w // 12))
        v = np.gradient(ys, t)
        out["loading"] = v > 0
        out["unloading"] = v < 0
        dev = np.abs(y - np.median(y))
        env = running_max(dev, max(3, w))
        out["large amplitude"] = env > 0.5 * env.max()
        out["small amplitude"] = ~out["large amplitude"]
        ub = None
        if fit is not None and fit.params and float(trace.gravity_m_s2) > 0:
            ub = balance_elongation(trace, fit)
        out["slack"] = (y + ub < 0) if ub is not None else np.zeros(n, bool)
    else:
        T = np.asarray(trace.input, float)
        dT = np.gradient(T, t)
        scale = max(float(np.max(np.abs(dT))), 1e-300)
        moving = np.abs(dT) > 1e-3 * scale
        out["loading"] = dT > 1e-3 * scale
        out["unloading"] = dT < -1e-3 * scale
        hold = ~moving
        # only holds that last: runs of at least 2 % of the record's duration
        min_len = 0.02 * (t[-1] - t[0])
        long_hold = np.zeros(n, bool)
        for a, b in true_runs(hold):
            if t[b - 1] - t[a] >= min_len:
                long_hold[a:b] = True
        out["hold"] = long_hold
        out["high load"] = T > 0.5 * T.max()
        out["low load"] = ~out["high load"]
    return out


def balance_elongation(trace: Trace, fit: ModelFit) -> float | None:
    """The model's static stretch under the payload's weight (payload rig)."""
    m, g, L0 = float(trace.payload_mass_kg), float(trace.gravity_m_s2), float(trace.length_m)
    W = m * g - float(fit.params.get("z0", 0.0) if fit.spec.hysteresis == "boucwen" else 0.0)
    p = fit.params
    if fit.spec.hysteresis == "kawabata":
        pe = 2.0 / p["kaw_LT"] - 1.0
        return L0 * p["kaw_eps_ref"] * (W / p["kaw_F_ref"]) ** (1.0 / pe) if W > 0 else 0.0
    if fit.spec.stiffness == "cubic":
        from ..fit.elastic import cubic_inverse, cubic_tension
        e = float(cubic_inverse(p)(W)) if W > 0 else 0.0
        return L0 * e if W <= 0 or abs(float(cubic_tension(p, e)) - W) <= 1e-6 * W else None
    if fit.spec.stiffness == "exponential":
        from ..fit.elastic import elastic_inverse
        return L0 * float(elastic_inverse("exponential", p)(W)) if W > -p["exp_F"] else None
    if fit.spec.stiffness == "bilinear":
        from ..fit.elastic import elastic_inverse
        return L0 * float(elastic_inverse("bilinear", p)(W))
    return L0 * W / p["EA"] if p.get("EA") else None


def lowest_elongation(trace: Trace, fit: ModelFit) -> tuple[float, float | None]:
    """Payload rig: the lowest measured displacement [m] and the model's balance stretch u_b (None
    where the model gives none): the tether goes slack where the displacement is below -u_b, the
    same test as the ``slack`` regime of :func:`regimes`."""
    lowest = float(np.min(np.asarray(trace.measured, float)))
    if not fit.params or not float(trace.gravity_m_s2) > 0:
        return lowest, None
    return lowest, balance_elongation(trace, fit)


def slack_reach(trace: Trace, fit: ModelFit) -> str:
    """What the record measures against the slack threshold, in words: the lowest displacement, the
    threshold -u_b of ``fit`` and the lowest elongation u_b + min(x)."""
    lowest, ub = lowest_elongation(trace, fit)
    if ub is None:
        return (f"the measured displacement reaches down to {lowest:.4g} m; the model {fit.model} gives no balance "
                f"stretch under the payload's weight, so where the tether would go slack is not known")
    goes = "goes" if lowest + ub < 0 else "never goes"
    return (f"the measured displacement reaches down to {lowest:.4g} m; with the balance stretch {ub:.4g} m of "
            f"the model {fit.model} the tether goes slack below {-ub:.4g} m, and the record {goes} below it "
            f"(lowest elongation {lowest + ub:+.4g} m)")


def disagreement(trace: Trace, fit: ModelFit, sigma: float, masks: dict | None = None) -> list[Window]:
    """Time windows where the local RMS residual (over about one response period, or 1 % of a load
    test) stands above the noise (above sigma * sqrt(1 + 4 sqrt(2/w)), where pure noise rarely gets,
    and at least 1.2 sigma) and above a third of its largest value."""
    t = np.asarray(trace.time, float)
    r = np.asarray(fit.predicted - trace.measured, float)
    w = _window_length(trace)
    ms = _moving_mean(r ** 2, w)
    thr = sigma ** 2 * max(1.0 + 4.0 * math.sqrt(2.0 / w), 1.44)
    # where the disagreement is: above the noise, and not far below its worst (a local RMS above a
    # third of the largest), so that a residual above the noise everywhere still shows where it peaks
    flag = ms > max(thr, 0.1 * float(np.max(ms)))
    masks = masks if masks is not None else regimes(trace, fit)
    excess_total = float(np.sum(np.maximum(r ** 2 - sigma ** 2, 0.0))) or 1e-300
    runs = true_runs(flag)
    merged: list[list[int]] = []
    for a, b in runs:                      # close gaps shorter than a window
        if merged and a - merged[-1][1] < w:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    out = []
    for a, b in merged:
        if b - a < max(3, w // 2):
            continue
        seg = slice(a, b)
        rr = r[seg]
        share = float(np.sum(np.maximum(rr ** 2 - sigma ** 2, 0.0))) / excess_total
        cover = []
        for name, mk in masks.items():
            frac = float(np.mean(mk[seg]))
            if frac >= 0.5 and name not in ("loading", "unloading"):
                cover.append(name)
        # loading / unloading: where the excess lies
        e = np.maximum(rr ** 2 - sigma ** 2, 0.0)
        tot = float(e.sum()) or 1e-300
        for name in ("loading", "unloading"):
            if name in masks and float(e[masks[name][seg]].sum()) / tot >= 0.7:
                cover.append(name)
        out.append(Window(float(t[a]), float(t[b - 1]), float(np.sqrt(np.mean(rr ** 2))), share, cover))
    return out


def regime_table(trace: Trace, fit: ModelFit, sigma: float, masks: dict) -> dict:
    """Per regime: share of the samples, RMS residual / noise, and share of the excess residual."""
    r = np.asarray(fit.predicted - trace.measured, float)
    e = np.maximum(r ** 2 - sigma ** 2, 0.0)
    tot = float(e.sum()) or 1e-300
    out = {}
    for name, mk in masks.items():
        if not mk.any():
            continue
        out[name] = {"samples": float(np.mean(mk)), "rms_over_noise": float(np.sqrt(np.mean(r[mk] ** 2)) / sigma),
                     "share_of_excess": float(e[mk].sum()) / tot}
    return out


def _branch_split(level: np.ndarray, r: np.ndarray, up: np.ndarray, down: np.ndarray, bins: int = 20):
    """Mean residual per level bin on the rising and the falling branch: the share of the residual
    energy that is common to both (a function of the level: a static law) and the share that
    differs between them (a loop: hysteresis)."""
    tot = float(np.sum(r ** 2)) or 1e-300
    sel = up | down
    if sel.sum() < 2 * bins:
        return 0.0, 0.0
    edges = np.quantile(level[sel], np.linspace(0, 1, bins + 1))
    idx = np.clip(np.searchsorted(edges, level, side="right") - 1, 0, bins - 1)
    common = diff = 0.0
    for b in range(bins):
        iu = (idx == b) & up
        idn_ = (idx == b) & down
        if iu.sum() < 2 or idn_.sum() < 2:
            continue
        mu, md = float(np.mean(r[iu])), float(np.mean(r[idn_]))
        n = int(iu.sum() + idn_.sum())
        common += n * (0.5 * (mu + md)) ** 2
        diff += n * (0.5 * (mu - md)) ** 2
    return common / tot, diff / tot


def _phase_amplitude(trace: Trace, fit: ModelFit, w: int):
    """Payload rig: the residual in each window of about one period split into an amplitude error
    (along the predicted displacement) and a phase error (along the predicted velocity); shares of
    the residual energy."""
    t = np.asarray(trace.time, float)
    x = np.asarray(fit.predicted, float)
    v = np.gradient(x, t)
    r = np.asarray(fit.predicted - trace.measured, float)
    tot = float(np.sum(r ** 2)) or 1e-300
    amp = ph = 0.0
    for a in range(0, len(t) - w + 1, w):
        s = slice(a, a + w)
        X = np.column_stack([x[s] - np.mean(x[s]), v[s]])
        if not np.all(np.isfinite(X)) or np.linalg.matrix_rank(X) < 2:
            continue
        c, *_ = np.linalg.lstsq(X, r[s], rcond=None)
        amp += float(np.sum((c[0] * X[:, 0]) ** 2))
        ph += float(np.sum((c[1] * X[:, 1]) ** 2))
    return amp / tot, ph / tot


def signatures(trace: Trace, fit: ModelFit, sigma: float, masks: dict) -> dict[str, dict]:
    """For each candidate effect of the experiment, a score in [0, 1] (how much of the residual has
    the shape that effect leaves) and one line saying what was measured."""
    r = np.asarray(fit.predicted - trace.measured, float)
    excess = np.maximum(r ** 2 - sigma ** 2, 0.0)
    ex_tot = float(excess.sum()) or 1e-300
    out: dict[str, dict] = {}
    cands = CANDIDATES[trace.experiment]
    if trace.rig == "payload":
        w = _window_length(trace)
        amp, ph = _phase_amplitude(trace, fit, w)
        big = masks["large amplitude"]
        big_share = float(excess[big].sum()) / ex_tot
        big_frac = float(np.mean(big))
        out["nonlinear_stiffness"] = {
            "score": ph, "text": f"{100 * ph:.0f} % of the residual is a phase (frequency) error, period by period"}
        out["nonlinear_damping"] = {
            "score": amp * min(1.0, big_share / max(big_frac, 1e-9) / 2.0 + 0.5),
            "text": f"{100 * amp:.0f} % of the residual is an amplitude (decay) error; the large-amplitude part of "
                    f"the record ({100 * big_frac:.0f} % of it) holds {100 * big_share:.0f} % of the excess"}
        out["hysteresis"] = {
            "score": 2.0 * min(amp, ph),
            "text": f"both an amplitude ({100 * amp:.0f} %) and a phase ({100 * ph:.0f} %) error: stiffness and "
                    f"damping that change with amplitude"}
        sl = masks.get("slack")
        if sl is not None and sl.any():
            share = float(excess[sl].sum()) / ex_tot
            out["slack"] = {"score": share,
                            "text": f"the measured elongation (balance stretch {balance_elongation(trace, fit):.4g} m "
                                    f"plus displacement) is below zero in {100 * np.mean(sl):.1f} % of the record, "
                                    f"which holds {100 * share:.0f} % of the excess residual ({slack_reach(trace, fit)})"}
        else:
            out["slack"] = {"score": 0.0, "text": f"{slack_reach(trace, fit)}: nothing in the record shows a slack tether"}
    else:
        T = np.asarray(trace.input, float)
        common, diff = _branch_split(T, r, masks["loading"], masks["unloading"])
        hold = masks["hold"]
        # within holds: the share of the residual that is a drift in time (a line per hold)
        drift = 0.0
        if hold.any():
            t = np.asarray(trace.time, float)
            tot = float(np.sum(r ** 2)) or 1e-300
            level = 0.0
            for a, b in true_runs(hold):
                if b - a < 5:
                    continue
                X = np.column_stack([np.ones(b - a), t[a:b] - t[a]])
                c, *_ = np.linalg.lstsq(X, r[a:b], rcond=None)
                drift += float(np.sum((c[1] * X[:, 1] - np.mean(c[1] * X[:, 1])) ** 2)) / tot
                level += float((b - a) * c[0] ** 2) / tot
            hold_share = float(excess[hold].sum()) / ex_tot
            out["creep"] = {"score": drift,
                            "text": f"{100 * drift:.0f} % of the residual is a drift in time while the load is held "
                                    f"(holds: {100 * np.mean(hold):.0f} % of the record, {100 * hold_share:.0f} % of "
                                    f"the excess)"}
            if trace.experiment == "creep":
                common = max(common, min(level, 1.0))
        else:
            out["creep"] = {"score": 0.0, "text": "no long hold of the load: a drift in time would show only as a "
                                                  "lag between loading and unloading"}
        out["nonlinear_stiffness"] = {
            "score": common, "text": f"{100 * common:.0f} % of the residual is the same function of the load on "
                                     f"loading and unloading (a static law)"}
        out["hysteresis"] = {
            "score": diff, "text": f"{100 * diff:.0f} % of the residual differs between loading and unloading at "
                                   f"the same load (a loop)"}
    return {k: v for k, v in out.items() if k in cands}
