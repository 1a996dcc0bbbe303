"""The equation error's pieces: least squares with scaled columns (plain and non-negative), the
payload equation's restoring and damping columns, and the samples of a record that are surely taut."""

from __future__ import annotations

import numpy as np

def scaled_lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares A coef = b with A's columns scaled to unit norm (a column of zeros as it is):
    columns of displacement, velocity and their powers differ by many orders of magnitude."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    coef, *_ = np.linalg.lstsq(A / scale, b, rcond=None)
    return coef / scale


def scaled_nnls(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative least squares A coef = b, coef >= 0, with A's columns scaled to unit norm as in
    scaled_lstsq; returns coef and the residual norm |A coef - b| (which the scaling leaves as is)."""
    from scipy.optimize import nnls

    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    coef, res = nnls(A / scale, b)
    return coef / scale, float(res)


def taut_for_sure(x: np.ndarray, m: float, g: float, k: float) -> np.ndarray:
    """Samples of a payload record whose displacement x stays above 90 % of the balance stretch
    m g / k below balance: taut whatever the law's details (a slack record's other samples may not be)."""
    return x > -0.9 * m * g / k


def restoring_columns(x: np.ndarray, cubic: bool) -> list[np.ndarray]:
    """The restoring force's columns in x: the linear law's x, the cubic's x, x^2, x^3."""
    return [x, x ** 2, x ** 3] if cubic else [x]


def damping_magnitude(x: np.ndarray, v: np.ndarray, swing_rate: float = 0.0) -> np.ndarray:
    """What c(.) reads (physics/damping.c): the displacement |x|, or, given the payload's angular
    frequency ``swing_rate`` (the amplitude law), the swing's amplitude sqrt(x^2 + (v / swing_rate)^2)."""
    return np.hypot(x, v / swing_rate) if swing_rate > 0 else np.abs(x)


def damping_columns(x: np.ndarray, v: np.ndarray, displacement: bool, swing_rate: float = 0.0) -> list[np.ndarray]:
    """The damping force's columns: viscous v; displacement-dependent v, a v, a^2 v with a the
    magnitude c(.) reads (damping_magnitude: |x|, or the amplitude given ``swing_rate``)."""
    if not displacement:
        return [v]
    a = damping_magnitude(x, v, swing_rate)
    return [v, a * v, a ** 2 * v]

