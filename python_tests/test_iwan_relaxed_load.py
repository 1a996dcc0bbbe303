"""A load-rig record whose Iwan bank was last unloaded at a load before the record
(iwan_relaxed_load; the FMU's closed-form tests are in test_fmu_iwan.py): the nuisance parameter's
rules, and a fit that frees it on a record drawn by the engine from a tether shaken down under its
first load, against the same fit from a virgin bank. Measured figures are printed as 'FIGURE ...'
lines (pytest -s shows them)."""
from __future__ import annotations

import numpy as np

from tether import nuisance as NZ
from tether.models import parse_model
from tether.traces import read_trace

#: four elements slipping from 1e-4 to 1.5e-3 of strain beside a linear law
BANK = dict(iw_k1=150.0, iw_eps1=1e-4, iw_k2=200.0, iw_eps2=3e-4, iw_k3=250.0, iw_eps3=7e-4, iw_k4=300.0,
            iw_eps4=1.5e-3) | {f"iw_k{i}": 0.0 for i in range(5, 17)}


def _load_unload(write_trace, name, load, elongation):
    t = np.arange(0.0, float(len(load)), 1.0)
    return read_trace(write_trace(name, write_trace.meta("load_unload"),
                                  {"time": t, "load": np.asarray(load, float), "elongation": elongation}))


def test_the_relaxed_load_is_a_nuisance_of_load_rig_records_with_a_bank(write_trace):
    load = np.concatenate([np.full(10, 5.0), np.linspace(5.0, 50.0, 40), np.linspace(50.0, 5.0, 40)])
    pre = _load_unload(write_trace, "pre", load, 1e-4 * load)
    zero = _load_unload(write_trace, "zero", np.concatenate([[0.0], load]), 1e-4 * np.concatenate([[0.0], load]))
    assert NZ.refusal(pre, "iwan_relaxed_load") is None
    assert "first load is 0 N" in NZ.refusal(zero, "iwan_relaxed_load")
    assert NZ.law_refusal("iwan_relaxed_load", parse_model("linear+iwan", "load_unload")) is None
    assert "hysteresis is boucwen" in NZ.law_refusal("iwan_relaxed_load", parse_model("linear+boucwen", "load_unload"))
    lo, hi, start, scaling = NZ.nuisance_box(pre, "iwan_relaxed_load")
    assert (lo, hi, start, scaling) == (0.0, 50.0, 0.0, "linear")
    grid = NZ.relaxed_load_grid(pre)
    assert grid[0] == 0.0 and 5.0 in grid and grid[-1] == 50.0 and all(b > a for a, b in zip(grid, grid[1:]))
    assert NZ.stated_values(pre)["iwan_relaxed_load"] == 0.0


def test_a_fit_with_the_relaxed_load_free_finds_a_tether_shaken_down_under_its_first_load(write_trace):
    """Drawn by the engine with the bank unloaded at the first load (10 N), then loops to 60, 20, 45
    and back to 10 N: a fit of the bank's stiffnesses from a virgin bank misses the record; with
    iwan_relaxed_load free it reaches the noise and its interval holds the 10 N."""
    from tether.discover.fitting import predict
    from tether.fit import fit_traces

    nodes = [10.0, 60.0, 20.0, 45.0, 10.0]
    load = np.concatenate([np.linspace(a, b, 30)[:-1] for a, b in zip(nodes[:-1], nodes[1:])] + [[10.0]])
    spec = parse_model("linear+iwan", "load_unload")
    truth = dict(EA=3000.0, iwan_relaxed_load=10.0) | BANK
    blank = _load_unload(write_trace, "blank", load, 0 * load)
    noise = 2e-5
    u = predict(blank, spec, truth) + np.random.default_rng(4).normal(0.0, noise, len(load))
    trace = _load_unload(write_trace, "shaken_down", load, u)
    free = ["EA", "iw_k1", "iw_k2", "iw_k3", "iw_k4"]
    start = dict(EA=2500.0, iw_k1=100.0, iw_k2=100.0, iw_k3=100.0, iw_k4=100.0)
    fixed = {k: v for k, v in BANK.items() if k not in free}
    virgin = fit_traces([trace], "linear+iwan", free=free, start=start, fixed=fixed)
    relaxed = fit_traces([trace], "linear+iwan", free=free + ["iwan_relaxed_load"], start=start, fixed=fixed)
    lo, hi = relaxed.intervals["iwan_relaxed_load"]
    print(f"FIGURE a bank shaken down under its first load of 10 N: from a virgin bank {virgin.rms / noise:.2f} x "
          f"noise; the relaxed load free {relaxed.rms / noise:.2f} x noise, at {relaxed.values['iwan_relaxed_load']:.3f} N "
          f"[{lo:.3f}, {hi:.3f}]")
    assert virgin.rms > 1.5 * noise
    assert relaxed.rms < 1.1 * noise
    assert lo <= 10.0 <= hi and hi - lo < 2.0
