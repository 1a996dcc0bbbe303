"""Every switch set from three importers: the element rig coupled with a mass FMU.

KevlarTether in its element rig, coupled with PointMass.fmu (python_tests/fixtures/mass_fmu, a
point mass under gravity pulled up by the tether), is the payload rig split in two FMUs:

    mass.position -> tether.elongation    mass.velocity -> tether.elongation_rate
    tether.tension -> mass.tether_force

Each importer (fmpy, libcosimpy, ecospy) sets all five Integer switches away from their defaults
(rig element, linear stiffness, viscous damping, Bouc-Wen hysteresis, BDF), and the two Boolean
ones (creep on, slack off), and reads them back,
runs 5 s at a communication step of 1e-4 s, and must reproduce the payload rig of the same
configuration (run alone through fmpy) to 1e-3 m. A switch an importer fails to set changes the
physics (the defaults are the cubic law, displacement-dependent damping, no hysteresis, payload
rig: the mass would hang still at the balance).

The coupling holds each input over a step (a loop delay of one step), so the error is of first
order in the step; the release (0.15 m below the balance) keeps the tether taut, where that error
is smooth. Viscous damping and Bouc-Wen without shape terms see no `x`, which the element rig takes
as the elongation and the payload rig as the displacement from balance.
"""
import time

import numpy as np
import pytest

import fmu_harness as H

SWITCHES = dict(stiffness=1, damping=1, hysteresis=3, integrator=2)
ELEMENT = dict(rig=1) | SWITCHES
FLAGS = dict(creep=True, slack=False)   # the Boolean switches, also away from their defaults
X0 = 0.15            # release below the balance [m]
H_STEP = 1e-4        # communication step [s]
N_STEPS = 50_000     # 5 s
TOLERANCE = 1e-3     # [m]
MASS_FMU = H.REPO / "build" / "fixtures" / "PointMass.fmu"


def require_mass_fmu():
    if not MASS_FMU.is_file():
        pytest.fail(f"test fixture not found at {MASS_FMU} (cmake --build build builds it)", pytrace=False)
    return MASS_FMU


def test_switches_are_integers_whose_descriptions_list_their_values():
    """libcosim and ecos ignore Enumeration variables: every switch must be an Integer."""
    md = H.model_description()
    v = {x.name: x for x in md.modelVariables}
    for name, values in {"rig": ["element", "payload", "load"], "stiffness": ["linear", "cubic", "exponential", "bilinear"],
                         "damping": ["viscous", "displacement", "coulomb", "amplitude"],
                         "hysteresis": ["none", "kawabata", "boucwen", "iwan"],
                         "integrator": ["auto", "bdf", "adams"]}.items():
        assert v[name].type == "Integer", name
        assert (int(v[name].min), int(v[name].max)) == (1, len(values)), name
        for k, label in enumerate(values, 1):
            assert f"{k} = {label}" in v[name].description, (name, label)
    assert all(x.type != "Enumeration" for x in md.modelVariables)


@pytest.fixture(scope="module")
def payload_reference():
    """The payload rig alone (fmpy): displacement on the grid, and the balance stretch."""
    inst = H.cs(dict(rig=2, x0=X0) | SWITCHES | FLAGS)
    bal = inst.get("balance_elongation")
    r = H.run_cs(inst, np.arange(N_STEPS + 1) * H_STEP, ["displacement"])
    inst.free()
    assert np.min(r["displacement"]) > -bal, "the reference should stay taut"
    return r["displacement"], bal


def report(importer, diff, seconds):
    print(f"FIGURE element rig + PointMass in {importer}, 5 s at 1e-4 s: max |x - x_payload| = {diff:.3g} m "
          f"({seconds:.1f} s)")


def test_fmpy_element_rig_with_mass_reproduces_payload_rig(payload_reference, tmp_path):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    ref, bal = payload_reference
    t0 = time.perf_counter()
    tether = H.cs(ELEMENT | FLAGS | dict(elongation=bal + X0))
    assert tether.get(*ELEMENT, *FLAGS) == list(ELEMENT.values()) + list(FLAGS.values())
    md = read_model_description(str(require_mass_fmu()))
    mass = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(MASS_FMU), unzipdir=str(tmp_path)), modelIdentifier="PointMass",
                     instanceName="mass")
    mvr = {v.name: v.valueReference for v in md.modelVariables}
    mass.instantiate()
    mass.setupExperiment(startTime=0.0)
    mass.setReal([mvr["position0"]], [bal + X0])
    mass.enterInitializationMode()
    mass.exitInitializationMode()
    tvr = [H.vr("elongation"), H.vr("elongation_rate")]
    x = np.empty(N_STEPS + 1)
    for k in range(N_STEPS + 1):
        pos, vel = mass.getReal([mvr["position"], mvr["velocity"]])
        x[k] = pos - bal
        if k == N_STEPS:
            break
        st, (tension,) = tether.get_reals_raw([H.vr("tension")])
        tether.check(st, "fmi2GetReal")
        tether.check(tether.set_real(tvr, [pos, vel]), "fmi2SetReal")
        mass.setReal([mvr["tether_force"]], [tension])
        tether.check(tether.do_step(k * H_STEP, H_STEP), "fmi2DoStep")
        mass.doStep(k * H_STEP, H_STEP)
    tether.free()
    mass.terminate()
    mass.freeInstance()
    diff = float(np.max(np.abs(x - ref)))
    report("fmpy", diff, time.perf_counter() - t0)
    assert diff < TOLERANCE


def test_libcosim_element_rig_with_mass_reproduces_payload_rig(payload_reference):
    from libcosimpy import CosimConstants
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    ref, bal = payload_reference
    t0 = time.perf_counter()
    log_output_level(CosimLogLevel.ERROR)
    h_ns = int(round(H_STEP * 1e9))
    ex = CosimExecution.from_step_size(h_ns)
    tether = ex.add_local_slave(CosimLocalSlave(fmu_path=str(H.require_fmu()), instance_name="tether"))
    mass = ex.add_local_slave(CosimLocalSlave(fmu_path=str(require_mass_fmu()), instance_name="mass"))
    mvr = {v.name.decode(): v.reference for v in ex.slave_variables(mass)}
    for name, value in ELEMENT.items():
        assert ex.integer_initial_value(tether, H.vr(name), value), name
    for name, value in FLAGS.items():
        assert ex.boolean_initial_value(tether, H.vr(name), value), name
    assert ex.real_initial_value(mass, mvr["position0"], bal + X0)
    for out_slave, out_vr, in_slave, in_vr in [(mass, mvr["position"], tether, H.vr("elongation")),
                                               (mass, mvr["velocity"], tether, H.vr("elongation_rate")),
                                               (tether, H.vr("tension"), mass, mvr["tether_force"])]:
        assert ex.connect_real_variables(out_slave, out_vr, in_slave, in_vr) == CosimConstants.success
    last = CosimObserver.create_last_value()
    series = CosimObserver.create_time_series(buffer_size=N_STEPS + 1)
    ex.add_observer(last)
    ex.add_observer(series)
    assert series.start_time_series(mass, mvr["position"], CosimVariableType.REAL)
    assert ex.simulate_until(N_STEPS * h_ns), ex.status()
    assert last.last_integer_values(tether, [H.vr(n) for n in ELEMENT]) == list(ELEMENT.values())
    assert last.last_boolean_values(tether, [H.vr(n) for n in FLAGS]) == list(FLAGS.values())
    times, steps, pos = series.time_series_real_samples(mass, mvr["position"], from_step=0,
                                                        sample_count=N_STEPS + 1)
    # libcosimpy trims the samples by counting step numbers equal to 0, so the last one is cut off:
    # align by time, and take the final value from the last-value observer
    k = np.asarray(times) // h_ns
    assert np.array_equal(k, np.arange(N_STEPS)), (k[:3], k[-3:])
    x = np.append(pos, last.last_real_values(mass, [mvr["position"]])) - bal
    diff = float(np.max(np.abs(x - ref)))
    report("libcosimpy", diff, time.perf_counter() - t0)
    assert diff < TOLERANCE


def test_ecos_element_rig_with_mass_reproduces_payload_rig(payload_reference):
    from ecospy import EcosSimulation, EcosSimulationStructure

    ref, bal = payload_reference
    t0 = time.perf_counter()
    ss = EcosSimulationStructure()
    ss.add_model("tether", str(H.require_fmu()))
    ss.add_model("mass", str(require_mass_fmu()))
    ss.make_real_connection("mass::position", "tether::elongation")
    ss.make_real_connection("mass::velocity", "tether::elongation_rate")
    ss.make_real_connection("tether::tension", "mass::tether_force")
    ss.add_parameter_set("initial", {f"tether::{k}": int(v) for k, v in ELEMENT.items()}
                         | {f"tether::{k}": bool(v) for k, v in FLAGS.items()}
                         | {"mass::position0": float(bal + X0)})
    sim = EcosSimulation(structure=ss, step_size=H_STEP)
    try:
        assert sim.init(parameter_set="initial")
        assert [sim.get_integer(f"tether::{k}") for k in ELEMENT] == list(ELEMENT.values())
        assert [sim.get_bool(f"tether::{k}") for k in FLAGS] == list(FLAGS.values())
        x = np.empty(N_STEPS + 1)
        x[0] = sim.get_real("mass::position")
        for k in range(1, N_STEPS + 1):
            sim.step()
            x[k] = sim.get_real("mass::position")
        assert abs(sim.get_time() - N_STEPS * H_STEP) < 1e-9
        sim.terminate()
    finally:
        sim.free()
        ss.free()
    diff = float(np.max(np.abs(x - bal - ref)))
    report("ecospy", diff, time.perf_counter() - t0)
    assert diff < TOLERANCE
