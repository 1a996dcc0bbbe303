"""Discovery with nuisance parameters (issue 30): a record whose effective mass is not the one its
JSON states, whose measured column carries an offset, or that starts in motion.

The records come from python_tests/hidden_effects.py's nuisance option (its own integrator and
laws); the truths are its ``hidden.nuisance``, which discovery does not read. The acceptance run
on 24 such records is bench/discovery_eval.py --family nuisance (docs/nuisance-discovery.md).
"""

from __future__ import annotations

import json

import pytest

import hidden_effects as he
from tether import discover as D
from tether.traces import read_trace

#: a short forced record with slack (a fast discovery), its mass 1.2 x the JSON's, its measured
#: column 4 noise levels off
SLACK_FORCED = dict(noise=1e-4, rate=100.0, duration_s=10.0, nuisance=True, mass_factor=1.2, offset_noise=4.0,
                    preroll_s=0.0)


def _write(tmp_path, stem, experiment, effects, seed, **kw):
    tr = he.generate(experiment, effects, seed, **kw)
    tr.write(tmp_path, stem)
    return tmp_path / stem, tr


@pytest.fixture(scope="module")
def slack_forced(tmp_path_factory):
    """The record, its JSON saying how the generator drove it (the linear interpolant of the force
    samples): with the default cubic spline the fitted mass's interval ended at 5.7017 kg, the
    truth 5.7 just outside it (docs/nuisance-discovery.md)."""
    tr = he.generate("forced", {"slack"}, 18, **SLACK_FORCED)
    tr.meta["input_interpolation"] = "linear"
    d = tmp_path_factory.mktemp("nz")
    tr.write(d, "forced_slack_mass")
    return d / "forced_slack_mass", tr


def test_a_hidden_mass_and_an_offset_are_not_named_as_effects(slack_forced, run_cli, tmp_path):
    stem, tr = slack_forced
    out = tmp_path / "d.json"
    status, stdout, err = run_cli("discover", stem, "--json", out)
    assert status == 0, err
    doc = json.loads(out.read_text())
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    nz = tr.meta["hidden"]["nuisance"]
    assert doc["added_effects"] == ["slack"]
    assert doc["rmse_final"] <= 1.5 * sigma
    got = doc["nuisance"]["parameters"]
    lo, hi = got["m"]["interval"]
    assert lo <= nz["m_true"] <= hi
    assert got["m"]["moved"] and got["m"]["start"] == tr.meta["payload_mass_kg"]
    lo, hi = got["offset_measured"]["interval"]
    assert lo <= nz["offset_measured"] <= hi
    assert "nuisance m:" in stdout and "moved" in stdout
    assert set(doc["nuisance"]["not_freed"]) == {"offset_input", "last_reversal_beyond"}
    assert "starts at rest" in doc["nuisance"]["not_freed"]["last_reversal_beyond"]
    # the --params part of the record holds the model's own parameters only
    assert not set(doc["parameters"]) & {"m", "x0", "v0", "offset_measured"}


def test_without_the_nuisance_parameters_the_same_record_is_misread(slack_forced):
    """The hidden set's model (linear+slack) fitted with the record's stated mass and no offset stays
    far above the noise, from the data-based start with four starts and from the generator's own law
    alike (measured 201 x), while the same fit with the nuisance parameters free reaches it (0.98 x):
    a discovery without them cannot name slack alone within 1.5 x noise. (Until 2026-12-06 this test
    ran that discovery, 61 s: docs/test-suite-time.md.) Such a discovery keeps every parameter that
    applies to the record at its value and says why."""
    from tether.fit import fit_traces

    stem, tr = slack_forced
    trace = read_trace(stem)
    sigma = tr.meta["hidden"]["noise_sigma_m"]
    truth = tr.meta["hidden"]["derived"]
    law = {"EA": truth["k_lin_N_m"] * trace.length_m, "c0": truth["c0_N_s_m"]}
    stated = [fit_traces([trace], "linear+slack", n_starts=4), fit_traces([trace], "linear+slack", start=law)]
    assert min(r.rms for r in stated) > 1.5 * sigma, [r.rms / sigma for r in stated]
    freed = fit_traces([trace], "linear+slack", free=["EA", "c0"] + D.nuisance_parameters(trace))
    assert freed.rms <= 1.5 * sigma, freed.rms / sigma
    doc = D.discovery_document(D.discover(trace, free_nuisance=False, budget=0.0))
    assert doc["nuisance"]["parameters"] == {}
    kept = doc["nuisance"]["not_freed"]
    # the parameters that apply to the record, each kept: the force gain is known, so no input_gain
    assert set(kept) == {"offset_measured", "m", "x0", "v0", "last_reversal_beyond", "offset_input"}
    assert "--no-nuisance" in kept["offset_measured"]


def test_a_mass_band_without_the_nuisance_parameters_is_refused(slack_forced, run_cli, tmp_path):
    stem, _ = slack_forced
    out = tmp_path / "d.json"
    status, stdout, err = run_cli("discover", stem, "--json", out, "--mass-band", "0.2", "--no-nuisance")
    assert status == 2 and len(err.strip().splitlines()) == 1 and "--no-nuisance" in err, err
    assert not out.exists()


def test_which_nuisance_parameters_discovery_frees(tmp_path):
    fv, _ = _write(tmp_path, "fv", "free_vibration", set(), 3, noise=1e-4, rate=100.0, nuisance=True)
    fo, _ = _write(tmp_path, "fo", "forced", set(), 4, noise=1e-4, rate=100.0, nuisance=True)
    lu, _ = _write(tmp_path, "lu", "load_unload", set(), 5, noise=5e-5, rate=5.0)
    fv, fo, lu = (read_trace(s) for s in (fv, fo, lu))
    assert D.nuisance_parameters(fv) == ["offset_measured", "x0"]
    assert "m" in D.nuisance_not_freed(fv) and "scales with" in D.nuisance_not_freed(fv)["m"]
    assert D.nuisance_parameters(fo) == ["offset_measured", "x0", "v0", "m"]
    assert D.nuisance_parameters(lu) == ["offset_measured"]
    assert "offset_input" in D.nuisance_not_freed(lu)
    fo.force_gain_known = False
    assert D.nuisance_parameters(fo) == ["offset_measured", "x0", "v0", "input_gain"]
    fo.force_gain_known, fo.mass_uncertainty_rel = True, 0.0
    assert "m" not in D.nuisance_parameters(fo)


@pytest.mark.parametrize("seed", [21, 22, 23])
def test_the_bank_memory_is_freed_on_records_that_start_in_motion(tmp_path, seed):
    """The same forced record with hysteresis, once from rest and once cut 3 s into a longer run:
    the Iwan bank's memory of that run (last_reversal_beyond) is freed on the second only, and the
    first says why not."""
    kw = dict(noise=1e-4, rate=200.0, duration_s=8.0, nuisance=True, mass_factor=1.2, offset_noise=3.0)
    rest, _ = _write(tmp_path, "rest", "forced", {"hysteresis"}, seed, preroll_s=0.0, **kw)
    cut, meta = _write(tmp_path, "cut", "forced", {"hysteresis"}, seed, preroll_s=3.0, **kw)
    rest, cut = read_trace(rest), read_trace(cut)
    assert meta.meta["hidden"]["nuisance"]["in_motion"]
    assert "last_reversal_beyond" not in D.nuisance_parameters(rest)
    assert "starts at rest" in D.nuisance_not_freed(rest)["last_reversal_beyond"]
    assert "last_reversal_beyond" in D.nuisance_parameters(cut)
    assert "last_reversal_beyond" not in D.nuisance_not_freed(cut)


#: a forced record with Iwan friction and slack, cut 3 s into a longer run (issue 30's bank memory)
CUT_IWAN_SLACK = dict(noise=1e-4, rate=200.0, duration_s=10.0, nuisance=True, mass_factor=1.15, offset_noise=2.0,
                      preroll_s=3.0)


def _generator_bank(meta) -> dict:
    """The generator's own Iwan bank (hidden_effects: twelve equal springs, slip strains on its
    power law) by the FMU's names, the four elements left over empty."""
    import numpy as np
    from tether.fit.iwan_bank import iwan_params

    P = meta["hidden"]["params"]
    n = int(P["hyst_n"])
    k = P["hyst_eta"] * P["EA_N"] / n
    slip = P["hyst_eps_ymax"] * ((np.arange(n) + 0.5) / n) ** P["hyst_beta"]
    return iwan_params(list(slip) + [1.0] * (16 - n), np.r_[np.full(n, k), np.zeros(16 - n)])


@pytest.mark.parametrize("seed", [4, 8])
def test_a_record_cut_from_a_run_is_fitted_with_the_bank_memory(tmp_path, seed):
    """The generator's bank (one element's spring free) with its elastic law 10 % and its damping
    50 % off at the start: the fit finds the bank's memory of the run (from its data-based start,
    then a scan of its grid with x0 and v0 corrected along), so that it reaches the noise with the
    initial state inside its intervals. Before (the memory started at 0 and freed beside the bank
    held at its start): 1.95 and 1.18 x noise, x0 and v0 outside."""
    from tether.fit import fit_traces

    stem, gen = _write(tmp_path, "r", "forced", {"hysteresis", "slack"}, seed, **CUT_IWAN_SLACK)
    truth, P = gen.meta["hidden"]["nuisance"], gen.meta["hidden"]["derived"]
    bank = _generator_bank(gen.meta)
    start = {"EA": 1.1 * gen.meta["hidden"]["params"]["EA_N"], "c0": 1.5 * P["c0_N_s_m"], "iw_k1": bank["iw_k1"]}
    free = ["EA", "c0", "iw_k1", "m", "x0", "v0", "offset_measured", "last_reversal_beyond"]
    r = fit_traces([read_trace(stem)], "linear+iwan+slack", free=free, start=start,
                   fixed={n: v for n, v in bank.items() if n != "iw_k1"})
    assert r.rms < 1.05 * 1e-4, r.rms
    for n in ("x0", "v0"):
        lo, hi = r.ci95[n]
        assert lo <= truth[n] <= hi, (n, r.values[n], r.ci95[n], truth[n])


def test_the_bank_memory_starts_on_the_side_the_payload_comes_from(tmp_path):
    """last_reversal_estimate: a record cut while the payload moves up reversed below (negative),
    one cut while it moves down above; the grid a fit scans is symmetric and within the record's
    span."""
    from tether import nuisance as NZ

    signs = []
    for seed in (3, 5, 8):
        stem, gen = _write(tmp_path, f"r{seed}", "forced", {"hysteresis"}, seed, **CUT_IWAN_SLACK)
        t = read_trace(stem)
        b = NZ.last_reversal_estimate(t)
        signs.append((gen.meta["hidden"]["nuisance"]["v0"] > 0) == (b < 0))
        grid = NZ.last_reversal_grid(t)
        span = float(t.measured.max() - t.measured.min())
        assert grid == sorted(-g for g in grid) and max(grid) == pytest.approx(span) and 0.0 not in grid
    assert all(signs), signs


@pytest.mark.parametrize("experiment,seed", [("free_vibration", 11), ("forced", 12), ("forced", 13)])
def test_the_data_based_start_reads_the_offset_and_the_mass(tmp_path, experiment, seed):
    """The equation-error start finds the offset to a fraction of itself and a mass closer to the
    truth than the trace's (null records: the linear law is the truth), where the trace's own
    values are 2-5 noise levels and 10-30 % off. (The mass start of seed 13 is 6 % low: its multisine
    reaches 4 x the natural frequency, and the smoothed acceleration misses its top.)"""
    stem, tr = _write(tmp_path, "r", experiment, set(), seed, noise=1e-4, rate=200.0, nuisance=True)
    nz = tr.meta["hidden"]["nuisance"]
    t = read_trace(stem)
    st = D.nuisance.nuisance_start(t, D.nuisance_parameters(t))
    assert st["offset_measured"] == pytest.approx(nz["offset_measured"], abs=0.3 * abs(nz["offset_measured"]))
    if experiment == "forced":
        assert abs(st["m"] - nz["m_true"]) < 0.6 * abs(t.payload_mass_kg - nz["m_true"])
    assert st["x0"] == pytest.approx(nz["x0"], abs=3e-4)


def test_a_forced_record_the_linear_equation_does_not_describe_is_read_as_it_states(slack_forced_b26):
    """The second generator's forced record of a tether that goes slack 14 times (development draw
    b26, seed 11: its stated mass the truth): the equation error's acceleration column took up what
    the linear law lacks, 0.50 times the mass, clamped to the band's edge, and the law's stiffness at
    half its own, a start from which the slack candidate's fit stopped at 40 x noise. That equation
    explains 59 % of the force's variance there (at least nuisance.MASS_ESTIMATE_MIN_R2 where the
    start is read: the records of the test above): the record's own reading is what it states."""
    import numpy as np

    from tether.fit.kinematics import dominant_frequency, kinematics

    _, t = slack_forced_b26
    K = kinematics(t, dominant_frequency(np.asarray(t.time), np.asarray(t.measured)))
    A = np.column_stack([K.a[K.use], K.v[K.use], K.x[K.use], np.ones(int(K.use.sum()))])
    coef = np.linalg.lstsq(A, K.f[K.use], rcond=None)[0]
    assert coef[0] < 0.6 * t.payload_mass_kg                       # what the equation reads
    assert D.nuisance._explained(A, coef, K.f[K.use]) < D.nuisance.MASS_ESTIMATE_MIN_R2
    assert D.nuisance.nuisance_start(t, D.nuisance_parameters(t)) == {
        "offset_measured": 0.0, "x0": 0.0, "v0": 0.0, "m": t.payload_mass_kg}


def test_mass_band_is_checked_on_the_command_line(slack_forced, run_cli, tmp_path):
    stem, _ = slack_forced
    out = tmp_path / "d.json"
    status, _, err = run_cli("discover", stem, "--json", out, "--mass-band", "-1")
    assert status == 2 and "--mass-band" in err and not out.exists()


def test_the_html_report_shows_the_nuisance_table():
    from tether.discover_report import nuisance_html

    section = {"parameters": {"m": {"start": 4.0, "value": 4.8, "interval": [4.79, 4.81], "change": 0.8,
                                    "change_relative": 0.2, "change_interval_widths": 40.0, "moved": True},
                              "offset_measured": {"start": 0.0, "value": 1e-6, "interval": [-1e-6, 3e-6],
                                                  "change": 1e-6, "change_relative": None,
                                                  "change_interval_widths": 0.25, "moved": False}},
               "not_freed": {"offset_input": "trades one for one <against> offset_measured"},
               "mass_band_rel": 0.3, "mass_band_kg": [2.8, 5.2]}
    page = nuisance_html(section)
    assert "<h2>Nuisance parameters</h2>" in page and "2.8–5.2 kg" in page and "±30 %" in page
    assert "+20.0 %" in page and "4.79 – 4.81" in page and "moved" in page
    assert "&lt;against&gt;" in page                      # escaped
    assert nuisance_html(None) == ""


@pytest.mark.parametrize("seed", [3, 8])
def test_the_data_based_estimate_reads_the_record_as_the_nuisance_values_describe_it(tmp_path, seed):
    """The equation of motion m a + c v + k x = f: with the JSON's mass a quarter below the true
    one, the equation error gives the stiffness a quarter low (k / m is what the record's
    frequencies fix); read off the record with the fitted mass and offset (nuisance.data_start) it
    gives the generator's k and c within 0.5 %, and the nuisance values start the fit."""
    from tether.discover.nuisance import data_start
    from tether.fit import initial_estimate
    from tether.models import parse_model

    stem, tr = _write(tmp_path, "forced", "forced", (), seed, noise=1e-5, rate=100.0, nuisance=True,
                      mass_factor=1.25, offset_noise=4.0, preroll_s=0.0)
    trace, truth, derived = read_trace(stem), tr.meta["hidden"]["nuisance"], tr.meta["hidden"]["derived"]
    nz = {"m": truth["m_true"], "offset_measured": truth["offset_measured"]}
    raw = initial_estimate([trace], parse_model("linear"))
    start = data_start(trace, parse_model("linear"), nz)
    k, L0 = derived["k_lin_N_m"], trace.length_m
    print(f"FIGURE k {k:.1f} N/m: as given {raw['EA'] / L0:.1f}, as the nuisance values describe it {start['EA'] / L0:.1f}")
    assert abs(raw["EA"] / L0 / k - 1.0 / 1.25) < 0.02           # the mass error, leaning on k
    assert start["EA"] / L0 == pytest.approx(k, rel=5e-3)
    assert start["c0"] == pytest.approx(derived["c0_N_s_m"], rel=5e-3)
    assert start["m"] == nz["m"] and start["offset_measured"] == nz["offset_measured"]
    assert data_start(trace, parse_model("linear"), {}) is None


def test_a_search_fit_starts_its_data_based_estimate_from_the_current_nuisance_values(tmp_path, monkeypatch):
    """A candidate's start None (tether.fit's data-based estimate) reaches the engine as the estimate
    read off the record with the current model's mass and offset, not the JSON's: on the tuning
    draw's forced record 23 of seed 4 (effective mass 1.23 x), the drag then fitted beside the cubic
    and the search ended at 0.99 x noise with the hidden set, where it named an extra hysteresis at
    3.48 x (docs/nuisance-discovery.md). A fit of the record's first part keeps its starts."""
    from tether.discover import search
    from tether.discover.fitting import ModelFit
    from tether.models import parse_model

    stem, tr = _write(tmp_path, "forced", "forced", (), 3, noise=1e-5, rate=100.0, nuisance=True,
                      mass_factor=1.25, offset_noise=4.0, preroll_s=0.0)
    trace, truth = read_trace(stem), tr.meta["hidden"]["nuisance"]
    seen = []
    monkeypatch.setattr(search, "fit_model", lambda tr_, sp, eff, starts, sc, **kw: seen.append(starts))
    s = search.Search.__new__(search.Search)
    s.trace, s.part, s.shape_free, s.shape_held, s.fit_cap, s.deadline, s.nuisance = trace, object(), (), (), 1.0, None, ()
    s.own_work_ratio = lambda *a: 1.0
    s.cur = ModelFit(spec=parse_model("linear"), effects=(), params={"EA": 1.0, "m": truth["m_true"],
                     "offset_measured": truth["offset_measured"]}, free=["EA"], rms=1.0, predicted=None)
    s.fit(trace, parse_model("linear+nonlinear_damping"), ("nonlinear_damping",), [{"EA": 2.0}, None], None,
          cap_factor=1.0)
    given, data = seen[0]
    assert given == {"EA": 2.0}
    assert data["m"] == truth["m_true"] and data["offset_measured"] == truth["offset_measured"]
    assert data["EA"] / trace.length_m == pytest.approx(tr.meta["hidden"]["derived"]["k_lin_N_m"], rel=5e-3)
    s.fit(s.part, parse_model("linear"), (), [None], None, cap_factor=1.0)
    assert seen[1] == [None]
