"""Savitzky-Golay smoothing and derivatives, bit for bit scipy.signal.savgol_filter (mode "interp").

Importing scipy.signal takes 1-2 s (it loads scipy.stats and parses hundreds of docstrings), more
than a short fit needs in all; the starts of a fit need only this filter. The same arithmetic in
the same order, with scipy.linalg's least squares, gives the same bits (python_tests/test_savgol.py
checks it against scipy.signal), so the fits that start from it do not change.

    xs, v, a = (savgol(y, 31, 4, deriv=d, delta=dt) for d in (0, 1, 2))
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["savgol", "savgol_gain"]

_EPS = np.finfo(float).eps


def savgol(y, window: int, order: int, deriv: int = 0, delta: float = 1.0) -> np.ndarray:
    """The least-squares polynomial of ``order`` through the ``window`` samples (odd) centred on
    each sample of ``y`` (spacing ``delta``), evaluated there: its value (deriv 0) or its
    derivative of order ``deriv``. Within window // 2 of an end: the polynomial through the first
    or last ``window`` samples."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or window % 2 != 1 or not 0 <= deriv <= order < window <= len(y):
        raise ValueError(f"savgol: need an odd window above the order and at most the {y.size} samples, and "
                         f"deriv <= order; got window {window}, order {order}, deriv {deriv}")
    h = window // 2
    out = np.empty_like(y)
    out[h:len(y) - h] = _centred(y, _weights(window, order, deriv, delta))
    pos = np.arange(window, dtype=float)
    for first, at in ((0, np.arange(h)), (len(y) - window, np.arange(window - h, window))):
        poly = _derivative(_polyfit(pos, y[first:first + window], order), deriv)
        out[first + at] = _polyval(poly, at.astype(float)) / delta ** deriv
    return out


def savgol_gain(window: int, order: int, deriv: int, cycles_per_sample: float) -> float:
    """What the centred filter gives on a sampled tone of ``cycles_per_sample``, over the tone's
    exact derivative of order ``deriv`` (1 where the window's polynomial follows the tone; below 1
    where the window spans a good part of its period)."""
    h = window // 2
    w = _weights(window, order, deriv, 1.0)
    phase = 2 * math.pi * cycles_per_sample
    response = np.sum(w * np.exp(1j * phase * np.arange(-h, window - h)))
    return float((response / (1j * phase) ** deriv).real)


def _weights(window: int, order: int, deriv: int, delta: float) -> np.ndarray:
    """w such that sum_j w[j] y[i - h + j] is the derivative at sample i (h = window // 2): the
    row deriv of the pseudo-inverse of the window's Vandermonde matrix, found as scipy finds it
    (positions taken from the last to the first, minimum-norm least squares)."""
    from scipy.linalg import lstsq

    h = window // 2
    x = np.arange(-h, window - h, dtype=float)[::-1]
    A = x ** np.arange(order + 1, dtype=float).reshape(-1, 1)
    rhs = np.zeros(order + 1)
    rhs[deriv] = float(math.factorial(deriv)) / delta ** deriv
    c, *_ = lstsq(A, rhs, cond=_EPS * max(A.shape))
    return c[::-1]


def _centred(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """sum_j w[j] y[i - h + j] for every i with a whole window, summed as scipy.ndimage's
    correlate1d sums: symmetric (or antisymmetric) weights pair the samples i - k and i + k."""
    h = len(w) // 2
    mid = np.arange(h, len(y) - h)
    sym = _symmetry(w)
    if sym:
        out = y[mid] * w[h]
        for k in range(h, 0, -1):
            out = out + (y[mid - k] + sym * y[mid + k]) * w[h - k]
        return out
    out = y[mid + h] * w[2 * h]
    for j in range(-h, h):
        out = out + y[mid + j] * w[h + j]
    return out


def _symmetry(w: np.ndarray) -> int:
    """1 if the weights are symmetric about their centre, -1 if antisymmetric (to within eps), else 0."""
    h = len(w) // 2
    for sign in (1, -1):
        if all(abs(w[h + k] - sign * w[h - k]) <= _EPS for k in range(1, h + 1)):
            return sign
    return 0


def _polyfit(x: np.ndarray, y: np.ndarray, order: int) -> np.ndarray:
    """Coefficients (highest power first) of the least-squares polynomial, Vandermonde columns scaled to unit norm."""
    from scipy.linalg import lstsq

    lhs = x[:, None] ** np.arange(order, -1, -1, dtype=float)[None, :]
    scale = np.sqrt(np.sum(lhs * lhs, axis=0))
    c, *_ = lstsq(lhs / scale, y, cond=x.shape[0] * _EPS)
    return c / scale


def _derivative(p: np.ndarray, m: int) -> np.ndarray:
    """The m-th derivative of the polynomial p (highest power first)."""
    n = len(p)
    if m == 0:
        return p
    if n <= m:
        return np.zeros(1)
    dp = p[:-m].copy()
    for k in range(m):
        dp *= np.arange(n - k - 1, m - k - 1, -1, dtype=float)
    return dp


def _polyval(p: np.ndarray, x: np.ndarray) -> np.ndarray:
    """p at x by Horner's rule."""
    out = np.zeros_like(x)
    for c in p:
        out = out * x + c
    return out
