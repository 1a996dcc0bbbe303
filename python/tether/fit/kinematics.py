"""What the data say before any model: the dominant frequency, and the
payload's displacement, velocity and acceleration (filtered, or exact for a periodic record)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..run import record_period
from ..traces import Trace


def dominant_frequency(t: np.ndarray, y: np.ndarray) -> float:
    """The frequency (Hz) of the highest peak of y's Hann-windowed spectrum, the mean aside."""
    dt = float(np.median(np.diff(t)))
    yy = (y - np.mean(y)) * np.hanning(len(y))
    spec = np.abs(np.fft.rfft(yy))
    f = np.fft.rfftfreq(len(y), dt)
    spec[0] = 0.0
    return float(f[int(np.argmax(spec))]) or 1.0 / (t[-1] - t[0])


@dataclass
class Kinematics:
    """The payload's motion as the equation error uses it (one period of a periodic record)."""

    x: np.ndarray      # smoothed displacement
    v: np.ndarray
    a: np.ndarray
    f: np.ndarray      # force on the payload (0 for free vibration)
    use: np.ndarray    # samples the equation error may use (edges of a filter window dropped)
    periodic: bool


def kinematics(trace: Trace, f_dom: float) -> Kinematics:
    """Displacement, velocity and acceleration of a payload trace (one period for periodic records)."""
    t = np.asarray(trace.time, float)
    y = np.asarray(trace.measured, float)
    f = np.zeros_like(y) if trace.input is None else np.asarray(trace.input, float)
    P = int(trace.periodic_samples or 0)
    if P:
        # exact derivatives of the mean period's Fourier series, below the highest excited frequency
        x = y.reshape(-1, P).mean(axis=0)
        fp = f[:P]
        Tp = record_period(t, P)
        X = np.fft.rfft(x)
        w = 2 * np.pi * np.fft.rfftfreq(P, Tp / P)
        F = np.abs(np.fft.rfft(fp))
        if F.max() > 0:
            excited = F > 1e-3 * F.max()
            cut = 1.2 * w[excited].max() if excited.any() else w[-1]
            X[w > cut] = 0.0
        xs = np.fft.irfft(X, P)
        v = np.fft.irfft(1j * w * X, P)
        a = np.fft.irfft(-(w ** 2) * X, P)
        return Kinematics(xs, v, a, fp.copy(), np.ones(P, bool), True)
    from ..savgol import savgol, savgol_gain

    dt = float(np.median(np.diff(t)))
    win = int(round(1.0 / (f_dom * dt) / 6.0)) | 1           # about a sixth of the dominant period
    win = max(7, min(win, 101, (len(y) // 4) | 1 if len(y) >= 28 else 7))
    if len(y) <= win:
        win = max(5, (len(y) - 1) | 1 if (len(y) - 1) % 2 else len(y) - 2)
    order = 4 if win >= 9 else 3
    # each divided by the filter's gain on the dominant tone: a window long against the period
    # would bias the equation error's stiffness low (docs/reproducibility.md)
    xs, v, a = (savgol(y, win, order, deriv=d, delta=dt) / savgol_gain(win, order, d, f_dom * dt) for d in range(3))
    use = np.zeros(len(y), bool)
    use[win:len(y) - win] = True
    if use.sum() < 10:
        use[:] = True
    return Kinematics(xs, v, a, f, use, False)


