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


@pytest.mark.parametrize("window, order, cycles_per_sample", [(7, 3, 0.08), (7, 3, 0.02), (17, 4, 0.01), (31, 4, 0.03)])
def test_the_gain_on_a_tone_is_what_the_filter_does_to_it(window, order, cycles_per_sample):
    """savgol_gain against scipy's filter run on a sampled tone and compared with the tone's exact
    derivatives, away from the ends."""
    from tether.savgol import savgol_gain

    n, w = 2000, 2 * np.pi * cycles_per_sample
    k = np.arange(n)
    exact = (np.cos(w * k), -w * np.sin(w * k), -w * w * np.cos(w * k))
    for deriv in range(3):
        got = savgol_filter(exact[0], window, order, deriv=deriv)[window:-window]
        ratio = np.dot(got, exact[deriv][window:-window]) / np.dot(exact[deriv][window:-window], exact[deriv][window:-window])
        assert savgol_gain(window, order, deriv, cycles_per_sample) == pytest.approx(ratio, rel=1e-9)


def test_the_kinematics_of_a_record_with_few_samples_a_period_follow_its_tone():
    """8 Hz at 100 Hz (12.5 samples a period): the filter alone gives 0.81 of the acceleration; the
    kinematics divide its gain out, so a noise-free tone's x, v and a are its own."""
    from tether.fit.kinematics import kinematics
    from tether.traces import Trace

    t = np.arange(0.0, 10.0, 0.01)
    w = 2 * np.pi * 8.0
    tr = Trace.from_arrays(t, experiment="free_vibration", length_m=1.0, payload_mass_kg=1.0,
                           displacement=0.05 * np.cos(w * t))
    K = kinematics(tr, 8.0)
    u = K.use
    for got, want in ((K.x, 0.05 * np.cos(w * t)), (K.v, -0.05 * w * np.sin(w * t)), (K.a, -0.05 * w * w * np.cos(w * t))):
        assert np.max(np.abs(got[u] - want[u])) < 1e-6 * np.max(np.abs(want))
