"""The one noise estimator of `tether fit` and `tether discover` (tether.noise), against the noise
drawn into a record: also where the signal changes fast from sample to sample, which the 4th
differences fit used before took for noise (issue 25: 2.24 mV against discovery's 0.606 mV on one
real record)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tether.noise import estimate_noise, noise_level
from tether.traces import Trace


def _free_vibration(sigma: float, f_hz: float, rate: float, seed: int = 1, periods: int | None = None) -> Trace:
    t = np.arange(0.0, 10.0, 1.0 / rate)
    decay = 0.0 if periods else 0.1
    y = 0.05 * np.cos(2 * math.pi * f_hz * t) * np.exp(-decay * t)
    y = y + np.random.default_rng(seed).normal(0.0, sigma, len(t))
    if periods:        # a forced record in its periodic steady state
        return Trace.from_arrays(t, experiment="forced", length_m=1.0, payload_mass_kg=1.0, displacement=y,
                                 force=np.sin(2 * math.pi * f_hz * t), periodic_samples=periods)
    return Trace.from_arrays(t, experiment="free_vibration", length_m=1.0, payload_mass_kg=1.0, displacement=y)


def _fourth_difference_estimate(y: np.ndarray) -> float:
    """The estimator fit used before (robust scale of the 4th differences / sqrt 70)."""
    d4 = y[4:] - 4 * y[3:-1] + 6 * y[2:-2] - 4 * y[1:-3] + y[:-4]
    return float(1.4826 * np.median(np.abs(d4 - np.median(d4)))) / math.sqrt(70.0)


@pytest.mark.parametrize("seed", [1, 2])
def test_a_fast_signal_is_not_taken_for_noise(seed):
    sigma = 1e-4
    tr = _free_vibration(sigma, f_hz=8.0, rate=100.0, seed=seed)      # 12.5 samples per period
    assert _fourth_difference_estimate(tr.measured) > 2.0 * sigma    # the old estimator's miss
    assert estimate_noise(tr).sigma == pytest.approx(sigma, rel=0.08)
    assert noise_level(tr) == estimate_noise(tr).sigma


def test_a_periodic_record_gives_the_noise_from_its_periods():
    sigma = 3e-4
    tr = _free_vibration(sigma, f_hz=2.0, rate=100.0, periods=50)     # 20 periods of 50 samples
    est = estimate_noise(tr)
    assert "periods" in est.method and est.sigma == pytest.approx(sigma, rel=0.08)


def test_a_noise_free_record_gets_a_small_positive_scale():
    t = np.arange(0.0, 2.0, 0.01)
    tr = Trace.from_arrays(t, experiment="free_vibration", length_m=1.0, payload_mass_kg=1.0,
                           displacement=0.05 * t ** 2)
    assert estimate_noise(tr).sigma < 1e-12
    assert 0 < noise_level(tr) <= 1e-9 * 0.2 + 1e-12


def test_fit_reports_the_noise_discovery_judges_against():
    from tether.fit import fit_traces

    tr = _free_vibration(2e-4, f_hz=8.0, rate=100.0)
    r = fit_traces([tr], "linear")
    assert r.noise[0] == estimate_noise(tr).sigma == pytest.approx(2e-4, rel=0.08)
