"""A load-rig record that starts under a preload hung before it (creep_preload_age): the creep
states start where that hold left them, in the FMU and in the identification engine, against the
closed forms of docs/models.md (Kelvin cells, primary creep) and against a record of the hold itself
(the slip law, which has no closed form); the refusals; the nuisance parameter a fit frees on
load-rig records with creep, in a fit and in a discovery (docs/discovery.md, "A preload's creep").

Every expectation is a closed form written out here or a second run of the FMU, never earlier
output. Measured figures are printed as 'FIGURE ...' lines (pytest -s shows them).
"""
from __future__ import annotations

import numpy as np
import pytest

import fmu_harness as H
from tether import identify_native as idn
from tether import nuisance as NZ
from tether.models import parse_model
from tether.traces import read_trace

L0, EA = 16.0, 3000.0
LOAD_RIG = dict(rig=3, stiffness=1, EA=EA, damping=1, hysteresis=1, creep=True, slack=False, L0=L0)
# primary creep (strain hardening, n = 0.3) beside one Kelvin cell of half an hour
PRIMARY = LOAD_RIG | dict(creep_law=2, creep_J1=1e-6, creep_tau1=1800.0, creep_J2=0.0, creep_J3=0.0,
                          primary_J=2e-6, primary_tau=30.0, primary_n=0.3)
T_HELD, AGE = 80.0, 7200.0


def _engine_strain(values: dict, grid, loads) -> np.ndarray:
    exp = idn.Experiment(np.asarray(grid, float), settings={k: float(v) for k, v in values.items() if k != "load"},
                         input_kind=idn.INPUT_LOAD, input=np.asarray(loads, float),
                         input_der=np.zeros((len(grid), 3)), output="strain")
    return idn.simulate(exp)


def test_a_preload_continues_its_hold_in_closed_form_in_the_fmu_and_the_engine():
    """Under the preload's own load held on, the record is the hold's continuation: the Kelvin cell
    J T (1 - exp(-(age + t)/tau)), the primary strain (C/n)((1 + (age + t)/tau)^n - 1), C = J T."""
    values = PRIMARY | dict(creep_preload_age=AGE, load=T_HELD)
    grid = H.grid(6 * 3600.0, 60.0)
    inst = H.cs(values)
    r = H.run_cs(inst, grid, ["strain", "slip_strain", "creep_strain_1"], inputs=lambda t: {"load": T_HELD})
    inst.free()
    since = AGE + grid
    cell = 1e-6 * T_HELD * -np.expm1(-since / 1800.0)
    C, n = 2e-6 * T_HELD, 0.3
    primary = C / n * np.expm1(n * np.log1p(since / 30.0))
    total = T_HELD / EA + cell + primary
    engine = _engine_strain(values, grid, np.full(len(grid), T_HELD))
    err_cell = float(np.max(np.abs(r["creep_strain_1"] - cell)) / cell.max())
    err_primary = float(np.max(np.abs(r["slip_strain"] - primary)) / primary.max())
    err_fmu = float(np.max(np.abs(r["strain"] - total)) / total.max())
    err_engine = float(np.max(np.abs(engine - total)) / total.max())
    print(f"FIGURE preload of {AGE:g} s at {T_HELD:g} N, then 6 h on: Kelvin cell {err_cell:.2g}, primary creep "
          f"{err_primary:.2g}, total strain FMU {err_fmu:.2g}, engine {err_engine:.2g} (relative to the largest)")
    assert err_cell < 1e-7 and err_primary < 1e-7 and err_fmu < 1e-7 and err_engine < 1e-7
    # the first sample already carries the preload's creep: a third of the cell's and most of the
    # primary strain the record would otherwise start without
    assert r["creep_strain_1"][0] > 0.98 * 1e-6 * T_HELD and r["slip_strain"][0] > 0.5 * primary[-1]


def _load_history(t, t_on):
    """A 20 N preload from 0 on; from t_on, a ramp to 90 N over 60 s, held 2 h, then 20 N again."""
    s = np.asarray(t, float) - t_on
    return np.where(s < 0, 20.0, np.where(s < 60.0, 20.0 + 70.0 * s / 60.0, np.where(s < 7260.0, 90.0, 20.0)))


def test_the_slip_law_under_a_preload_matches_a_record_of_the_hold_itself():
    """The slip law (the default creep law, no closed form): a record that starts after a preload
    of age A with creep_preload_age = A against the same FMU run through the hold itself from a
    tether free of creep; the elongations agree after the hold's time."""
    age, h = 3 * 3600.0, 10.0
    values = LOAD_RIG | dict(creep_law=1, rtol=1e-10)
    whole_grid = H.grid(age + 4 * 3600.0, h)
    inst = H.cs(values | dict(load=20.0))
    whole = H.run_cs(inst, whole_grid, ["total_elongation", "slip_strain"],
                     inputs=lambda t: {"load": float(_load_history(t, age))})
    inst.free()
    cut_grid = H.grid(4 * 3600.0, h)
    inst = H.cs(values | dict(load=20.0, creep_preload_age=age))
    cut = H.run_cs(inst, cut_grid, ["total_elongation", "slip_strain"],
                   inputs=lambda t: {"load": float(_load_history(t, 0.0))})
    inst.free()
    tail = whole_grid >= age - 1e-9
    u_whole, u_cut = whole["total_elongation"][tail], cut["total_elongation"]
    err = float(np.max(np.abs(u_cut - u_whole)) / np.max(np.abs(u_whole)))
    slip_at_cut = float(whole["slip_strain"][tail][0])
    err_slip = abs(float(cut["slip_strain"][0]) - slip_at_cut) / slip_at_cut
    print(f"FIGURE slip law, preload 20 N for {age:g} s: the cut record's elongation vs the whole run's, max "
          f"relative difference {err:.2g}; slip strain at the cut {cut['slip_strain'][0]:.6g} vs {slip_at_cut:.6g}")
    assert slip_at_cut > 0.0
    assert err_slip < 1e-5 and err < 1e-5


@pytest.mark.parametrize("extra, text", [(dict(creep_preload_age=-1.0), "creep_preload_age = -1 s"),
                                         (dict(creep_preload_age=float("nan")), "creep_preload_age = nan"),
                                         (dict(rig=2, m=4.3, g=9.81, creep_preload_age=10.0), "rig = 2")])
def test_a_preload_age_out_of_range_or_on_another_rig_is_refused_with_its_value(extra, text):
    settings = {k: float(v) for k, v in (PRIMARY | extra).items()}
    kind = idn.INPUT_LOAD if settings["rig"] == 3 else None
    exp = (idn.Experiment(np.array([0.0, 1.0]), settings=settings, input_kind=kind, input=np.array([10.0, 10.0]),
                          output="strain") if kind else idn.Experiment(np.array([0.0, 1.0]), settings=settings))
    with pytest.raises(RuntimeError, match=text):
        idn.simulate(exp)


def test_the_preload_age_is_a_nuisance_of_load_rig_records_with_creep(write_trace):
    t = np.arange(0.0, 3600.0, 10.0)
    load = read_trace(write_trace("pre", write_trace.meta("creep"),
                                  {"time": t, "load": np.full(t.size, 50.0), "elongation": 0.01 + 0 * t}))
    unloaded = read_trace(write_trace("zero", write_trace.meta("creep"),
                                      {"time": t, "load": np.where(t < 60, 0.0, 50.0), "elongation": 0 * t}))
    assert NZ.refusal(load, "creep_preload_age") is None
    assert "first load is 0 N" in NZ.refusal(unloaded, "creep_preload_age")
    assert NZ.law_refusal("creep_preload_age", parse_model("linear+creep", "creep")) is None
    assert "creep is off" in NZ.law_refusal("creep_preload_age", parse_model("cubic", "creep"))
    lo, hi, start, scaling = NZ.nuisance_box(load, "creep_preload_age")
    assert scaling == "linear" and lo == 0.0 and hi > 1e2 * 3590.0 * 0.99 and start == NZ.stated_values(load)["creep_preload_age"]
    grid = NZ.preload_age_grid(load)
    assert grid[0] == 0.0 and grid[1] == 10.0 and grid[-1] == hi and all(b > a for a, b in zip(grid, grid[1:]))
    assert NZ.stated_values(load)["creep_preload_age"] == 0.0


def test_a_fit_with_the_preload_age_free_reaches_the_noise_where_a_fit_from_rest_cannot(write_trace):
    """A creep test drawn by the engine under a 10 N preload hung for 15 minutes (one Kelvin cell of
    30 minutes, then 60 N held 3 h): `linear+creep` from rest misses the cell's relaxation the
    record starts with; the preload age freed, the fit reaches the noise and its interval holds the
    truth."""
    from tether.discover.fitting import predict
    from tether.fit import fit_traces

    t = np.arange(0.0, 4 * 3600.0, 20.0)
    load = np.where(t < 600.0, 10.0, 60.0)
    truth = dict(EA=3000.0, creep_J1=4e-6, creep_tau1=1800.0, creep_J2=0.0, creep_J3=0.0, slip_capacity0=0.0,
                 creep_preload_age=900.0)
    blank = read_trace(write_trace("blank", write_trace.meta("creep"), {"time": t, "load": load, "elongation": 0 * t}))
    noise = 2e-5
    u = predict(blank, parse_model("linear+creep", "creep"), truth) + np.random.default_rng(3).normal(0.0, noise, t.size)
    trace = read_trace(write_trace("preloaded", write_trace.meta("creep"), {"time": t, "load": load, "elongation": u}))
    free = ["EA", "creep_J1", "creep_tau1"]
    fixed = dict(creep_J2=0.0, creep_J3=0.0, slip_capacity0=0.0)
    start = dict(EA=2500.0, creep_J1=3e-6, creep_tau1=1200.0)
    rest = fit_traces([trace], "linear+creep", free=free, fixed=fixed, start=start)
    aged = fit_traces([trace], "linear+creep", free=free + ["creep_preload_age"], fixed=fixed, start=start)
    lo, hi = aged.intervals["creep_preload_age"]
    print(f"FIGURE creep test under a 10 N preload of 900 s: from rest {rest.rms / noise:.2f} x noise; preload age "
          f"free {aged.rms / noise:.2f} x noise, age {aged.values['creep_preload_age']:.0f} s [{lo:.0f}, {hi:.0f}]")
    assert rest.rms > 1.5 * noise
    assert aged.rms < 1.1 * noise
    assert lo <= 900.0 <= hi and hi - lo < 900.0


def _preloaded_load_unload(write_trace, name: str, truth: dict, noise: float):
    """A load-unload test drawn by the engine: 10 N hung ``creep_preload_age`` before the first
    sample, then 60 N for 200 s and 10 N for 200 s (ramps of 20 s, one sample a second)."""
    from tether.discover.fitting import predict

    t = np.arange(0.0, 440.0, 1.0)
    load = np.interp(t, [0.0, 20.0, 40.0, 240.0, 260.0, 440.0], [10.0, 10.0, 60.0, 60.0, 10.0, 10.0])
    blank = read_trace(write_trace(f"{name}_blank", write_trace.meta("load_unload"),
                                   {"time": t, "load": load, "elongation": 0 * t}))
    u = predict(blank, parse_model("linear+creep", "load_unload"), truth)
    u = u + np.random.default_rng(5).normal(0.0, noise, t.size)
    return read_trace(write_trace(name, write_trace.meta("load_unload"), {"time": t, "load": load, "elongation": u}))


#: a fast Kelvin cell (a minute) in balance with the preload when the record starts
FAST_CELL = dict(EA=3000.0, creep_J1=6e-6, creep_tau1=60.0, creep_J2=0.0, creep_J3=0.0, slip_capacity0=0.0,
                 creep_preload_age=3600.0)


def test_a_fit_with_the_preload_age_free_ends_no_worse_than_with_the_age_at_zero(write_trace):
    """The model with the age at 0 is inside the model with the age free, so the fit with it free
    must end at least as low, from the same start: the law is fitted with the age at its stated
    value first (tether.fit.memory.SCANNED_AFTER_LAW), then the age is scanned and freed."""
    from tether.fit import fit_traces

    noise = 2e-5
    trace = _preloaded_load_unload(write_trace, "fast_cell", FAST_CELL, noise)
    free = ["EA", "creep_J1", "creep_tau1", "offset_measured"]
    fixed = dict(creep_J2=0.0, creep_J3=0.0, slip_capacity0=0.0)
    start = dict(EA=2500.0, creep_J1=3e-6, creep_tau1=300.0)
    rest = fit_traces([trace], "linear+creep", free=free, fixed=fixed, start=start)
    aged = fit_traces([trace], "linear+creep", free=free + ["creep_preload_age"], fixed=fixed, start=start)
    print(f"FIGURE load-unload under a 10 N preload in balance with a 60 s cell: age at 0 {rest.rms / noise:.2f} x "
          f"noise, age free {aged.rms / noise:.2f} x noise (age {aged.values['creep_preload_age']:.0f} s, tau1 "
          f"{aged.values['creep_tau1']:.1f} s)")
    assert rest.rms > 1.5 * noise
    assert aged.rms <= rest.rms and aged.rms < 1.1 * noise
    assert aged.values["creep_tau1"] == pytest.approx(60.0, rel=0.1)


def test_discovery_frees_the_preload_age_and_the_fast_cells_of_a_load_unload_test(write_trace):
    """A load-unload test under a preload with a cell of a minute: discovery frees the preload's age
    (a nuisance of load-rig records whose first load is not zero) and the cells' time constants, and
    names creep alone within the noise; a record whose first load is 0 has no preload age."""
    from tether import discover as D

    noise = 2e-5
    trace = _preloaded_load_unload(write_trace, "fast_cell_d", FAST_CELL, noise)
    assert "creep_preload_age" in D.nuisance_parameters(trace)
    t = np.arange(0.0, 100.0, 1.0)
    unloaded = read_trace(write_trace("from_zero", write_trace.meta("load_unload"),
                                      {"time": t, "load": np.minimum(t, 50.0), "elongation": t * 1e-5}))
    assert "creep_preload_age" not in D.nuisance_parameters(unloaded)
    res = D.discover(trace)
    doc = D.discovery_document(res)
    print(f"FIGURE discovery of the preloaded fast cell: named {doc['added_effects']}, "
          f"{doc['rmse_final'] / noise:.2f} x noise, age {doc['nuisance']['parameters']['creep_preload_age']['value']:.0f} s, "
          f"{doc['seconds']:.1f} s")
    assert doc["added_effects"] == ["creep"]
    assert doc["rmse_final"] < 1.5 * noise


def test_the_stages_hold_the_preload_age_while_the_law_is_fitted_then_free_everything():
    """tether.fit's stages with the age free: the elastic law first (with the nuisance parameters
    that are not a law's state), then every parameter but the age, then all (the scan between)."""
    from tether.fit.engine import _stages

    free = ["EA", "creep_J1", "creep_tau1", "offset_measured", "creep_preload_age"]
    stages = _stages(free)
    assert [names for _, names in stages] == [["EA", "offset_measured"],
                                              ["EA", "creep_J1", "creep_tau1", "offset_measured"], free]
    # without the age, or with the Iwan bank's memory (scanned from the first stage's end), no such stage
    assert len(_stages(free[:-1])) == 2
    assert len(_stages(["EA", "iw_k1", "last_reversal_beyond"])) == 2
