"""A creep test whose load ramps to its level, sampled on the way (a lab's hanging weight let down
over seconds, sampled each second, then held for hours sampled every half minute), traces the
elastic curve on its ramps as a load test does: tether.fit's data-based start reads a nonlinear
elastic law from those samples (fit/load_start.py, _static_law), where before it read nothing but
the first sample after a step and left the law at the FMU's defaults."""

from __future__ import annotations

import numpy as np
import pytest

from tether.fit import fit_traces
from tether.fit.experiments import predict, trace_experiment
from tether.fit.start import fmu_defaults, initial_estimate
from tether.models import parse_model
from tether.traces import Trace

L0, NOISE = 16.0, 4e-5
#: an exponential tether with the default Kelvin cells, no slip
TRUTH = {"exp_F": 40.0, "exp_eps": 0.03, "creep_J1": 1e-6, "creep_tau1": 1800.0, "creep_J2": 2.5e-6,
         "creep_tau2": 5400.0, "creep_J3": 1.5e-6, "creep_tau3": 172800.0, "slip_capacity0": 0.0, "slip_rate": 0.0}


def _schedule(ramp_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """5 N, up to 100 N over ``ramp_samples`` seconds sampled each second, held 2 h sampled every
    30 s, down to 5 N the same way, held 1.5 h."""
    t, F = [0.0], [5.0]
    for to, dur, dt in ((100.0, ramp_samples, 1.0), (100.0, 7200.0, 30.0), (5.0, ramp_samples, 1.0),
                        (5.0, 5400.0, 30.0)):
        n = int(round(dur / dt))
        t0, f0 = t[-1], F[-1]
        t += [t0 + dt * j for j in range(1, n + 1)]
        F += [f0 + (to - f0) * j / n for j in range(1, n + 1)]
    return np.array(t), np.array(F)


@pytest.fixture(scope="module")
def ramped_creep_test() -> Trace:
    """The engine's elongation of the exponential tether with creep under a ramped schedule, with
    Gaussian noise of NOISE."""
    t, F = _schedule(20)
    tr = Trace.from_arrays(t, experiment="creep", length_m=L0, load=F, elongation=np.zeros_like(t), name="ramped")
    y = predict(trace_experiment(tr, parse_model("exponential+creep", "creep"), {}), TRUTH)
    tr.measured = y + NOISE * np.random.default_rng(1).standard_normal(y.size)
    return tr


def test_the_ramps_of_a_creep_test_give_the_elastic_law_its_start(ramped_creep_test):
    """The start's exponential law within 5 % of the truth (the ramps' samples hold a few seconds of
    creep at most)."""
    est = initial_estimate([ramped_creep_test], parse_model("exponential+creep", "creep"))
    for k in ("exp_F", "exp_eps"):
        assert abs(est[k] / TRUTH[k] - 1) < 0.05, (k, est[k])


def test_the_right_model_fits_a_ramped_creep_test_to_the_noise_from_the_data(ramped_creep_test):
    """From the data-based start, the fit of the exponential law with creep reaches the error of the
    truth itself (within 2 %; from the FMU's default law it stopped at 6.6 x noise, 2026-12-04)."""
    free = ["exp_F", "exp_eps", "creep_J1", "creep_J2", "creep_J3", "slip_capacity0", "slip_rate"]
    fit = fit_traces([ramped_creep_test], "exponential+creep", free=free)
    y = predict(trace_experiment(ramped_creep_test, parse_model("exponential+creep", "creep"), {}), TRUTH)
    truth_rms = float(np.sqrt(np.mean((y - ramped_creep_test.measured) ** 2)))
    assert fit.rms_per_trace[0] < 1.02 * truth_rms, (fit.rms_per_trace[0] / NOISE, truth_rms / NOISE)


def test_a_creep_test_whose_load_steps_between_two_samples_informs_only_the_linear_law():
    """Steps of the load between two samples leave two levels: no ramp, and the nonlinear law keeps
    its defaults (no curve to read); the linear law still gets EA from the first sample after each
    step."""
    t = 30.0 * np.arange(421)
    F = np.where(t < 7200, 100.0, 5.0)
    F[0] = 5.0
    tr = Trace.from_arrays(t, experiment="creep", length_m=L0, load=F, elongation=F * L0 / 20000.0, name="stepped")
    est = initial_estimate([tr], parse_model("exponential+creep", "creep"))
    assert (est["exp_F"], est["exp_eps"]) == (fmu_defaults()["exp_F"], fmu_defaults()["exp_eps"])
    assert initial_estimate([tr], parse_model("linear+creep", "creep"))["EA"] == pytest.approx(20000.0, rel=1e-6)
