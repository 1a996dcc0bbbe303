"""Acceptance tests of the FMU's Iwan hysteresis (hysteresis = 4: parallel Jenkins elements beside
the elastic law) against a second implementation: the hidden-effects generator's Iwan bank and
its own RK4 integrator and quasi-static solver (python_tests/hidden_effects.py), which share no
code with the FMU. Measured figures are printed as 'FIGURE ...' lines."""
import numpy as np
import pytest

import fmu_harness as H
import hidden_effects as he

M, G, L0, EA = 4.3, 9.81, 16.0, 3500.0
# a bank of eight elements with slip strains from 6e-6 to 2e-4 (amplitudes here: 1e-4 to 1e-3)
K_EL = [60.0, 40.0, 80.0, 50.0, 70.0, 30.0, 90.0, 45.0]
EPS_EL = [2e-4 * 0.6 ** (7 - i) for i in range(8)]
IWAN = dict(hysteresis=4) | {f"iw_k{i + 1}": K_EL[i] for i in range(8)} | {f"iw_eps{i + 1}": EPS_EL[i] for i in range(8)}


class _Linear:
    """the generator's interface of an elastic law, linear"""
    def __init__(self, EA):
        self.EA = EA

    def force(self, e):
        return self.EA * e

    def tangent(self, e):
        return self.EA


def generator_bank():
    return he.Iwan(K_EL, [k * e for k, e in zip(K_EL, EPS_EL)])


def generator_payload(times, x0, c0, slack):
    """The payload's displacement from balance by the generator's integrator (RK4, 1e-4 s steps,
    the bank committed after every step, slack entry and exit located inside a step)."""
    ub = M * G / EA * L0
    bank = generator_bank()
    bank.reset(ub / L0)
    bank.commit(max(ub + x0, 0.0) / L0)        # displaced monotonically from the balance
    rig = he._Rig(L0, M, G, _Linear(EA), bank, lambda x, v: c0 * v, slack, ub)
    U = rig.run(times, ub + x0, 0.0, hmax=1e-4)[0]
    return np.asarray(U) - ub, rig.slack_events


@pytest.mark.parametrize("case", ["taut", "slack"])
def test_payload_free_vibration_matches_the_generators_integration(case):
    """Released from x0 (taut: 0.01 m, below the slack point; slack: 0.25 m, the payload rises
    above the slack point on the rebound); 5 s with light viscous damping. The FMU's trajectory
    equals the second implementation's to 1e-6 of the swing, and the friction really acts (the
    same release without it decays differently by far more)."""
    slack = case == "slack"
    x0 = 0.25 if slack else 0.01
    c0 = 0.2
    values = dict(rig=2, stiffness=1, damping=1, creep=False, slack=slack, m=M, g=G, EA=EA, L0=L0, c0=c0,
                  x0=x0, rtol=1e-10)
    times = H.grid(5.0, 1e-3)
    inst = H.cs(values | IWAN, categories=["logEvents"])
    r = H.run_cs(inst, times, ["displacement", "tension"])
    reversals = sum("Iwan reversal" in m for m in inst.log.in_category("logEvents"))
    inst.free()
    plain = H.cs(values | dict(hysteresis=1))
    r0 = H.run_cs(plain, times, ["displacement"])
    plain.free()
    x_gen, slack_events = generator_payload(times, x0, c0, slack)
    swing = float(np.ptp(x_gen))
    err = float(np.max(np.abs(r["displacement"] - x_gen)))
    friction = float(np.max(np.abs(r0["displacement"] - x_gen)))
    print(f"FIGURE Iwan payload ({case}): {reversals} reversals, {slack_events} slack events in the "
          f"generator, largest |x_FMU - x_generator| {err:.3g} m over a swing of {swing:.3g} m; without "
          f"the friction {friction:.3g} m")
    assert reversals >= 8
    assert (slack_events >= 2) == slack
    assert err < 1e-6 * swing
    assert friction > 1e-2 * swing
    if slack:
        assert np.any(r["tension"] == 0.0)


def test_a_record_cut_after_a_reversal_goes_on_as_the_whole_run():
    """A run released from x_r (the bank displaced monotonically from the balance: the motion
    reverses there) and cut on its way down, 0.1 s later, before its next reversal: a record that
    starts at the cut (x0, v0 there) with last_reversal_beyond = x_r - |x0| has the bank's state
    of the whole run (Masing's rule: monotone to x_r, then back), and goes on as the generator's
    whole run does, to 1e-6 of the swing. Started with the bank displaced monotonically to x0 (0,
    the default), or with a reversal 2 mm further up, it does not: the elements remember."""
    x_r, c0, h, cut = 0.01, 0.2, 1e-3, 100            # the first minimum comes at about 0.4 s
    times = H.grid(3.0, h)
    ub = M * G / EA * L0
    bank = generator_bank()
    bank.reset(ub / L0)
    bank.commit((ub + x_r) / L0)
    rig = he._Rig(L0, M, G, _Linear(EA), bank, lambda x, v: c0 * v, False, ub)
    U, V, _ = rig.run(times, ub + x_r, 0.0, hmax=1e-4)
    x_gen, x0, v_cut = np.asarray(U) - ub, float(U[cut] - ub), float(V[cut])
    assert v_cut < 0.0 and 0.0 < x0 and np.all(np.diff(x_gen[:cut + 1]) < 0.0)   # on its way down, no reversal yet
    values = dict(rig=2, stiffness=1, damping=1, creep=False, slack=False, m=M, g=G, EA=EA, L0=L0, c0=c0,
                  x0=x0, v0=v_cut, rtol=1e-10) | IWAN
    rest = times[cut:] - times[cut]
    errors = {}
    for label, beyond in (("at x_r", x_r - x0), ("the default", 0.0), ("2 mm above x_r", x_r - x0 + 0.002)):
        inst = H.cs(values | dict(last_reversal_beyond=beyond))
        x = H.run_cs(inst, rest, ["displacement"])["displacement"]
        inst.free()
        errors[label] = float(np.max(np.abs(x - x_gen[cut:])))
    swing = float(np.ptp(x_gen[cut:]))
    print(f"FIGURE Iwan record cut after a reversal: largest |x_FMU - x_generator| over a swing of {swing:.3g} m, "
          "the last reversal " + ", ".join(f"{k} {v:.3g} m" for k, v in errors.items()))
    assert errors["at x_r"] < 1e-6 * swing
    assert errors["the default"] > 1e-3 * swing and errors["2 mm above x_r"] > 1e-4 * swing


def test_last_reversal_beyond_must_be_finite():
    """A NaN last reversal is refused when set, the message naming it and its value."""
    inst = H.Instance("cs")
    st = inst.set("last_reversal_beyond", float("nan"))
    errors = inst.log.with_status(H.fmi2Error)
    inst.free()
    assert st == H.fmi2Error and errors and "last_reversal_beyond = nan" in errors[-1], errors


def test_load_rig_loops_match_the_generators_quasi_static_solution():
    """A load program with nested loops (0 -> 60 N -> 20 -> 45 -> 30 -> 45 -> 20 -> 60 -> 0),
    the load held over each 0.1 s step: the strain at every step equals the generator's
    quasi-static solution, and the inner loop 45 -> 30 -> 45 closes on itself (Masing)."""
    nodes = [0.0, 60.0, 20.0, 45.0, 30.0, 45.0, 20.0, 60.0, 0.0]
    load = np.concatenate([np.linspace(a, b, 41)[:-1] for a, b in zip(nodes[:-1], nodes[1:])] + [[0.0]])
    times = np.arange(len(load)) * 0.1
    # a bank that carries a good part of the load: 2700 N of stiffness slipping at 6e-5 to 2e-3
    bank = dict(hysteresis=4) | {f"iw_k{i + 1}": 30 * K_EL[i] for i in range(8)} | {
        f"iw_eps{i + 1}": 10 * EPS_EL[i] for i in range(8)}
    values = dict(rig=3, stiffness=1, creep=False, EA=EA, L0=L0, rtol=1e-10, load=float(load[0])) | bank
    inst = H.cs(values)
    r = H.run_cs(inst, times, ["strain", "tension"], inputs=lambda t: {"load": float(load[int(round(t / 0.1)) + 1])})
    inst.free()
    # the step from times[k] ends at load[k + 1]: r[k + 1] belongs to load[k + 1]
    expected = he._quasi_static(_Linear(EA), he.Iwan([30 * k for k in K_EL], [300 * k * e for k, e in zip(K_EL, EPS_EL)]), load)
    err = float(np.max(np.abs(r["strain"] - expected)))
    loop = (120, 200)                    # the starts of the segments 45 -> 30 and 45 -> 20
    assert load[loop[0]] == load[loop[1]] == 45.0
    closure = abs(r["strain"][loop[1]] - r["strain"][loop[0]])
    width = float(np.max(np.abs(expected - load / EA)))
    print(f"FIGURE Iwan load rig: largest |strain_FMU - strain_generator| {err:.3g} (largest friction "
          f"share of the strain {width:.3g}); the 45 N point before and after the inner loop differs by {closure:.3g}")
    assert np.allclose(r["tension"], load, atol=1e-9)
    assert width > 0.1 * float(np.max(expected))
    assert err < 1e-9 * float(np.max(expected))
    assert closure < 1e-12


def test_bad_iwan_parameters_are_named():
    """A negative element stiffness is refused when set; a slip strain of 0 beside a stiffness at
    initialisation; an element with no stiffness needs no slip strain."""
    inst = H.Instance("cs")
    st = inst.set("iw_k3", -1.0)
    errors = inst.log.with_status(H.fmi2Error)
    inst.free()
    assert st == H.fmi2Error and errors and "iw_k3 = -1" in errors[-1], errors
    for change, needle in ((dict(iw_eps5=0.0), "iw_eps5 = 0 with iw_k5 = 70 N"), (dict(iw_eps5=0.0, iw_k5=0.0), None)):
        inst = H.Instance("cs")
        inst.set_all(dict(rig=2, stiffness=1, EA=EA, L0=L0, m=M) | IWAN | change)
        inst.check(inst.setup(), "fmi2SetupExperiment")
        inst.check(inst.enter_init(), "fmi2EnterInitializationMode")
        st = inst.exit_init()
        errors = inst.log.with_status(H.fmi2Error)
        inst.free()
        if needle is None:
            assert st == H.fmi2OK, errors
        else:
            assert st == H.fmi2Error and errors and needle in errors[-1], errors
            print(f"FIGURE Iwan error: {errors[-1]}")


def test_restored_state_keeps_the_bank_memory():
    """Saved after a dozen reversals and restored into a new instance, the run goes on bit for bit;
    a fresh bank at the same displacement and velocity would not (the memory is state)."""
    values = dict(rig=2, stiffness=1, damping=1, creep=False, slack=True, m=M, g=G, EA=EA, L0=L0, c0=0.2,
                  x0=0.25, rtol=1e-9) | IWAN
    h = 1e-3
    inst = H.cs(values)
    H.run_cs(inst, np.arange(1501) * h, ["displacement"])
    state = inst.fmu.getFMUstate()
    blob = bytes(inst.fmu.serializeFMUstate(state))
    inst.fmu.freeFMUstate(state)
    after = 1.5 + np.arange(1001) * h
    cont = H.run_cs(inst, after, ["displacement", "velocity", "tension"])
    inst.free()
    copy = H.Instance("cs")
    restored = copy.fmu.deSerializeFMUstate(blob)
    copy.fmu.setFMUstate(restored)
    copy.fmu.freeFMUstate(restored)
    again = H.run_cs(copy, after, ["displacement", "velocity", "tension"])
    copy.free()
    differing = sum(int(np.sum(cont[v] != again[v])) for v in ("displacement", "velocity", "tension"))
    fresh = H.cs(values | dict(x0=float(cont["displacement"][0])))
    # a fresh bank, released from the same displacement at rest, is not the saved motion
    other = H.run_cs(fresh, after - after[0], ["displacement"])
    fresh.free()
    print(f"FIGURE Iwan restore: {len(blob)} bytes, {differing} values differ after 1000 steps")
    assert differing == 0
    assert np.max(np.abs(other["displacement"] - cont["displacement"])) > 1e-4


def test_model_exchange_locates_the_reversals_as_co_simulation_does():
    """fmpy's own CVode drives the model-exchange interface: the reversals are state events there
    (the Kawabata rate indicator), and the trajectory with slack agrees with co-simulation's."""
    from fmpy import simulate_fmu
    values = dict(rig=2, stiffness=1, damping=1, creep=False, slack=True, m=M, g=G, EA=EA, L0=L0, c0=0.2,
                  x0=0.25) | IWAN
    path = str(H.require_fmu())
    kw = dict(start_values=values, stop_time=5.0, output_interval=1e-3, output=["displacement", "tension"])
    cs = simulate_fmu(path, fmi_type="CoSimulation", **kw)
    me = simulate_fmu(path, fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                      record_events=False, **kw)
    swing = float(np.ptp(cs["displacement"]))
    err = float(np.max(np.abs(cs["displacement"] - me["displacement"])))
    x_gen, _ = generator_payload(cs["time"], 0.25, 0.2, True)
    print(f"FIGURE Iwan CS vs ME: largest |x_CS - x_ME| {err:.3g} m over a swing of {swing:.3g} m; "
          f"ME against the generator {float(np.max(np.abs(me['displacement'] - x_gen))):.3g} m")
    assert err < 1e-5 * swing


@pytest.mark.parametrize("relaxed", [20.0, 10.0])
def test_a_load_rig_bank_unloaded_at_a_load_before_the_record_follows_masing_from_there(relaxed):
    """iwan_relaxed_load = Tr: the elements start unloaded at the strain Tr / EA (a tether shaken down
    under Tr), then follow the load monotonically to the first load (20 N) and on. With a linear law,
    EA eps + H(eps - Tr / EA) = T, so the strain is Tr / EA plus the generator's quasi-static strain
    of a virgin bank under T - Tr, prepended with its start at T = Tr. The engine agrees."""
    from tether import identify_native as idn

    nodes = [20.0, 60.0, 5.0, 45.0, 20.0]
    load = np.concatenate([np.linspace(a, b, 41)[:-1] for a, b in zip(nodes[:-1], nodes[1:])] + [[20.0]])
    times = np.arange(len(load)) * 0.1
    K, E = [30 * k for k in K_EL], [10 * e for e in EPS_EL]
    bank = dict(hysteresis=4) | {f"iw_k{i + 1}": K[i] for i in range(8)} | {f"iw_eps{i + 1}": E[i] for i in range(8)}
    values = dict(rig=3, stiffness=1, creep=False, EA=EA, L0=L0, rtol=1e-10, iwan_relaxed_load=relaxed) | bank
    inst = H.cs(values | dict(load=float(load[0])))
    r = H.run_cs(inst, times, ["strain"], inputs=lambda t: {"load": float(load[min(int(round(t / 0.1)) + 1, len(load) - 1)])})
    inst.free()
    shifted = np.concatenate([[0.0], load - relaxed])
    expected = relaxed / EA + he._quasi_static(_Linear(EA), he.Iwan(K, [k * e for k, e in zip(K, E)]), shifted)[1:]
    virgin = he._quasi_static(_Linear(EA), he.Iwan(K, [k * e for k, e in zip(K, E)]), load)
    exp = idn.Experiment(times, settings={k: float(v) for k, v in values.items()}, input_kind=idn.INPUT_LOAD,
                         input=np.asarray(load, float), input_der=np.zeros((len(times), 3)), output="strain")
    # with zero derivatives the engine holds each sample's load over the interval after it, where
    # the FMU above is given the next sample's load over the interval before it: one sample apart
    engine = idn.simulate(exp)
    err = float(np.max(np.abs(r["strain"] - expected)))
    err_engine = float(np.max(np.abs(engine[1:] - expected[:-1])))
    moved = float(np.max(np.abs(expected - virgin)))
    print(f"FIGURE Iwan load rig unloaded at {relaxed:g} N before a record from 20 N: largest |strain - closed form| "
          f"FMU {err:.3g}, engine {err_engine:.3g}; the start moves the strain by up to {moved:.3g} from a virgin bank's")
    assert moved > 1e3 * err
    assert err < 1e-9 * float(np.max(expected)) and err_engine < 1e-9 * float(np.max(expected))


def test_a_relaxed_load_on_the_payload_rig_or_below_zero_is_refused_with_its_value():
    bank = dict(hysteresis=4, iw_k1=100.0, iw_eps1=1e-4)
    for values, text in ((dict(rig=2, m=M, g=G, iwan_relaxed_load=5.0), "iwan_relaxed_load = 5 N"),
                         (dict(rig=3, load=10.0, iwan_relaxed_load=-1.0), "iwan_relaxed_load = -1")):
        with pytest.raises(Exception, match=text):
            H.cs(dict(stiffness=1, EA=EA, L0=L0, creep=False) | bank | values)
