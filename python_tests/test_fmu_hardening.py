"""Issue 27, the FMU side: no call sequence or saved state crashes the FMU, a step never stalls.

- F1: every fmi2 function returns fmi2Error on a NULL or a foreign component (no crash).
- F2-F4: a restored state is checked field by field: a NaN displacement (with the damping table
  on), a run state that no saved instance is in (0, fatal), a switch outside its values (rig =
  1e6), a parameter outside its declared range, a corrupt Kawabata memory... are refused with
  fmi2Error and a message naming the field and the value, through fmi2DeSerializeFMUstate and
  through fmi2SetFMUstate, and the instance is left as it was (it continues like an untouched twin).
- F5: the Kawabata + slack + displacement-damping payload under a steady force comes to rest:
  fmi2DoStep(0, 5) succeeds and the tension then settles, smooth, at m g + f.
- The stiffness cap of Kawabata minor loops (docs/models.md): along nested loops of decaying
  amplitude, no tangent of the tension exceeds the cap.

Crashing cases run in a subprocess, so that a crash is a failed test, not a dead test run.
"""
from __future__ import annotations

import math
import struct
import subprocess
import sys
import textwrap
from ctypes import (POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p, create_string_buffer,
                    memmove)

import numpy as np
import pytest

import fmu_harness as H
from fmu_harness import fmi2Error, fmi2OK

# ---- F1: NULL and foreign components ----------------------------------------------------------
# every fmi2 function that takes a component, with its argument types after the component
# ('d' double, 'i' int, 'z' size_t, 'p' pointer); sizes are nonzero and pointers NULL
SIGNATURES = {
    "fmi2SetDebugLogging": "izp", "fmi2SetupExperiment": "iddid", "fmi2EnterInitializationMode": "",
    "fmi2ExitInitializationMode": "", "fmi2Terminate": "", "fmi2Reset": "",
    "fmi2GetReal": "pzp", "fmi2GetInteger": "pzp", "fmi2GetBoolean": "pzp", "fmi2GetString": "pzp",
    "fmi2SetReal": "pzp", "fmi2SetInteger": "pzp", "fmi2SetBoolean": "pzp", "fmi2SetString": "pzp",
    "fmi2GetFMUstate": "p", "fmi2SetFMUstate": "p", "fmi2FreeFMUstate": "p", "fmi2SerializedFMUstateSize": "pp",
    "fmi2SerializeFMUstate": "ppz", "fmi2DeSerializeFMUstate": "pzp", "fmi2GetDirectionalDerivative": "pzpzpp",
    "fmi2EnterEventMode": "", "fmi2NewDiscreteStates": "p", "fmi2EnterContinuousTimeMode": "",
    "fmi2CompletedIntegratorStep": "ipp", "fmi2SetTime": "d", "fmi2SetContinuousStates": "pz",
    "fmi2GetDerivatives": "pz", "fmi2GetEventIndicators": "pz", "fmi2GetContinuousStates": "pz",
    "fmi2GetNominalsOfContinuousStates": "pz", "fmi2SetRealInputDerivatives": "pzpp",
    "fmi2GetRealOutputDerivatives": "pzpp", "fmi2DoStep": "ddi", "fmi2CancelStep": "",
    "fmi2GetStatus": "ip", "fmi2GetRealStatus": "ip", "fmi2GetIntegerStatus": "ip",
    "fmi2GetBooleanStatus": "ip", "fmi2GetStringStatus": "ip",
}

PROBE = textwrap.dedent("""
    import ctypes, sys
    from ctypes import c_double, c_int, c_size_t, c_void_p
    lib = ctypes.CDLL(sys.argv[1])
    which = sys.argv[2]
    sigs = {sigs!r}
    types = dict(d=c_double, i=c_int, z=c_size_t, p=c_void_p)
    values = dict(d=0.5, i=1, z=3, p=None)
    foreign = ctypes.create_string_buffer(bytes((i * 37 + 11) % 256 for i in range(4096)))
    comp = None if which == "null" else ctypes.cast(foreign, c_void_p)
    for name, sig in sigs.items():
        f = getattr(lib, name)
        f.restype = c_int
        f.argtypes = [c_void_p] + [types[k] for k in sig]
        print(name, f(comp, *[values[k] for k in sig]), flush=True)
    lib.fmi2FreeInstance.argtypes = [c_void_p]
    lib.fmi2FreeInstance(comp)
    print("fmi2FreeInstance returned", flush=True)
""").format(sigs=SIGNATURES)


@pytest.mark.parametrize("which", ["null", "foreign"])
def test_every_function_refuses_a_null_or_foreign_component(which):
    """F1: fmi2CancelStep(NULL) wrote through NULL; every function now returns fmi2Error."""
    r = subprocess.run([sys.executable, "-c", PROBE, str(H.binary_path()), which],
                       capture_output=True, text=True)
    lines = r.stdout.splitlines()
    assert r.returncode == 0, f"the probe died (exit {r.returncode}) after: {lines[-1:]}\n{r.stderr[-2000:]}"
    statuses = dict(line.rsplit(" ", 1) for line in lines[:-1])
    assert set(statuses) == set(SIGNATURES)
    wrong = {name: s for name, s in statuses.items() if int(s) != fmi2Error}
    assert not wrong, f"not fmi2Error on a {which} component: {wrong}"
    assert lines[-1] == "fmi2FreeInstance returned"


# ---- F2-F4: a restored state trusts nothing -----------------------------------------------------
# distinctive values, found again in the serialized bytes to locate their fields
SENTINELS = dict(m=4.30001234567, L0=16.0001234567, x0=0.0101234567, c_table_dx=0.0501234567,
                 c_table_1=2.01234567, c0=1.501234567)
TOLERANCE = 1.01234567e-8
PAYLOAD = dict(rig=2, stiffness=1, damping=2, hysteresis=2, slack=True, **SENTINELS)


def new_instance():
    inst = H.Instance("cs")
    inst.check(inst.setup(TOLERANCE), "fmi2SetupExperiment")
    inst.set_all(PAYLOAD)
    inst.check(inst.enter_init(), "fmi2EnterInitializationMode")
    inst.check(inst.exit_init(), "fmi2ExitInitializationMode")
    return inst


def offsets(blob: bytes, value: float) -> list[int]:
    pat = struct.pack("<d", value)
    return [i for i in range(len(blob) - 7) if blob[i:i + 8] == pat]


class Layout:
    """Where the fields of a serialized state are, found from the sentinels (and checked)."""

    def __init__(self, blob: bytes):
        self.blob = blob
        rtol = offsets(blob, TOLERANCE)
        assert len(rtol) == 1, "rtol not found once in the state"
        # tether_params starts with the switches: int rig, stiffness, damping, hysteresis, creep,
        # slack, integrator, then (aligned) double rtol
        self.rig = rtol[0] - 32
        got = struct.unpack_from("<7i", blob, self.rig)
        assert got[:4] == (2, 1, 2, 2) and got[5] == 1, f"switches not where expected: {got}"
        # the header: magic, (version,) size, the GUID in 40 bytes, then the run state
        guid = blob.find(H.model_description().guid.encode())
        assert guid > 0, "the GUID is not in the state"
        self.run_state = guid + 40
        assert struct.unpack_from("<i", blob, self.run_state)[0] == 1 << 4, "run state (step complete) not found"
        L0 = offsets(blob, SENTINELS["L0"])
        assert len(L0) == 1
        self.L0 = L0[0]
        # tether_inputs: L0, elongation, elongation_rate, force, load, force_der[3], load_der[3],
        # t_ref; then tether_discrete: int taut, the Kawabata memory {int n, int direction, ...}
        # aligned to 8 bytes
        self.taut = self.L0 + 12 * 8
        self.kaw_n = self.taut + 8
        self.kaw_direction = self.taut + 12
        taut, n, direction = struct.unpack_from("<i4xii", blob, self.taut)
        assert taut == 1 and 1 <= n <= 64 and direction in (1, -1), f"discrete state not where expected: {taut, n, direction}"
        # the end: the nine states (displacement first), time, last successful time, start time
        self.displacement = len(blob) - 8 * (len(H.STATE_NAMES) + 3)
        t, t_ok, t0 = struct.unpack_from("<3d", blob, len(blob) - 24)
        assert t == t_ok and t > 0 and t0 == 0.0, f"times not where expected: {t, t_ok, t0}"
        self.m = offsets(blob, SENTINELS["m"])[0]

    def with_int(self, field: str, value: int) -> bytes:
        b = bytearray(self.blob)
        struct.pack_into("<i", b, getattr(self, field), value)
        return bytes(b)

    def with_double(self, field: str, value: float) -> bytes:
        b = bytearray(self.blob)
        struct.pack_into("<d", b, getattr(self, field), value)
        return bytes(b)


def saved(inst) -> bytes:
    state = inst.fmu.getFMUstate()
    blob = bytes(inst.fmu.serializeFMUstate(state))
    inst.fmu.freeFMUstate(state)
    return blob


def deserialize(inst, data: bytes):
    buf = create_string_buffer(data, len(data))
    state = c_void_p()
    st = inst.call("fmi2DeSerializeFMUstate", [c_char_p, c_size_t, POINTER(c_void_p)], buf, len(data), byref(state))
    return st, state


HOSTILE = [  # (field, kind, value, words the error names)
    ("displacement", "d", math.nan, ["displacement", "nan"]),
    ("displacement", "d", math.inf, ["displacement", "inf"]),
    ("run_state", "i", 256, ["run state = 256"]),
    ("run_state", "i", 0, ["run state = 0"]),
    ("run_state", "i", 1, ["run state = 1"]),          # instantiated: a state is never saved there
    ("run_state", "i", 1 << 4 | 1 << 5, ["run state = 48"]),
    ("run_state", "i", -2**31, ["run state = -2147483648"]),
    ("rig", "i", 1_000_000, ["rig = 1000000"]),
    ("rig", "i", 0, ["rig = 0"]),
    ("m", "d", -1.0, ["m = -1"]),
    ("m", "d", 0.0, ["m = 0"]),                         # in range, but the payload rig needs m > 0
    ("L0", "d", math.nan, ["L0 = nan"]),
    ("taut", "i", 7, ["taut = 7"]),
    ("kaw_n", "i", 65, ["Kawabata reversal count = 65"]),
    ("kaw_n", "i", -1, ["Kawabata reversal count = -1"]),
    ("kaw_direction", "i", 0, ["Kawabata direction = 0"]),
]


def twin_outputs(inst, steps=20):
    out = []
    for k in range(steps):
        inst.check(inst.do_step(1.0 + 0.01 * k, 0.01), "fmi2DoStep")
        out.append(inst.get_reals_raw([H.vr("tension"), H.vr("displacement")])[1])
    return np.array(out)


@pytest.mark.parametrize("field,kind,value,needles", HOSTILE, ids=[f"{f}={v}" for f, _, v, _ in HOSTILE])
def test_hostile_state_is_refused_and_changes_nothing(field, kind, value, needles):
    """F2-F4: through fmi2DeSerializeFMUstate and through fmi2SetFMUstate (a good state whose
    memory is then overwritten), the hostile field is refused, named with its value, and the
    instance continues exactly like a twin that was never offered the state."""
    inst, twin = new_instance(), new_instance()
    for i in (inst, twin):
        i.check(i.do_step(0.0, 1.0), "fmi2DoStep")
    layout = Layout(saved(inst))
    saved(twin)                      # saving restarts CVODE (docs): the twin does the same
    bad = layout.with_int(field, value) if kind == "i" else layout.with_double(field, value)

    st, state = deserialize(inst, bad)
    assert st == fmi2Error and not state.value, "fmi2DeSerializeFMUstate accepted the bytes"
    msg = inst.log.with_status(fmi2Error)[-1]
    for needle in needles:
        assert needle in msg, f"{needle!r} not in {msg!r}"

    st, state = deserialize(inst, layout.blob)              # a good state ...
    assert st == fmi2OK
    memmove(state.value, bad, len(bad))                      # ... whose memory is then corrupted
    st = inst.call("fmi2SetFMUstate", [c_void_p], state)
    assert st == fmi2Error, "fmi2SetFMUstate accepted the state"
    msg = inst.log.with_status(fmi2Error)[-1]
    for needle in needles:
        assert needle in msg, f"{needle!r} not in {msg!r}"
    inst.fmu.freeFMUstate(state)

    np.testing.assert_array_equal(twin_outputs(inst), twin_outputs(twin))
    inst.free()
    twin.free()


def test_good_state_still_restores_bit_for_bit():
    """The checks refuse nothing a real run saves: the sentinel state, restored into a new
    instance, continues exactly like the original."""
    inst = new_instance()
    inst.check(inst.do_step(0.0, 1.0), "fmi2DoStep")
    blob = saved(inst)
    copy = new_instance()
    st, state = deserialize(copy, blob)
    assert st == fmi2OK
    copy.check(copy.call("fmi2SetFMUstate", [c_void_p], state), "fmi2SetFMUstate")
    copy.fmu.freeFMUstate(state)
    np.testing.assert_array_equal(twin_outputs(copy), twin_outputs(inst))
    inst.free()
    copy.free()


NAN_STATE_PROBE = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import test_fmu_hardening as T, math
    inst = T.new_instance()
    inst.check(inst.do_step(0.0, 0.1), "fmi2DoStep")
    bad = T.Layout(T.saved(inst)).with_double("displacement", math.nan)
    st, state = T.deserialize(inst, bad)
    if st == 0:
        inst.call("fmi2SetFMUstate", [T.c_void_p], state)
        print("step", inst.do_step(0.1, 0.1), inst.get_reals_raw([T.H.vr("tension")]), flush=True)
    print("deserialize", st, flush=True)
""")


def test_nan_displacement_with_the_damping_table_does_not_crash():
    """F2 as reported: a state with a NaN displacement and c_table_dx > 0 once indexed the damping
    table with (int)NaN (SIGSEGV). Run in a subprocess: it must exit cleanly, the state refused."""
    import os
    env = dict(os.environ, KT_FMU=str(H.require_fmu()))
    r = subprocess.run([sys.executable, "-c", NAN_STATE_PROBE, str(H.REPO / "python_tests")],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, f"crashed (exit {r.returncode}):\n{r.stdout}\n{r.stderr[-2000:]}"
    assert f"deserialize {fmi2Error}" in r.stdout, r.stdout


def test_fatal_state_cannot_be_restored_and_reset_does_not_revive_it():
    """F3: a state claiming the fatal run state is refused; the instance stays usable, and its
    FMU states can always be freed (no leak)."""
    inst = new_instance()
    inst.check(inst.do_step(0.0, 0.5), "fmi2DoStep")
    layout = Layout(saved(inst))
    st, state = deserialize(inst, layout.with_int("run_state", 256))
    assert st == fmi2Error and not state.value
    inst.check(inst.do_step(0.5, 0.5), "fmi2DoStep after the refused state")
    inst.check(inst.call("fmi2Reset", []), "fmi2Reset")
    inst.free()


# ---- F5: a steady force on Kawabata + slack + displacement damping ------------------------------
F5 = dict(rig=2, stiffness=1, damping=2, hysteresis=2, slack=True, force=100.0)


def test_steady_force_on_kawabata_payload_comes_to_rest():
    """F5: fmi2DoStep(0, 5) once ended in fmi2Discard after 100,000 events (a storm of Kawabata
    reversals at ~1e4 Hz with the strain fixed to 1e-10). Now it succeeds with a few dozen events;
    over the next second (1 ms samples) the tension is a smooth, slow, decaying vibration (it turns
    only at the reversal events, at most 30 times a second, by less than 0.2 N per ms, against swings
    of 2.7 N within 0.1 ms before), and by t = 30 s the payload is at rest: no more events, velocity
    zero, tension the static balance m g + f."""
    inst = H.cs(F5, categories=["logEvents"])
    assert inst.do_step(0.0, 5.0) == fmi2OK, inst.log.with_status(2)
    events = [len(inst.log.in_category("logEvents"))]
    m, g = inst.get("m", "g")
    balance = m * g + F5["force"]
    out = H.run_cs(inst, 5.0 + np.arange(1001) * 1e-3, ["tension"])
    events.append(len(inst.log.in_category("logEvents")))
    inst.check(inst.do_step(6.0, 14.0), "fmi2DoStep(6, 14)")
    events.append(len(inst.log.in_category("logEvents")))
    inst.check(inst.do_step(20.0, 10.0), "fmi2DoStep(20, 10)")
    events.append(len(inst.log.in_category("logEvents")))
    T_rest, v_rest = inst.get("tension", "velocity")
    inst.free()
    T = out["tension"]
    dT = np.diff(T)
    turns = int(np.sum(np.sign(dT[1:]) != np.sign(dT[:-1])))
    print(f"F5: events {np.diff([0] + events).tolist()} in [0, 5], [5, 6], [6, 20], [20, 30] s; in [5, 6] s the "
          f"tension turns {turns} times, largest 1 ms change {np.abs(dT).max():.3g} N; at 30 s tension {T_rest:.9g} N, "
          f"velocity {v_rest:.2e} m/s, balance m g + f = {balance:.9g} N")
    assert events[0] < 500
    assert turns <= 30 and turns <= events[1] - events[0] + 2, "the tension turns between reversals"
    assert np.abs(dT).max() < 0.2
    assert events[3] == events[2], "events go on at rest"
    assert abs(T_rest - balance) < 1e-6 * balance and abs(v_rest) < 1e-6


# ---- the stiffness cap of Kawabata minor loops ---------------------------------------------------
def set_input_rate(inst, name, rate):
    return inst.call("fmi2SetRealInputDerivatives", [POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)],
                     (c_uint * 1)(H.vr(name)), 1, (c_int * 1)(1), (c_double * 1)(rate))


def test_kawabata_minor_loops_never_stiffer_than_the_cap():
    """Load rig (the strain follows the Kawabata law under the load): the load rises to a peak on
    the virgin curve, then swings about a mean with an amplitude that shrinks by only 4 % per half
    cycle, as a decaying vibration does (F5): each reversal falls in the steep start of the last
    unloading branch, so the loops nest. The largest secant stiffness dT/deps between samples stays
    below KAWABATA_STIFFNESS_CAP (10) times the outer unloading branch's start stiffness
    q F(R1) / ((1 - r) eps(R1)), in closed form from the parameters. Uncapped, each nested loop was
    about twice as stiff as its parent: 68 times the cap after 60 half cycles."""
    LT, RT, r, e_ref, F_ref = 0.7, 0.5, 0.1, 0.02, 88.0
    p, q = 2 / LT - 1, 2 * (1 - r) / (RT * LT) - 1
    F_peak, F_mean = 160.0, 142.0
    e_peak = e_ref * (F_peak / F_ref) ** (1 / p)
    K_cap = 10 * q * F_peak / ((1 - r) * e_peak)
    legs, F, amp, sign = [np.linspace(0, F_peak, 100), np.linspace(F_peak, F_mean, 50)[1:]], F_mean, 15.0, 1
    for _ in range(60):
        target = F_mean + sign * amp
        legs.append(np.linspace(F, target, 30)[1:])
        F, amp, sign = target, amp * 0.96, -sign
    load = np.concatenate(legs)
    inst = H.cs(dict(rig=3, stiffness=1, damping=1, hysteresis=2, slack=False, L0=16.0, load=0.0,
                     kaw_LT=LT, kaw_RT=RT, kaw_residual=r, kaw_eps_ref=e_ref, kaw_F_ref=F_ref))
    strain = [inst.get("strain")]
    for k in range(len(load) - 1):            # one leg piece per step, the load linear in time
        inst.check(inst.set_real([H.vr("load")], [load[k]]), "set load")
        inst.check(set_input_rate(inst, "load", load[k + 1] - load[k]), "fmi2SetRealInputDerivatives")
        inst.check(inst.do_step(float(k), 1.0), "fmi2DoStep")
        strain.append(inst.get("strain"))
    inst.free()
    de, dT = np.diff(strain), np.diff(load)
    secant = dT[de != 0] / de[de != 0]
    print(f"Kawabata minor loops: largest secant stiffness {secant.max():.4g} N, cap {K_cap:.4g} N "
          f"(10 x the outer unloading start {K_cap / 10:.4g} N)")
    assert secant.max() <= K_cap * (1 + 1e-3)
    assert secant.min() > 0.0, "load and strain move in opposite directions"


def test_engine_agrees_with_the_fmu_on_the_steady_force_trace():
    """The identification engine runs the FMU's physics: on the F5 model's forced trace (2,001
    samples, 5 ms, constant 100 N; 17 s of chattering for either before) both give the same
    displacement and tension, settling (within 0.03 N over the last second) at the balance m g + f."""
    from test_identify_engine import _fmu_path, idn, run_fmu
    t = np.arange(2001) * 5e-3
    f = np.full_like(t, 100.0)
    der = idn.spline_derivatives(t, f)
    settings = dict(rig=2, stiffness=1, damping=2, hysteresis=2, slack=True, m=4.3, g=9.81, L0=16.0, x0=0.0)
    T_fmu = run_fmu(_fmu_path(), t, settings, output="tension", input_name="force", inp=f, der=der)
    x_fmu = run_fmu(_fmu_path(), t, settings, input_name="force", inp=f, der=der)
    e = idn.Experiment(t, settings=settings, input_kind=idn.INPUT_FORCE, input=f, input_der=der)
    x_eng = idn.simulate(e)
    T_eng = idn.simulate(e, outputs=["tension"])[:, 0]
    assert np.max(np.abs(x_eng - x_fmu)) <= 1e-9
    assert np.max(np.abs(T_eng - T_fmu)) <= 1e-9 * np.max(np.abs(T_fmu))
    balance = 4.3 * 9.81 + 100.0
    assert np.abs(T_fmu[-200:] - balance).max() < 2e-4 * balance, "not settling at the balance"


def test_a_step_that_would_take_for_ever_stops_at_its_step_budget():
    """A non-stiff solver forced onto the stiff load rig (tracking time 1 ms) asked for 1e5 s in one
    step would take ~1e8 CVODE steps: the step stops at its budget of 200,000 steps with
    fmi2Discard, says how many steps and events it took and where it stopped, and
    fmi2LastSuccessfulTime is that point."""
    inst = H.cs(dict(rig=3, creep=True, integrator=3, load=60.0), categories=["logStatusDiscard"])
    assert inst.do_step(0.0, 1e5) == 2
    st, t_reached = inst.last_successful_time()
    msg = inst.log.in_category("logStatusDiscard")[-1]
    inst.free()
    assert st == fmi2OK and 0.0 < t_reached < 1e5
    assert "200000 solver steps and 0 events within one step" in msg and f"{t_reached:.17g}" in msg, msg
