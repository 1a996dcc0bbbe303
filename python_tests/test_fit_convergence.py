"""The engine's fit reaches the least-squares point (docs/fit-convergence.md).

A forced record with the mass free: the stiffness and the mass are 0.9999 correlated (the
resonance fixes their ratio), and forward differences stopped LM short of the optimum along that
direction. A second optimizer (scipy's least_squares, three-point differences, started from the
engine's result) must find no point better by more than a small part of one noise variance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import least_squares

import hidden_effects as he
from tether.discover.fitting import predict
from tether.fit import fit_traces
from tether.traces import read_trace

FREE = ["EA", "c0", "m", "x0", "v0", "offset_measured"]


@pytest.fixture(scope="module")
def forced_mass_record(tmp_path_factory):
    """The tuning draw's forced null of the nuisance family cut to 12 s (a sweep at 200 Hz, 2.09 s
    into a longer run, its mass 1.2 x the JSON's, 1e-5 m of noise): the generator's linear law is
    the model's. Forward differences throughout left 4.5 noise variances to scipy here and the
    true mass outside its interval; polished 0.000, and inside (docs/fit-convergence.md)."""
    tr = he.generate("forced", set(), 1002, noise=1e-5, rate=200.0, nuisance=True, duration_s=12.0)
    d = tmp_path_factory.mktemp("conv")
    tr.write(d, "forced_mass")
    return read_trace(d / "forced_mass"), tr


def _chi2_left(trace, fitted_values, sigma):
    """How much lower (in noise variances) scipy takes the sum of squares from ``fitted_values``."""
    names = list(FREE)
    x0 = np.array([fitted_values[n] for n in names])
    scale = np.abs(x0) + 1e-12
    y = np.asarray(trace.measured, float)

    def residual(z):
        return predict(trace, "linear", dict(zip(names, z * scale))) - y

    r0 = residual(x0 / scale)
    sol = least_squares(residual, x0 / scale, jac="3-point", diff_step=1e-6, xtol=1e-14, ftol=1e-14, gtol=1e-14,
                        max_nfev=200)
    return (r0 @ r0 - sol.fun @ sol.fun) / sigma ** 2


def test_the_fit_ends_at_the_least_squares_point(forced_mass_record):
    trace, tr = forced_mass_record
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    r = fit_traces([trace], "linear", free=FREE)
    left = _chi2_left(trace, r.values, sigma)
    assert left < 0.2, f"a second optimizer lowers the sum of squares by {left:.2f} noise variances"
    lo, hi = r.ci95["m"]
    assert lo <= tr.meta["hidden"]["nuisance"]["m_true"] <= hi


def _ar1(n, rho, sigma, seed):
    """AR(1) noise of standard deviation sigma: e_t = rho e_(t-1) + sqrt(1 - rho^2) sigma w_t."""
    w = np.random.default_rng(seed).standard_normal(n) * sigma * np.sqrt(1 - rho ** 2)
    e = np.empty(n)
    e[0] = sigma * np.random.default_rng(seed + 1).standard_normal()
    for i in range(1, n):
        e[i] = rho * e[i - 1] + w[i]
    return e


@pytest.mark.parametrize("rho", [0.0, 0.8])
def test_intervals_widen_for_residuals_correlated_in_time(tmp_path, rho):
    """An offset of the measured column is a mean: with AR(1) noise its variance is the classic
    sigma^2 / N times (1 + rho) / (1 - rho) (the long-run variance); the engine's block sandwich
    must find that, and with white noise stay at the classic sigma / sqrt(N). The estimate of one
    record scatters by about 16 % (20 blocks): the mean over six noise draws is judged."""
    sigma = 1e-4
    tr = he.generate("forced", set(), 1004, noise=sigma, rate=200.0, duration_s=8.0, nuisance=True,
                     mass_factor=1.0, offset_noise=3.0, preroll_s=0.0)
    n = len(tr.truth["measured"])
    expected = sigma / np.sqrt(n) * np.sqrt((1 + rho) / (1 - rho))
    ratios = []
    for draw in range(6):
        tr.columns[tr.measured_name] = tr.truth["measured"] + _ar1(n, rho, sigma, 11 + 2 * draw)
        tr.write(tmp_path, f"rec{draw}")
        r = fit_traces([read_trace(tmp_path / f"rec{draw}")], "linear", free=["EA", "c0", "offset_measured"])
        ratios.append(r.std_error["offset_measured"] / expected)
    assert 0.8 < np.mean(ratios) < 1.2, ratios



def test_a_parameter_the_data_do_not_determine_is_written_as_null(tmp_path):
    """An Iwan element that never slips has an infinite variance (the engine's pseudo-inverse);
    its interval and standard error go to the params file as null, and the file stays strict JSON
    that its schema accepts and `--params` reads (it exited 1 on 'Out of range float values'; so did
`tether fit` where such a parameter's correlation with itself, inf / inf, was written as NaN)."""
    import json
    import math

    import jsonschema

    from tether.fit import write_fit_params
    from tether.models import read_params

    tr = he.generate("forced", set(), 1004, noise=1e-4, rate=100.0, duration_s=6.0)
    tr.write(tmp_path, "rec")
    r = fit_traces([read_trace(tmp_path / "rec")], "linear", free=["EA", "c0"])
    r.std_error["c0"] = math.inf
    r.ci95["c0"] = (-math.inf, math.inf)
    r.correlation = np.array(r.correlation, float)
    r.correlation[1, 1] = math.nan      # the engine's cov / sqrt(cov cov) of an infinite variance: inf / inf
    path = write_fit_params(tmp_path / "p.json", r)
    doc = json.loads(path.read_text(), parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
    assert doc["intervals"]["c0"] is None and doc["std_error"]["c0"] is None
    assert doc["intervals"]["EA"] == [float(x) for x in r.ci95["EA"]]
    assert doc["correlation"]["matrix"][1][1] is None and doc["correlation"]["matrix"][0][0] == 1.0
    schema = json.loads((Path(__file__).resolve().parents[1] / "docs/schemas/tether-params-1.schema.json").read_text())
    jsonschema.validate(doc, schema)
    assert read_params(path).parameters["c0"] == pytest.approx(r.values["c0"])
