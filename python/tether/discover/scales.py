"""The record's scales (stiffness, amplitude, strain, force, longest hold), for the starts of added terms."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..traces import Trace


@dataclass
class _Scales:
    L0: float
    ea: float              # EA of the linear baseline, first guess [N]
    k: float               # stiffness EA/L0 [N/m]
    amp: float             # typical displacement / elongation change [m]
    eps: float             # typical strain (at balance, or at the largest load)
    force: float           # typical hysteretic force scale [N]: k*amp (payload) or the largest load
    rig: str
    hold: float = 0.0      # longest time the load stays put [s] (load rig; 0 for the payload rig)
    omega: float = 0.0     # natural angular frequency sqrt(k/m) [rad/s] (payload rig; 0 for the load rig)


def _longest_hold(t: np.ndarray, load: np.ndarray) -> float:
    """The longest stretch of the record over which the load does not move (by 0.1 % of its
    largest value between two samples)."""
    top = float(np.max(np.abs(load))) if len(load) else 0.0
    if len(t) < 2 or not top > 0:
        return 0.0
    moves = np.nonzero(np.abs(np.diff(load)) > 1e-3 * top)[0]
    edges = np.unique(np.concatenate([[0], moves, moves + 1, [len(t) - 1]]))
    return float(np.max(np.diff(t[edges])))


def _scales(trace: Trace) -> _Scales:
    from ..fit import initial_estimate

    L0 = float(trace.length_m)
    y = np.asarray(trace.measured, float)
    est = initial_estimate([trace], "linear")
    if trace.rig == "load":
        ea = float(est.get("EA", 0.0)) or 1e3
        Tmax = max(float(np.max(trace.input)), 1e-6)
        return _Scales(L0=L0, ea=ea, k=ea / L0, amp=max(float(np.ptp(y)), 1e-9),
                       eps=max(Tmax / ea, 1e-9), force=Tmax, rig="load",
                       hold=_longest_hold(np.asarray(trace.time, float), np.asarray(trace.input, float)))
    k = float(est.get("_k_lin", 0.0)) or float(est.get("EA", 1e3)) / L0
    amp = float(est.get("_amp", 0.0)) or max(float(np.max(np.abs(y))), 1e-9)
    m, g = float(trace.payload_mass_kg), float(trace.gravity_m_s2)
    eps = (m * g / k) / L0 if g > 0 else amp / L0
    return _Scales(L0=L0, ea=k * L0, k=k, amp=amp, eps=max(eps, 1e-9), force=max(k * amp, 1e-9), rig="payload",
                   omega=math.sqrt(k / m) if m > 0 else 0.0)
