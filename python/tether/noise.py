"""The measurement noise, estimated from the measured column alone (never from a fit): the one
estimator of `tether fit` (its weights and report) and `tether discover` (its scale for every gap)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .traces import Trace


def _divided_difference_weights(ts: np.ndarray, k: int) -> np.ndarray:
    """For each run of k+1 consecutive samples, the weights of the k-th divided difference (they
    annihilate every polynomial of degree < k, on any time grid), scaled to unit Euclidean norm
    so that white noise of standard deviation s gives differences of standard deviation s."""
    m = len(ts) - k
    W = np.ones((m, k + 1))
    for j in range(k + 1):
        for i in range(k + 1):
            if i != j:
                W[:, j] /= ts[j:j + m] - ts[i:i + m]
    W /= np.linalg.norm(W, axis=1, keepdims=True)
    return W


def _robust_std(d: np.ndarray) -> float:
    """Standard deviation of the bulk of d: MAD first, then the RMS of what lies within 4 MADs
    (outliers such as load steps, slack kinks or impacts do not count)."""
    d = d - np.median(d)
    s = 1.4826 * float(np.median(np.abs(d)))
    if s == 0.0:
        return 0.0
    keep = np.abs(d) < 4.0 * s
    return float(np.sqrt(np.mean(d[keep] ** 2)) / 0.99931)     # 4-sigma truncation of a Gaussian


@dataclass
class NoiseEstimate:
    sigma: float
    method: str
    by_order: list = field(default_factory=list)   # divided differences: the estimate for k = 1..8

    def as_dict(self) -> dict:
        return {"sigma": self.sigma, "method": self.method,
                **({"by_order": self.by_order} if self.by_order else {})}


def estimate_noise(trace: Trace, kmax: int = 8) -> NoiseEstimate:
    """The standard deviation of the measurement noise, from the measured column alone.

    A periodic record (``periodic_samples`` with two periods or more): the differences between
    consecutive periods hold the noise only (divided by sqrt 2). Otherwise: the k-th divided
    differences of the measured column on its own time grid (k = 1..8), scaled to unit gain for
    white noise; a smooth signal contributes less the higher k until the noise dominates. The
    estimate is the mean of the orders within 5 % of the smallest (robust scale of each).
    """
    y = np.asarray(trace.measured, float)
    P = int(trace.periodic_samples or 0)
    if P and len(y) >= 2 * P:
        per = y[: (len(y) // P) * P].reshape(-1, P)
        d = (per[1:] - per[:-1]).ravel() / math.sqrt(2.0)
        return NoiseEstimate(_robust_std(d), f"differences between the {per.shape[0]} periods of the record")
    t = np.asarray(trace.time, float)
    ts = (t - t[0]) / float(np.median(np.diff(t)))
    ests = []
    for k in range(1, min(kmax, len(y) - 2) + 1):
        W = _divided_difference_weights(ts, k)
        m = len(y) - k
        d = np.zeros(m)
        for j in range(k + 1):
            d += W[:, j] * y[j:j + m]
        ests.append(_robust_std(d))
    e = np.array(ests)
    lo = float(e.min())
    sigma = float(np.mean(e[e <= 1.05 * lo]))
    return NoiseEstimate(sigma, "divided differences of orders 1-8 of the measured column (robust scale)",
                         [float(v) for v in e])


def noise_level(trace: Trace) -> float:
    """estimate_noise's sigma, floored for a noise-free record (a positive scale even where the
    measured column is smooth to the last digit: 1e-9 of its largest value, at least 1e-12)."""
    y = np.asarray(trace.measured, float)
    sigma = estimate_noise(trace).sigma if len(y) >= 3 else 0.0
    return sigma if sigma > 0 else max(1e-12, 1e-9 * float(np.max(np.abs(y))) if len(y) else 1e-12)
