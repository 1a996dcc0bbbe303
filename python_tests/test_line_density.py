"""The tether line's own mass in the payload rig (issue 30): parameter ``line_density`` w [kg/m].

Expectations come from outside the model:
1. the first mode of a hanging mass m on a uniform linear elastic line (EA, L0, w), no damping:
   omega = beta sqrt(EA / w) / L0 with beta tan(beta) = w L0 / m (the classical bar with an end
   mass; beta found here by scipy's brentq), the period measured from the FMU's zero crossings;
2. the static stretch of a linear line under its own weight and the payload's, integrated along
   the line: (m + w L0 / 2) g L0 / EA;
3. a second implementation of the driver: the identification engine against the FMU through fmpy;
4. bad values refused with messages naming the variable (or the file and key) and the value;
5. the trace key ``tether.line_density_kg_m`` reaches the FMU (tether.simulate), the engine
   (experiment_from_trace) and a fit (tether.fit).
"""
from __future__ import annotations

import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import fmu_harness as H

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "python"))
from tether import identify_native as idn  # noqa: E402
from tether.traces import TraceError, read_trace  # noqa: E402

M, L0, EA, G = 4.3, 16.0, 5.0e4, 9.81
LINEAR_UNDAMPED = {"rig": 2, "stiffness": 1, "damping": 1, "hysteresis": 1, "creep": False, "slack": False,
                   "m": M, "L0": L0, "EA": EA, "c0": 0.0, "g": G, "rtol": 1e-10}


def first_mode_beta(mu: float) -> float:
    """The root in (0, pi/2) of beta tan(beta) = mu."""
    return brentq(lambda b: b * math.tan(b) - mu, 1e-300, math.pi / 2 - 1e-15, xtol=1e-15, rtol=1e-15)


def closed_form_period(mu: float) -> float:
    if mu == 0.0:
        return 2 * math.pi * math.sqrt(M * L0 / EA)
    w = mu * M / L0
    return 2 * math.pi * L0 / (first_mode_beta(mu) * math.sqrt(EA / w))


def measured_period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean period between the first and the last upward zero crossing (fmu_harness's; the
    curvature of a sine vanishes at its zeros, so the linear interpolation there is exact enough)."""
    period, crossings = H.period_by_zero_crossings(t, x)
    assert crossings >= 5, f"only {crossings} upward zero crossings"
    return period


def fmu_free_vibration(w: float, periods: float = 8.0, h: float = 1.234e-4, **settings):
    """Free vibration from x0 = -1 mm sampled every h (not a divisor of the period, so that the
    zero crossings fall between samples)."""
    T = closed_form_period(w * L0 / M)
    inst = H.cs(dict(LINEAR_UNDAMPED, line_density=w, x0=-1e-3, **settings))
    try:
        r = H.run_cs(inst, H.grid(periods * T, h), ["displacement", "balance_elongation"])
    finally:
        inst.free()
    return r


# ---- 1. the first mode of a hanging mass on an elastic line ------------------------------------
@pytest.mark.parametrize("mu", [0.0, 0.1, 0.5, 1.0, 2.0])
def test_period_of_a_hanging_mass_on_an_elastic_line_with_mass(mu):
    w = mu * M / L0
    r = fmu_free_vibration(w)
    T_meas = measured_period(r["time"], r["displacement"])
    T_exact = closed_form_period(mu)
    err = T_meas / T_exact - 1.0
    # the plain rule m + w L0 / 3 (the first estimate), for the record
    T_third = 2 * math.pi * math.sqrt((M + w * L0 / 3) * L0 / EA)
    note = (f"mu = w L0 / m = {mu}: period {T_meas:.9g} s measured, {T_exact:.9g} s closed form "
            f"(error {err:+.2e}); the plain m + w L0/3 rule gives {T_third:.9g} s "
            f"({T_third / T_exact - 1.0:+.2e} from the closed form)")
    print(note)
    assert abs(err) <= 5e-3, note
    # far better than the acceptance: the FMU integrates the exact first-mode mass at rtol 1e-10
    assert abs(err) <= 1e-6, note


@pytest.mark.parametrize("mu", [1e-12, 1e-6, 0.999e-3, 1.001e-3, 0.03, 5.0, 30.0, 100.0, 1e4])
def test_period_over_the_whole_range_of_line_to_payload_mass(mu):
    """From a line far lighter than the payload (the series) to one 10^4 times heavier (beta near
    pi/2); without gravity, so that a heavy line does not stretch beyond the law's range."""
    w = mu * M / L0
    T_exact = closed_form_period(mu)
    r = fmu_free_vibration(w, h=T_exact / 1987.3, g=0.0)
    T_meas = measured_period(r["time"], r["displacement"])
    assert T_meas == pytest.approx(T_exact, rel=1e-9), f"mu = {mu}: {T_meas!r} s measured, {T_exact!r} s closed form"


def test_the_plain_third_rule_misses_the_first_mode_where_the_fmu_does_not():
    mu = 1.0
    w = mu * M / L0
    r = fmu_free_vibration(w)
    T_meas = measured_period(r["time"], r["displacement"])
    T_exact = closed_form_period(mu)
    T_third = 2 * math.pi * math.sqrt((M + w * L0 / 3) * L0 / EA)
    third_err = T_third / T_exact - 1.0
    assert abs(T_meas / T_exact - 1.0) < 0.01 * abs(third_err), (
        f"measured {T_meas:.9g} s, closed form {T_exact:.9g} s, plain m + w L0/3 rule {T_third:.9g} s "
        f"(misses by {third_err:+.3%})")


# ---- 2. the static stretch ------------------------------------------------------------------------
@pytest.mark.parametrize("w", [0.0, 0.05, 0.3, 2.0])
def test_balance_elongation_carries_half_the_line_weight(w):
    inst = H.cs(dict(LINEAR_UNDAMPED, line_density=w))
    try:
        u_bal = inst.get("balance_elongation")
        T0, x0 = inst.get("tension", "displacement")
    finally:
        inst.free()
    expected = (M + w * L0 / 2) * G * L0 / EA
    assert u_bal == pytest.approx(expected, rel=1e-9, abs=0.0)
    assert x0 == 0.0
    assert T0 == pytest.approx((M + w * L0 / 2) * G, rel=1e-9)


@pytest.mark.parametrize("mu", [0.0, 1e-5, 0.1, 1.0, 100.0])
def test_effective_mass_output_is_the_first_mode_mass(mu):
    w = mu * M / L0
    inst = H.cs(dict(LINEAR_UNDAMPED, line_density=w))
    try:
        got = inst.get("effective_mass")
    finally:
        inst.free()
    expected = M if mu == 0.0 else w * L0 / first_mode_beta(mu) ** 2
    assert got == pytest.approx(expected, rel=1e-13, abs=0.0)
    assert got == pytest.approx(M + w * L0 / 3, rel=mu / 40 + 1e-15)    # Rayleigh's third, to first order
    e = idn.Experiment(np.arange(3) * 1e-3, settings=dict(LINEAR_UNDAMPED, line_density=w))
    assert idn.simulate(e, outputs=["effective_mass"])[0, 0] == got


# ---- 3. the engine and the FMU agree ---------------------------------------------------------------
def test_engine_equals_fmu_on_a_forced_payload_record_with_line_density():
    from test_identify_engine import FULL, TRUTH_FULL, run_fmu

    fmu = H.require_fmu()
    t = np.arange(4001) * 1e-3
    f = 6.0 * np.sin(2 * np.pi * 1.3 * t) + 3.0 * np.sin(2 * np.pi * 3.7 * t + 1.0)
    der = idn.spline_derivatives(t, f)
    settings = dict(FULL, x0=0.02, v0=-0.1, line_density=0.2, **TRUTH_FULL)   # mu = 0.74
    e = idn.Experiment(t, settings=settings, input_kind=idn.INPUT_FORCE, input=f, input_der=der)
    x_eng = idn.simulate(e)
    x_fmu = run_fmu(fmu, t, settings, input_name="force", inp=f, der=der)
    x_massless = idn.simulate(idn.Experiment(t, settings=dict(settings, line_density=0.0), input_kind=idn.INPUT_FORCE,
                                             input=f, input_der=der))
    assert np.max(np.abs(x_eng - x_massless)) > 1e-3, "the line density changes nothing"
    assert np.max(np.abs(x_eng - x_fmu)) <= 1e-9
    T_fmu = run_fmu(fmu, t, settings, output="tension", input_name="force", inp=f, der=der)
    T_eng = idn.simulate(e, outputs=["tension"])[:, 0]
    assert np.max(np.abs(T_eng - T_fmu)) <= 1e-9 * max(1.0, np.max(np.abs(T_fmu)))


# ---- 4. bad values ----------------------------------------------------------------------------------
@pytest.mark.parametrize("value, shown", [(-0.1, "-0.1"), (float("nan"), "nan"), (float("inf"), "inf")])
def test_fmu_refuses_a_bad_line_density(value, shown):
    inst = H.Instance("cs")
    try:
        inst.check(inst.setup(), "fmi2SetupExperiment")
        status = inst.set("line_density", value)
        log = str(inst.log)
    finally:
        inst.free()
    assert status == H.fmi2Error, f"fmi2SetReal(line_density = {value}) returned {status}; log:\n{log}"
    assert "line_density" in log and shown in log.lower(), log


@pytest.mark.parametrize("value, shown", [(-0.1, "-0.1"), (float("nan"), "nan"), (float("-inf"), "-inf")])
def test_engine_refuses_a_bad_line_density(value, shown):
    t = np.arange(11) * 1e-3
    e = idn.Experiment(t, settings=dict(LINEAR_UNDAMPED, line_density=value))
    with pytest.raises((RuntimeError, ValueError)) as ei:
        idn.simulate(e)
    msg = str(ei.value)
    assert "line_density" in msg and shown in msg.lower(), msg


@pytest.mark.parametrize("value, fragments", [(-0.02, ("value -0.02", ">= 0")),
                                              ("0.02", ('value "0.02"', "not a number"))])
def test_trace_with_a_bad_line_density_is_refused_naming_file_and_key(write_trace, value, fragments):
    meta = write_trace.meta(tether={"length_m": 16.0, "line_density_kg_m": value})
    stem = write_trace("t", meta, {"time": [0.0, 0.1, 0.2], "displacement": [0.1, 0.0, -0.1]})
    with pytest.raises(TraceError) as ei:
        read_trace(stem)
    msg = str(ei.value)
    for frag in ("t.json", "'tether.line_density_kg_m'") + fragments:
        assert frag in msg, f"{frag!r} not in {msg!r}"


def test_the_published_trace_schema_knows_the_key():
    import json

    jsonschema = pytest.importorskip("jsonschema")
    schema = json.loads((REPO / "docs" / "schemas" / "tether-trace-1.schema.json").read_text())
    doc = {"format": "tether-trace/1", "experiment": "free_vibration", "payload_mass_kg": M,
           "tether": {"length_m": L0, "line_density_kg_m": 0.02}}
    jsonschema.validate(doc, schema)
    doc["tether"]["line_density_kg_m"] = -0.02
    with pytest.raises(jsonschema.ValidationError, match="minimum"):
        jsonschema.validate(doc, schema)


# ---- 4b. a restored state is checked for the line density and the masses it gave ---------------
def _payload_with_line(w):
    inst = H.cs(dict(LINEAR_UNDAMPED, line_density=w, x0=0.01))
    inst.check(inst.do_step(0.0, 0.05), "fmi2DoStep")
    return inst


def _serialized(inst) -> bytes:
    state = inst.fmu.getFMUstate()
    blob = bytes(inst.fmu.serializeFMUstate(state))
    inst.fmu.freeFMUstate(state)
    return blob


def _offset(blob: bytes, value: float) -> int:
    pat = struct.pack("<d", value)
    found = [i for i in range(len(blob) - 7) if blob[i:i + 8] == pat]
    assert len(found) == 1, f"{value!r} found {len(found)} times in the state"
    return found[0]


W_SENTINEL = 0.0301234567   # a distinctive line density, found again in the serialized bytes


@pytest.mark.parametrize("field, value, needles", [
    ("line_density", -1.0, ["line_density = -1"]),
    ("line_density", math.nan, ["line_density = nan"]),
    ("carried_mass", math.inf, ["carried mass = inf"]),
    ("effective_mass", 0.0, ["effective mass = 0"]),
    ("effective_mass", math.nan, ["effective mass = nan"]),
])
def test_a_restored_state_with_a_bad_line_density_or_mass_is_refused(field, value, needles):
    from ctypes import POINTER, byref, c_char_p, c_size_t, c_void_p, create_string_buffer

    inst = _payload_with_line(W_SENTINEL)
    try:
        blob = _serialized(inst)
        where = {"line_density": _offset(blob, W_SENTINEL)}
        # tether_discrete: balance_elongation, then the carried and the effective mass
        where["carried_mass"] = _offset(blob, M + 0.5 * W_SENTINEL * L0)
        where["effective_mass"] = where["carried_mass"] + 8
        M_eff = struct.unpack_from("<d", blob, where["effective_mass"])[0]
        assert M_eff == pytest.approx(M * (W_SENTINEL * L0 / M) / first_mode_beta(W_SENTINEL * L0 / M) ** 2, rel=1e-13)
        bad = bytearray(blob)
        struct.pack_into("<d", bad, where[field], value)
        buf = create_string_buffer(bytes(bad), len(bad))
        state = c_void_p()
        st = inst.call("fmi2DeSerializeFMUstate", [c_char_p, c_size_t, POINTER(c_void_p)], buf, len(bad),
                       byref(state))
        assert st == H.fmi2Error and not state.value, "fmi2DeSerializeFMUstate accepted the bytes"
        msg = inst.log.with_status(H.fmi2Error)[-1]
        for needle in needles:
            assert needle in msg, f"{needle!r} not in {msg!r}"
        # the good state restores into a fresh instance and continues bit for bit
        copy = _payload_with_line(W_SENTINEL)
        try:
            good = create_string_buffer(blob, len(blob))
            copy.check(copy.call("fmi2DeSerializeFMUstate", [c_char_p, c_size_t, POINTER(c_void_p)], good,
                                 len(blob), byref(state)), "fmi2DeSerializeFMUstate")
            copy.check(copy.call("fmi2SetFMUstate", [c_void_p], state), "fmi2SetFMUstate")
            copy.fmu.freeFMUstate(state)
            a = H.run_cs(inst, [0.05, 0.1, 0.15], ["displacement"])["displacement"]
            b = H.run_cs(copy, [0.05, 0.1, 0.15], ["displacement"])["displacement"]
            np.testing.assert_array_equal(a, b)
        finally:
            copy.free()
    finally:
        inst.free()


# ---- 5. the trace key reaches the FMU, the engine and a fit ---------------------------------------
def _free_vibration_trace(write_trace, w, displacement=None, n=4001, h=1e-3, name="line"):
    t = np.arange(n) * h
    tether = {"length_m": L0} if w is None else {"length_m": L0, "line_density_kg_m": w}
    meta = write_trace.meta(tether=tether, payload_mass_kg=M, gravity_m_s2=G, initial_displacement_m=-0.01)
    x = np.zeros(n) if displacement is None else displacement
    return read_trace(write_trace(name, meta, {"time": t, "displacement": x}))


def test_trace_without_the_key_has_a_massless_line(write_trace):
    assert _free_vibration_trace(write_trace, None).line_density_kg_m == 0.0


def test_trace_line_density_reaches_the_fmu_and_the_engine(write_trace):
    import tether

    mu = 0.5
    trace = _free_vibration_trace(write_trace, mu * M / L0)
    assert trace.line_density_kg_m == pytest.approx(mu * M / L0, rel=1e-15)
    params = {"EA": EA, "c0": 0.0, "rtol": 1e-10}
    T_exact = closed_form_period(mu)
    fmu = tether.simulate(trace, "linear", params)
    T_fmu = measured_period(fmu.time, fmu.predicted)
    eng = idn.simulate(idn.experiment_from_trace(trace, {"stiffness": 1, "damping": 1, **params}))
    T_eng = measured_period(trace.time, eng)
    assert T_fmu == pytest.approx(T_exact, rel=1e-5), f"FMU through tether.simulate: {T_fmu} s"
    assert T_eng == pytest.approx(T_exact, rel=1e-5), f"engine through experiment_from_trace: {T_eng} s"


def test_payload_masses_of_a_trace(write_trace):
    """The fit's data-based start takes the weight's and the inertia's mass from here."""
    assert idn.payload_masses(_free_vibration_trace(write_trace, None)) == (M, M)
    w = 1.0 * M / L0
    m_w, m_eff = idn.payload_masses(_free_vibration_trace(write_trace, w, name="heavy"))
    assert m_w == pytest.approx(M + w * L0 / 2, rel=1e-15)
    assert m_eff == pytest.approx(w * L0 / first_mode_beta(1.0) ** 2, rel=1e-13)


def test_fit_of_a_trace_with_line_density_recovers_the_stiffness(write_trace):
    """A record made with the line's mass is fitted with it: EA and c0 come back; with a massless
    line the period would need EA / 1.16 (mu = 0.5)."""
    import tether

    mu, truth = 0.5, {"EA": EA, "c0": 2.0}
    w = mu * M / L0
    t = np.arange(4001) * 1e-3
    e = idn.Experiment(t, settings=dict(LINEAR_UNDAMPED, line_density=w, x0=-0.01))
    x = idn.simulate(e, truth)
    x_noisy = x + 1e-6 * np.random.default_rng(3).standard_normal(len(t))
    trace = _free_vibration_trace(write_trace, w, displacement=x_noisy)
    r = tether.fit(trace, "linear", free=["EA", "c0"])
    assert r.values["EA"] == pytest.approx(EA, rel=1e-3)
    assert r.values["c0"] == pytest.approx(2.0, rel=2e-2)
