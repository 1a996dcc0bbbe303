"""The held-out test's split of a record (discover.samples.heldout_split): the last part of the
record, and in a creep test the last part of each load level, which a fit of the rest never sees
(Trace.fitted_samples, the engine's sample weights)."""

from __future__ import annotations

import copy

import numpy as np

from tether.discover.samples import heldout_split, load_levels
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
    assert load_levels(tr) == [(0, 1), (1, 721), (721, 1261)]
    part, held = heldout_split(tr, 0.6)
    expected = np.zeros(1261, bool)
    expected[1 + 432:721] = True       # 40 % of the hold's 720 samples
    expected[721 + 324:1261] = True    # 40 % of the recovery's 540
    assert np.array_equal(held, expected)
    # the fit simulates the whole record and sees the rest
    assert np.array_equal(part.time, tr.time) and np.array_equal(part.fitted_samples, ~expected)


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
