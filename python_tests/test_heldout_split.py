"""The held-out test's split of a record (discover.samples.heldout_split): the last part of the
record, and in a load-controlled record the last part of each stretch of the load (a ramp up, a
ramp down, a hold), which a fit of the rest never sees (Trace.fitted_samples, the engine's sample
weights)."""

from __future__ import annotations

import copy

import numpy as np

from tether.discover.samples import heldout_split, load_stretches
from tether.fit import fit_traces
from tether.fit.experiments import predict, trace_experiment
from tether.models import parse_model
from tether.traces import Trace

EA, L0 = 20000.0, 2.0


def _creep_test(load_noise: float = 0.0, seed: int = 5) -> Trace:
    """A load test of a linear tether: 1 N at t = 0, 100 N for 720 samples, 5 N for 540 (the
    generator's campaigns hold 2 h and recover 1.5 h at 10 s a sample), its elongation exact."""
    t = 10.0 * np.arange(1261)
    load = np.where(t <= 0, 1.0, np.where(t <= 7200, 100.0, 5.0))
    load = load + load_noise * np.random.default_rng(seed).standard_normal(load.size)
    return Trace.from_arrays(t, experiment="creep", length_m=L0, load=load, elongation=load * L0 / EA,
                             name="creep_test")


def test_a_creep_test_holds_out_the_last_part_of_each_load_level():
    tr = _creep_test(load_noise=0.5)   # a measured load: its noise is no level change
    assert load_stretches(tr) == [(0, 721), (721, 1261)]   # the 1 N sample at t = 0 joins the hold after it
    part, held = heldout_split(tr, 0.6)
    expected = np.zeros(1261, bool)
    expected[433:721] = True           # 40 % of the hold's 721 samples
    expected[721 + 324:1261] = True    # 40 % of the recovery's 540
    assert np.array_equal(held, expected)
    # the fit simulates the whole record and sees the rest
    assert np.array_equal(part.time, tr.time) and np.array_equal(part.fitted_samples, ~expected)


def _load_unload_test(load_noise: float, seed: int = 2) -> tuple[Trace, list]:
    """A load test of a linear tether sampled each second: 5 N, up to 100 N over 60 s, held 120 s,
    down to 40 N over 30 s, up to 80 N over 20 s, down to 5 N over 38 s, held 90 s (the second
    generator's load-unload schedule); and the corners of its load, the samples where each stretch
    begins."""
    corners = [0, 60, 180, 210, 230, 268, 359]
    levels = [5.0, 100.0, 100.0, 40.0, 80.0, 5.0, 5.0]
    t = np.arange(359.0)
    load = np.interp(t, corners, levels)
    load = load + load_noise * np.random.default_rng(seed).standard_normal(load.size)
    tr = Trace.from_arrays(t, experiment="load_unload", length_m=L0, load=load, elongation=load * L0 / EA,
                           name="load_unload_test")
    return tr, corners


def test_a_load_test_holds_out_the_last_part_of_each_ramp_and_hold():
    """Each ramp and hold of the load is a stretch, cut at its corners (within a sample where the
    load is measured with noise of 0.2 N, a fifth of its change per sample on the slowest ramp); the
    fit of the part sees the first 60 % of each, so it sees the load fall and the recovery's hold."""
    for noise in (0.0, 0.2):
        tr, corners = _load_unload_test(noise)
        got = load_stretches(tr)
        assert len(got) == len(corners) - 1, (noise, got)
        assert got[-1][1] == 359 and all(abs(a - c) <= 1 for (a, _), c in zip(got, corners[:-1])), (noise, got)
        part, held = heldout_split(tr, 0.6)
        for a, b in got:
            seen = np.flatnonzero(~held[a:b])
            assert seen.size and seen[-1] == seen.size - 1 and abs(seen.size - 0.6 * (b - a)) <= 0.5, (a, b)
        falling = np.r_[np.diff(tr.input) < 0, False]
        assert np.any(falling & part.fitted_samples) and np.any(falling & held)


def test_other_records_hold_out_their_last_part():
    t = np.arange(1000) * 1e-3
    tr = Trace.from_arrays(t, experiment="free_vibration", length_m=1.0, payload_mass_kg=2.0,
                           displacement=1e-2 * np.cos(40 * t), initial_displacement_m=1e-2)
    part, held = heldout_split(tr, 0.6)
    assert len(part.time) == 600 and part.fitted_samples is None
    assert np.array_equal(held, np.arange(1000) >= 600)


def test_a_fit_of_the_part_never_sees_the_held_out_samples():
    tr = _creep_test()
    ruined = copy.copy(tr)
    ruined.measured = tr.measured.copy()
    part, held = heldout_split(tr, 0.6)
    ruined.measured[held] += 1e-3      # a tenth of the elongation at 100 N
    ruined_part = copy.copy(part)
    ruined_part.measured = ruined.measured
    fits = [fit_traces([p], "linear", free=["EA"], start={"EA": 15000.0}) for p in (part, ruined_part)]
    assert fits[0].values["EA"] == fits[1].values["EA"]
    assert abs(fits[0].values["EA"] / EA - 1) < 1e-6
    # its error is the one over the samples it saw, as computed here from its prediction
    y = predict(trace_experiment(ruined, parse_model("linear"), {}), {**fits[1].parameters})
    seen = ~held
    assert np.isclose(fits[1].rms_per_trace[0], np.sqrt(np.mean((y - ruined.measured)[seen] ** 2)), rtol=1e-9)
    # the whole ruined record moves it
    whole = fit_traces([ruined], "linear", free=["EA"], start={"EA": 15000.0})
    assert abs(whole.values["EA"] / EA - 1) > 0.02
