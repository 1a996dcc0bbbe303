"""tether.savgol is scipy.signal.savgol_filter (mode "interp") bit for bit: fits start from it, and
a start that moved in its last bit moves the end of a fit along a flat direction (docs/speed.md)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from tether.savgol import savgol

CASES = [(10001, 31, 4), (2001, 7, 3), (2001, 13, 4), (4001, 101, 4), (50, 9, 4), (30, 29, 4), (12, 7, 3),
         (9, 9, 4), (40, 5, 1), (25, 11, 0)]


@pytest.mark.parametrize("n, window, order", CASES)
def test_the_same_bits_as_scipy(n, window, order):
    rng = np.random.default_rng(n + window)
    t = np.arange(n) * 1e-3
    for y in (np.sin(7 * t) + 1e-3 * rng.standard_normal(n) + 3.0, rng.standard_normal(n) * 1e-4,
              np.cumsum(rng.standard_normal(n))):
        for deriv in range(min(order, 3) + 1):
            for delta in (1.0, 1e-3, 0.005):
                want = savgol_filter(y, window, order, deriv=deriv, delta=delta)
                got = savgol(y, window, order, deriv=deriv, delta=delta)
                assert np.array_equal(got, want), (n, window, order, deriv, delta)


def test_a_polynomial_of_the_order_is_reproduced_with_its_derivatives():
    """Independent of scipy: a quartic's samples, value and derivatives, everywhere, edges too."""
    t = np.linspace(-1.0, 2.0, 301)
    dt = t[1] - t[0]
    p = np.poly1d([0.5, -1.0, 2.0, 3.0, -4.0])
    for deriv in range(4):
        got = savgol(p(t), 21, 4, deriv=deriv, delta=dt)
        assert np.allclose(got, p.deriv(deriv)(t) if deriv else p(t), rtol=1e-9, atol=1e-8)


@pytest.mark.parametrize("window, order, deriv, n", [(8, 3, 0, 20), (7, 7, 0, 20), (7, 3, 4, 20), (9, 3, 0, 5)])
def test_impossible_windows_are_refused_with_the_values(window, order, deriv, n):
    with pytest.raises(ValueError, match=f"window {window}, order {order}, deriv {deriv}"):
        savgol(np.zeros(n), window, order, deriv=deriv)
