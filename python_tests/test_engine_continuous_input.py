"""The engine's fits integrate on through the samples where a record's input pieces join
(kt_fit_options.continuous_input, on by default) instead of restarting CVODE at every sample as
the FMU does when an importer sets its input (kt_simulate keeps that exact step sequence).

Checked through kt_fit with no iteration, whose RMS is that of the start's residuals:
1. a driven undamped oscillator against its closed form: both ways to the integration tolerance,
   and the fit's way is not the FMU's step sequence (the speed-up is in effect);
2. where the input's pieces do not join, the fit restarts exactly where the FMU does: a held
   (piecewise-constant) force, and a load rig with a straight line between samples (its equations
   see the load's rate, which jumps at every sample), give the FMU's trajectory bit for bit;
3. a periodic record (its period's end joins its start) agrees with the exact sequence to the
   tolerance;
4. a law with reversal memory (Kawabata) keeps the FMU's step sequence: a load back at an earlier
   turning load rejoins or reverses by a hair, as the FMU's switches at the samples decide; the
   Iwan bank, whose force is continuous in the strain's path, carries on, to the tolerance;
5. a creep test's loads, held for hours and changed between two samples (PCHIP ramps whose
   curvature jumps where they meet the holds): every change is seen.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "python"))
from tether import identify_native as idn  # noqa: E402

M, L0, EA = 4.3, 16.0, 3500.0
# a linear payload oscillator at rest at its balance (x is measured from there), taut throughout
OSCILLATOR = {"rig": 2, "stiffness": 1, "damping": 1, "hysteresis": 1, "creep": 0, "slack": 0, "m": M, "L0": L0,
              "g": 9.81, "EA": EA, "c0": 0.0, "x0": 0.0, "v0": 0.0}


def start_rms(exp: idn.Experiment, continuous: int) -> float:
    """The RMS of exp's residuals as a fit sees them (kt_fit, no iteration; the one free parameter,
    offset_measured, starts at 0 exactly)."""
    r = idn.fit([exp], {"offset_measured": (-1.0, 1.0, 0.0)}, scaling={"offset_measured": "linear"},
                max_iterations=0, central_differences=idn.FORWARD, n_threads=1, continuous_input=continuous)
    return float(r.rms)


def test_a_driven_oscillator_follows_its_closed_form_with_and_without_restarts():
    t = np.arange(4001) * 1e-3
    F0, Om = 8.0, 2 * np.pi * 3.0
    w = np.sqrt(EA / L0 / M)
    f = F0 * np.sin(Om * t)
    x = F0 / (M * (w ** 2 - Om ** 2)) * (np.sin(Om * t) - Om / w * np.sin(w * t))
    e = idn.Experiment(t, settings=OSCILLATOR, input_kind=idn.INPUT_FORCE, input=f,
                       input_der=idn.spline_derivatives(t, f), measured=x)
    amp = float(np.max(np.abs(x)))
    exact = start_rms(e, 0)
    carried_on = start_rms(e, 1)
    assert exact <= 1e-7 * amp
    assert carried_on <= 1e-7 * amp
    assert carried_on != exact


def test_a_held_force_restarts_at_every_sample_as_the_fmu_does():
    t = np.arange(1001) * 2e-3
    f = 6.0 * np.sin(2 * np.pi * 1.7 * t) + 0.5 * (np.arange(len(t)) % 2)   # held: it jumps at every sample
    e = idn.Experiment(t, settings=OSCILLATOR, input_kind=idn.INPUT_FORCE, input=f, input_der=np.zeros((len(t), 3)))
    e.measured = idn.simulate(e)
    assert np.ptp(e.measured) > 1e-3
    assert start_rms(e, 1) == 0.0


def test_a_load_whose_rate_jumps_restarts_at_every_sample_as_the_fmu_does():
    t = np.arange(801) * 1e-2
    load = np.random.default_rng(3).uniform(10.0, 30.0, len(t))
    der = np.zeros((len(t), 3))
    der[:-1, 0] = np.diff(load) / np.diff(t)                     # straight lines: the value joins, the rate not
    e = idn.Experiment(t, settings={"rig": 3, "stiffness": 2, "hysteresis": 1, "L0": L0}, input_kind=idn.INPUT_LOAD,
                       input=load, input_der=der, output="elongation")
    e.measured = idn.simulate(e)
    assert np.ptp(e.measured) > 1e-3
    assert start_rms(e, 1) == 0.0
    # the same load as a spline joins (value and rate): the fit carries on, to the tolerance
    e.input_der = idn.spline_derivatives(t, load)
    e.measured = idn.simulate(e)
    rms = start_rms(e, 1)
    assert 0.0 < rms <= 1e-7 * np.max(np.abs(e.measured))


def test_a_periodic_record_carries_on_through_its_period_to_the_tolerance():
    P, periods, dt = 500, 2, 2e-3
    tp = np.arange(P) * dt
    f1 = 8.0 * np.sin(2 * np.pi * tp) + 2.0 * np.sin(6 * np.pi * tp)
    d1 = idn.spline_derivatives(tp, f1, periodic=True)
    settings = dict(OSCILLATOR, c0=20.0)
    t = np.arange(P * periods) * dt
    e = idn.Experiment(t, settings=settings, input_kind=idn.INPUT_FORCE, input=np.tile(f1, periods),
                       input_der=np.tile(d1, (periods, 1)), periodic_samples=P, periodic_tol=1e-10)
    e.measured = idn.simulate(e)
    rms = start_rms(e, 1)
    assert 0.0 < rms <= 1e-7 * np.max(np.abs(e.measured))


def test_a_kawabata_load_test_back_at_an_earlier_turning_load_keeps_the_fmus_switches():
    # the load returns to the turning load of t = 60 s at t = 160 s: whether the branch rejoins the
    # older one there or reverses first is decided by the switches the FMU makes at the samples
    # (to a hair); a fit of a law with reversal memory keeps the FMU's step sequence
    t = np.linspace(0.0, 200.0, 2001)
    load = 100.0 * np.interp(t, [0, 40, 60, 100, 120, 160, 200], [0, 1, 1, 0.3, 0.3, 1, 0])
    settings = {"rig": 3, "stiffness": 2, "hysteresis": 2, "L0": L0, "kaw_LT": 0.7, "kaw_RT": 0.5,
                "kaw_F_ref": 88.0, "kaw_residual": 0.1, "offset_input": 2.0}
    from scipy.interpolate import PchipInterpolator

    pchip = PchipInterpolator(t, load)                          # as a load trace is driven
    der = np.column_stack([pchip(t, 1), pchip(t, 2), pchip(t, 3)])
    e = idn.Experiment(t, settings=settings, input_kind=idn.INPUT_LOAD, input=load, input_der=der,
                       output="elongation")
    e.measured = idn.simulate(e)
    assert np.ptp(e.measured) > 1e-2
    assert start_rms(e, 1) == 0.0


def test_an_iwan_load_test_back_at_an_earlier_turning_load_carries_on_to_the_tolerance():
    # the same load program on the Iwan bank: a reversal a hair earlier or later moves each play
    # operator by a hair, so the fit carries on through the joined pieces and stays within the
    # integration tolerance of the FMU's trajectory
    from scipy.interpolate import PchipInterpolator

    t = np.linspace(0.0, 200.0, 2001)
    load = 100.0 * np.interp(t, [0, 40, 60, 100, 120, 160, 200], [0, 1, 1, 0.3, 0.3, 1, 0])
    bank = {f"iw_k{i + 1}": k for i, k in enumerate([300.0, 200.0, 150.0, 100.0])}
    bank.update({f"iw_eps{i + 1}": e for i, e in enumerate([2e-4, 6e-4, 1.5e-3, 4e-3])})
    settings = {"rig": 3, "stiffness": 2, "hysteresis": 4, "L0": L0, "offset_input": 2.0, **bank}
    pchip = PchipInterpolator(t, load)
    der = np.column_stack([pchip(t, 1), pchip(t, 2), pchip(t, 3)])
    e = idn.Experiment(t, settings=settings, input_kind=idn.INPUT_LOAD, input=load, input_der=der,
                       output="elongation")
    e.measured = idn.simulate(e)
    bare = idn.simulate(idn.Experiment(t, settings={**settings, "hysteresis": 1}, input_kind=idn.INPUT_LOAD,
                                       input=load, input_der=der, output="elongation"))
    assert np.max(np.abs(e.measured - bare)) > 1e-3 * np.ptp(e.measured)     # the bank takes part
    rms = start_rms(e, 1)
    assert 0.0 < rms <= 1e-7 * np.ptp(e.measured)


def test_a_load_held_for_hours_and_stepped_within_a_sample_is_seen_at_every_step():
    # a creep test's program: loads held for hours, sampled every 5 s, changed between two samples;
    # PCHIP makes each change a ramp piece whose value and rate join the holds on both sides, but
    # whose curvature jumps there. An integrator carried on through the holds takes steps of hours
    # and can step over a whole ramp (the load rig's strain follows the load's rate): the fit
    # restarts where the curvature jumps, so every elongation is the held load's, L0 F / EA
    from scipy.interpolate import PchipInterpolator

    dt, hours = 5.0, [6.1, 2.0, 6.3, 7.6, 5.1, 5.4]
    holds = [100.0, 5.0, 100.0, 5.0, 91.7, 5.0]
    ends = np.cumsum(hours) * 3600.0
    t = np.arange(0.0, ends[-1], dt)
    load = np.array([holds[int(np.searchsorted(ends, s, side="right"))] for s in t])
    load[0] = 0.0                                                 # hung at the first sample
    pchip = PchipInterpolator(t, load)
    der = np.column_stack([pchip(t, 1), pchip(t, 2), pchip(t, 3)])
    e = idn.Experiment(t, settings={"rig": 3, "stiffness": 1, "hysteresis": 1, "L0": L0, "EA": EA},
                       input_kind=idn.INPUT_LOAD, input=load, input_der=der, output="elongation")
    e.measured = idn.simulate(e)
    held = L0 * load / EA
    assert np.max(np.abs(e.measured - held)) <= 1e-9 * np.max(held)
    assert start_rms(e, 1) <= 1e-9 * np.max(held)
