"""Acceptance tests of the KevlarTether FMU: FMI 2.0 conformance.

- Every error path of the FMI layer returns fmi2Error and logs, through the logger callback, a
  message naming the function and the offending variable or value (errors are logged even with
  logging off).
- fmi2Discard from a step that cannot be completed, with fmi2LastSuccessfulTime inside the step.
- The warning when the cubic law is driven past its rising range.
- Model Exchange: 9 states, 4 event indicators, states and derivatives in the order of the XML.
- Static checks: fmpy validation, fmutool -check, the binary's dependencies and exported symbols.
"""
import ctypes
import os
import re
import shutil
import subprocess
import sys
import zipfile
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p, create_string_buffer
from pathlib import Path

import numpy as np
import pytest

import fmu_harness as H
from fmu_harness import fmi2Discard, fmi2Error, fmi2OK, fmi2Warning


def single_error(inst, status, *needles):
    """The call returned fmi2Error and logged one error naming all needles."""
    assert status == fmi2Error, f"expected fmi2Error, got {H.STATUS_NAMES.get(status, status)}; log:\n{inst.log}"
    errors = inst.log.with_status(fmi2Error)
    assert errors, "fmi2Error returned without a logged message"
    msg = errors[-1]
    for needle in needles:
        assert needle in msg, f"{needle!r} not in the error message {msg!r}"
    assert inst.log.in_category("logStatusError")
    print(f"FIGURE 5 error: {msg}")
    return msg


def fresh(values=None, initialise=False, kind="cs"):
    inst = H.Instance(kind)
    if initialise:
        inst.initialize(values or {})
    elif values:
        inst.set_all(values)
    return inst


# ---- 5. error paths ------------------------------------------------------------------------------
def test_wrong_guid_at_instantiate_returns_null_and_logs():
    from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions
    md = H.model_description()
    holder = FMU2Slave(guid=md.guid, unzipDirectory=str(H.unpacked()), modelIdentifier="KevlarTether",
                       instanceName="unused")
    name = H.unique_name("badguid")
    proto = ctypes.CFUNCTYPE(c_void_p, c_char_p, c_int, c_char_p, c_char_p,
                                           POINTER(fmi2CallbackFunctions), c_int, c_int)
    instantiate = proto(("fmi2Instantiate", holder.dll))
    wrong = "{00000000-0000-0000-0000-000000000000}"
    comp = instantiate(name.encode(), H.fmi2CoSimulation, wrong.encode(), b"file:///tmp",
                       byref(H.callbacks()), 0, 0)
    holder.freeLibrary()
    assert comp is None
    errors = H.log_of(name).with_status(fmi2Error)
    assert errors and "fmi2Instantiate" in errors[-1] and wrong in errors[-1], H.log_of(name)
    print(f"FIGURE 5 error: {errors[-1]}")


def test_do_step_before_initialisation():
    inst = fresh()
    single_error(inst, inst.do_step(0.0, 1e-3), "fmi2DoStep", "instantiated")
    inst.free()


def test_set_fixed_parameter_after_initialisation():
    inst = fresh(initialise=True)
    single_error(inst, inst.set("m", 5.0), "fmi2SetReal", "'m'", "fixed")
    inst.free()
    inst = fresh(initialise=True)
    single_error(inst, inst.set("rig", 1), "fmi2SetInteger", "'rig'")
    inst.free()
    inst = fresh(initialise=True)
    single_error(inst, inst.set("slack", False), "fmi2SetBoolean", "'slack'")
    inst.free()


def test_model_exchange_function_on_co_simulation_instance_and_vice_versa():
    inst = fresh(initialise=True)
    x = (c_double * 9)()
    single_error(inst, inst.call("fmi2GetDerivatives", [POINTER(c_double), c_size_t], x, 9),
                 "fmi2GetDerivatives", "Model Exchange", "Co-Simulation")
    inst.free()
    me = fresh(initialise=True, kind="me")
    single_error(me, me.do_step(0.0, 1e-3), "fmi2DoStep", "Co-Simulation", "Model Exchange")
    me.free()


@pytest.mark.parametrize("function", ["fmi2GetReal", "fmi2SetReal", "fmi2GetInteger", "fmi2GetBoolean"])
def test_unknown_value_reference(function):
    inst = fresh(initialise=function != "fmi2SetReal")
    refs = (c_uint * 1)(999)
    if function in ("fmi2GetReal", "fmi2SetReal"):
        buf = (c_double * 1)(1.0)
        status = inst.call(function, [POINTER(c_uint), c_size_t, POINTER(c_double)], refs, 1, buf)
    else:
        buf = (c_int * 1)()
        status = inst.call(function, [POINTER(c_uint), c_size_t, POINTER(c_int)], refs, 1, buf)
    single_error(inst, status, function, "999")
    inst.free()


@pytest.mark.parametrize("name, value, needle", [("rtol", 1.0, "rtol = 1"), ("L0", -1.0, "L0 = -1"),
                                                 ("rig", 7, "rig = 7"), ("rtol", 1e-15, f"rtol = {1e-15:.17g}"),
                                                 ("c_drag", -0.5, "c_drag = -0.5"), ("pow_n", 0.5, "pow_n = 0.5"),
                                                 ("pow_F", -2.0, "pow_F = -2"), ("c_coulomb", -0.5, "c_coulomb = -0.5"),
                                                 ("coulomb_v", -1e-3, "coulomb_v = -0.001")])
def test_value_out_of_range(name, value, needle):
    inst = fresh()
    single_error(inst, inst.set(name, value), "fmi2Set", needle)
    inst.free()


@pytest.mark.parametrize("values, needle", [
    (dict(rig=2, m=0.0), "m = 0"),
    (dict(rig=2, damping=2, coulomb_v=0.0), "coulomb_v = 0 m/s"),  # inside the variable's min, but no scale
    (dict(rig=3, stiffness=2, load=500.0), "load = 500"),  # more than the cubic carries, load rig
    (dict(rig=2, stiffness=2, m=50.0), "m = 50"),  # 490 N > the 378 N the default cubic carries
    # a1 tiny against a2, a3 (a fit's iterate): the law turns down at a strain of 3e-162, so it
    # carries no weight; the balance search once missed that root and doubled its bracket for ever
    (dict(rig=2, stiffness=2, m=5.09, a1=2.4362802596204755e-153, a2=-380659340.83380359,
          a3=-1329625219.2758133), "m = 5.09"),
])
def test_bad_parameters_at_initialisation(values, needle):
    inst = fresh(values)
    inst.check(inst.setup(), "fmi2SetupExperiment")
    inst.check(inst.enter_init(), "fmi2EnterInitializationMode")
    single_error(inst, inst.exit_init(), "fmi2ExitInitializationMode", needle)
    inst.free()


@pytest.mark.parametrize("t, h, needles", [
    (0.5, 1e-3, ["currentCommunicationPoint = 0.5"]),
    (0.0, 0.0, ["communicationStepSize = 0"]),
    (0.0, -1e-3, ["communicationStepSize = -0.001"]),
])
def test_do_step_bad_communication_point_or_step(t, h, needles):
    inst = fresh(initialise=True)
    single_error(inst, inst.do_step(t, h), "fmi2DoStep", *needles)
    inst.free()


@pytest.mark.parametrize("name, order, needles", [
    ("L0", 1, ["'L0'", "takes no derivative"]),
    ("elongation", 1, ["'elongation'", "takes no derivative"]),
    ("force", 4, ["order = 4", "'force'"]),
])
def test_set_real_input_derivatives_errors(name, order, needles):
    inst = fresh(initialise=True)
    status = inst.call("fmi2SetRealInputDerivatives", [POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)],
                       (c_uint * 1)(H.vr(name)), 1, (c_int * 1)(order), (c_double * 1)(1.0))
    single_error(inst, status, "fmi2SetRealInputDerivatives", *needles)
    inst.free()


def serialized_state():
    inst = fresh(dict(x0=0.1), initialise=True)
    inst.check(inst.do_step(0.0, 0.1), "fmi2DoStep")
    state = inst.fmu.getFMUstate()
    blob = bytes(inst.fmu.serializeFMUstate(state))
    inst.fmu.freeFMUstate(state)
    inst.free()
    return blob


@pytest.mark.parametrize("case", ["wrong size", "garbage"])
def test_deserialize_wrong_size_or_garbage(case):
    blob = serialized_state()
    if case == "wrong size":
        data, needles = blob[:-8], [f"size = {len(blob) - 8}", str(len(blob))]
    else:
        data, needles = bytes(np.random.default_rng(1).integers(0, 256, len(blob), dtype=np.uint8)), ["not a state"]
    inst = fresh()
    buf = create_string_buffer(data, len(data))
    state = c_void_p()
    status = inst.call("fmi2DeSerializeFMUstate", [c_char_p, c_size_t, POINTER(c_void_p)], buf, len(data), byref(state))
    single_error(inst, status, "fmi2DeSerializeFMUstate", *needles)
    inst.free()


def test_unknown_log_category():
    inst = fresh()
    single_error(inst, inst.set_debug_logging(True, ["logEvents", "logNonsense"]), "fmi2SetDebugLogging",
                 "'logNonsense'")
    inst.free()


# ---- 5. fmi2Discard and the rising-range warning ------------------------------------------------
def test_discard_on_overwhelming_force_reports_time_reached():
    """A force of 1e300 N overflows the cubic law's tension within the step: fmi2Discard."""
    inst = H.cs(dict(x0=0.1), categories=["logStatusDiscard"])
    for k in range(5):
        inst.check(inst.do_step(k * 0.1, 0.1), "fmi2DoStep")
    inst.check(inst.set("force", 1e300), "set force")
    t0, h = 0.5, 0.5
    status = inst.do_step(t0, h)
    st, t_reached = inst.last_successful_time()
    value = c_int()
    st2 = inst.call("fmi2GetStatus", [c_int, POINTER(c_int)], 0, byref(value))  # fmi2DoStepStatus
    discards = inst.log.in_category("logStatusDiscard")
    inst.free()
    print(f"FIGURE 5 discard (force 1e300 N at t = 0.5 s, step 0.5 s): status {H.STATUS_NAMES[status]}, "
          f"fmi2LastSuccessfulTime {t_reached!r}; {discards[-1] if discards else 'no message'}")
    assert status == fmi2Discard
    assert st == fmi2OK and t0 <= t_reached < t0 + h
    assert st2 == fmi2OK and value.value == fmi2Discard
    assert discards and "fmi2DoStep" in discards[-1] and "stopped at" in discards[-1]


def test_discard_mid_step_when_the_payload_runs_away():
    """Released far beyond the cubic's range (slack off) the falling law pushes the payload away,
    m x'' ~ -a3 (x / L0)^3 blows up in finite time. The FMU stops the step with fmi2Discard as soon
    as the strain leaves +-100 % (TETHER_RUNAWAY_STRAIN), and fmi2LastSuccessfulTime is the last
    good point before that instant, which is computed here independently with scipy (and lies
    before the blow-up itself)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq
    m, g, L0, a1, a2, a3, c0, c1, x0 = 4.3, 9.81, 16.0, 1200.0, 2e5, -2e6, 1.5, 25.0, 3.0
    force = lambda e: e * (a1 + e * (a2 + e * a3))  # noqa: E731
    u_bal = brentq(lambda e: force(e) - m * g, 0.0, 0.0695) * L0

    def rhs(t, y):
        x, v = y
        return [v, g - (force((u_bal + x) / L0) + (c0 + c1 * abs(x)) * v) / m]

    def crossing(level):
        ev = lambda t, y: y[0] - level  # noqa: E731
        ev.terminal = True
        return solve_ivp(rhs, (0, 1), [x0, 0.0], method="DOP853", rtol=1e-12, atol=1e-12, events=ev).t_events[0][0]

    t_runaway = crossing(L0 - u_bal)   # strain (u_bal + x) / L0 reaches 1
    t_blow = crossing(1e7)
    inst = H.cs(dict(rig=2, stiffness=2, damping=2, slack=False, m=m, g=g, L0=L0, a1=a1, a2=a2, a3=a3,
                     c0=c0, c1=c1, c2=0.0, x0=x0), categories=["logStatusDiscard"])
    status = inst.do_step(0.0, 0.5)
    st, t_reached = inst.last_successful_time()
    messages = inst.log.in_category("logStatusDiscard")
    inst.free()
    print(f"FIGURE 5 discard at runaway: status {H.STATUS_NAMES[status]}, fmi2LastSuccessfulTime {t_reached:.10g} s, "
          f"strain 100 % reached at {t_runaway:.10g} s (scipy), blow-up at {t_blow:.10g} s")
    assert status == fmi2Discard
    assert st == fmi2OK and 0.0 < t_reached < 0.5
    assert t_reached <= t_runaway + 1e-9 and t_runaway - t_reached < 1e-4
    assert t_runaway < t_blow
    assert any("run away" in msg for msg in messages), messages


def test_warning_when_cubic_driven_past_rising_range():
    a1, a2, a3 = 1200.0, 2e5, -2e6
    limit = (-2 * a2 - np.sqrt(4 * a2 ** 2 - 12 * a3 * a1)) / (6 * a3)  # a1 + 2 a2 e + 3 a3 e^2 = 0
    inst = H.cs(dict(rig=2, stiffness=2, slack=True, x0=0.08 * 16.0 - 0.2), categories=["logStatusWarning"])
    status = inst.do_step(0.0, 0.01)
    warnings = [m for s, c, m in inst.log.records if s == fmi2Warning and c == "logStatusWarning"]
    inst.free()
    print(f"FIGURE 5 warning: status {H.STATUS_NAMES[status]}; {warnings[0] if warnings else 'none'}")
    assert status in (fmi2OK, fmi2Warning)
    assert len(warnings) == 1
    assert "cubic" in warnings[0] and f"{limit:.6g}" in warnings[0]


# ---- 6. Model Exchange -------------------------------------------------------------------------------
def me_in_continuous_time(values):
    from fmpy.fmi2 import fmi2EventInfo
    inst = fresh(kind="me")
    inst.initialize(values)
    info = fmi2EventInfo()
    inst.check(inst.call("fmi2NewDiscreteStates", [POINTER(fmi2EventInfo)], byref(info)), "fmi2NewDiscreteStates")
    inst.check(inst.call("fmi2EnterContinuousTimeMode", []), "fmi2EnterContinuousTimeMode")
    return inst


def vector_call(inst, function, n):
    x = (c_double * n)()
    return inst.call(function, [POINTER(c_double), c_size_t], x, n), list(x)


def test_model_exchange_counts():
    md = H.model_description()
    assert md.numberOfEventIndicators == 4
    assert len(md.derivatives) == 9
    inst = me_in_continuous_time({})
    assert vector_call(inst, "fmi2GetContinuousStates", 9)[0] == fmi2OK
    assert vector_call(inst, "fmi2GetEventIndicators", 4)[0] == fmi2OK
    assert vector_call(inst, "fmi2GetNominalsOfContinuousStates", 9)[0] == fmi2OK
    single_error(inst, vector_call(inst, "fmi2GetContinuousStates", 8)[0], "fmi2GetContinuousStates", "nx = 8")
    inst.free()
    inst = me_in_continuous_time({})
    single_error(inst, vector_call(inst, "fmi2GetEventIndicators", 3)[0], "fmi2GetEventIndicators", "ni = 3")
    inst.free()


def test_model_exchange_state_order_matches_the_variables():
    """Distinct values written with fmi2SetContinuousStates read back by name in the C enum's order
    (displacement, velocity, load_elongation, hysteretic_force, creep_strain_1..3, slip_strain,
    slip_capacity), and fmi2GetDerivatives equals der(<state>) in the XML's Derivatives order."""
    md = H.model_description()
    xml_states = [d.variable.derivative.name for d in md.derivatives]
    assert xml_states == H.STATE_NAMES
    x = [0.011, 0.023, 0.037, 0.5, 1.1e-5, 2.3e-5, 3.7e-5, 4.1e-5, 3.1e-4]
    # payload rig with Bouc-Wen and creep, so that every state and most derivatives matter
    for values in [dict(rig=2, hysteresis=3, creep=True), dict(rig=3, hysteresis=3, creep=True, load=30.0)]:
        inst = me_in_continuous_time(values)
        arr = (c_double * 9)(*x)
        inst.check(inst.call("fmi2SetContinuousStates", [POINTER(c_double), c_size_t], arr, 9), "fmi2SetContinuousStates")
        st, got = vector_call(inst, "fmi2GetContinuousStates", 9)
        assert st == fmi2OK and got == x
        st, der = vector_call(inst, "fmi2GetDerivatives", 9)
        assert st == fmi2OK
        by_name = inst.get(*H.STATE_NAMES)
        der_by_name = inst.get(*[f"der({n})" for n in H.STATE_NAMES])
        inst.free()
        print(f"FIGURE 6 rig {values['rig']}: states by name {by_name}\n    derivatives {der}")
        assert der == der_by_name
        if values["rig"] == 2:
            # displacement reads (u_bal + x) - u_bal: equal to rounding
            np.testing.assert_allclose(by_name[0], x[0], rtol=1e-12)
            assert by_name[1:] == x[1:]
            assert der[0] == x[1]  # der(displacement) = velocity
            nonzero = [d for i, d in enumerate(der) if i != 2]
        else:
            assert by_name[2:] == x[2:]
            nonzero = [der[2]] + der[3:]
        assert all(d != 0.0 for d in nonzero) and len(set(nonzero)) == len(nonzero), der


# ---- 7. static checks ----------------------------------------------------------------------------------
def test_fmpy_validation():
    from fmpy.validation import validate_fmu
    problems = validate_fmu(str(H.require_fmu()))
    assert problems == [], problems


def fmutool_command():
    script = Path(sys.executable).parent / "fmutool"
    if script.exists():
        return [str(script)]
    if shutil.which("fmutool"):
        return [shutil.which("fmutool")]
    return [sys.executable, "-c", "import sys; from fmu_manipulation_toolbox.cli.fmutool import fmutool; "
            "sys.argv[0] = 'fmutool'; sys.exit(fmutool())"]


def test_fmutool_check():
    r = subprocess.run(fmutool_command() + ["-input", str(H.require_fmu()), "-check"], capture_output=True,
                       text=True)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    assert "ERROR" not in out, out


def binary_from_zip(tmp_path):
    with zipfile.ZipFile(H.require_fmu()) as z:
        names = [n for n in z.namelist() if n.startswith("binaries/linux64/") and n.endswith(".so")]
        assert names == ["binaries/linux64/KevlarTether.so"], names
        return Path(z.extract(names[0], tmp_path))


def test_binary_depends_only_on_libc_and_libm(tmp_path):
    so = binary_from_zip(tmp_path)
    out = subprocess.run(["ldd", str(so)], capture_output=True, text=True, check=True).stdout
    libs = {re.split(r"\s", line.strip())[0] for line in out.splitlines() if line.strip()}
    allowed = {"linux-vdso.so.1", "libc.so.6", "libm.so.6"}
    extra = {lib for lib in libs if lib not in allowed and not re.search(r"ld-linux[-\w.]*\.so", lib)}
    print(f"FIGURE 7 ldd: {sorted(libs)}")
    assert not extra, out


def test_binary_exports_only_fmi2_symbols(tmp_path):
    so = binary_from_zip(tmp_path)
    out = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True).stdout
    symbols = [line.split()[-1] for line in out.splitlines() if line.strip()]
    others = [s for s in symbols if not s.startswith("fmi2")]
    print(f"FIGURE 7 nm: {len(symbols)} defined dynamic symbols, non-fmi2: {others}")
    assert symbols and not others
    assert os.path.getsize(so) > 0
