"""Acceptance tests of the KevlarTether FMU across importers and instances.

- Co-Simulation (CVODE inside the FMU) against Model Exchange integrated by fmpy's own CVode.
- fmpy against libcosimpy (the Open Simulation Platform's engine) on the same fixed step.
- Two instances of one extracted FMU stepped alternately against each run alone (bit for bit).
- A state saved, serialized and restored in a new instance continues bit for bit like the original.

The nonlinear case is the modelDescription's default configuration (payload rig, cubic law,
displacement-dependent damping, slack on) released 0.35 m below the balance, so that the tether
goes slack and taut again during the run. The libcosim case runs on the switches' start values;
the test asserts they are what it means to run (test_fmu_cosim_switches sets every switch from
fmpy, libcosim and ecos).
"""
import numpy as np
import pytest

import fmu_harness as H

OUTPUTS = ["displacement", "velocity", "tension", "strain"]
NONLINEAR = dict(x0=0.35, v0=0.0, rtol=1e-10)
NONLINEAR_FULL = dict(rig=2, stiffness=2, damping=2, hysteresis=1, creep=False, slack=True) | NONLINEAR


def test_default_configuration_is_the_nonlinear_case():
    """The switches' defaults (Integer variables, once Enumerations): payload, cubic, c(x) damping, slack."""
    start = {v.name: v.start for v in H.model_description().modelVariables}
    assert (start["rig"], start["stiffness"], start["damping"], start["hysteresis"]) == ("2", "2", "2", "1")
    assert start["slack"] == "true" and start["creep"] == "false"


def test_co_simulation_agrees_with_model_exchange():
    from fmpy import simulate_fmu
    path = str(H.require_fmu())
    out = OUTPUTS + ["is_slack"]
    cs = simulate_fmu(path, fmi_type="CoSimulation", start_values=NONLINEAR_FULL, stop_time=5.0,
                      output_interval=1e-3, output=out)
    me = simulate_fmu(path, fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-10,
                      record_events=False, start_values=NONLINEAR_FULL, stop_time=5.0,
                      output_interval=1e-3, output=out)
    assert len(cs) == len(me) and np.array_equal(cs["time"], me["time"])
    slack_samples = int(np.sum(cs["is_slack"]))
    assert slack_samples > 100, "the case should contain slack phases"
    assert np.sum(cs["is_slack"] != me["is_slack"]) <= 2 * 6  # at most a sample at each switch
    errs = {v: np.max(np.abs(cs[v] - me[v])) / np.max(np.abs(cs[v])) for v in OUTPUTS}
    print("FIGURE 4a CS vs ME (fmpy CVode, rtol 1e-10), 5 s, slack samples %d: " % slack_samples
          + ", ".join(f"{k} {e:.3g}" for k, e in errs.items()))
    assert max(errs.values()) < 1e-6


def run_fmpy(values, times):
    inst = H.cs(values)
    r = H.run_cs(inst, times, OUTPUTS)
    inst.free()
    return r


def test_libcosim_agrees_with_fmpy():
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.ERROR)
    h_ns, n = 1_000_000, 3000  # 1 ms, 3 s
    execution = CosimExecution.from_step_size(h_ns)
    slave = CosimLocalSlave(fmu_path=str(H.require_fmu()), instance_name="tether")
    index = execution.add_local_slave(slave)
    for name, value in NONLINEAR.items():
        assert execution.real_initial_value(index, H.vr(name), value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    refs = [H.vr(v) for v in OUTPUTS]
    rows = []
    for _ in range(n):
        assert execution.step(), execution.status()
        rows.append(observer.last_real_values(index, refs))
    assert execution.status().current_time == n * h_ns
    osp = np.array(rows)

    # libcosim counts time in integer nanoseconds and converts each communication point as
    # t_k = (k h_ns) / 1e9, the step as t_(k+1) - t_k; fmpy is driven through the same points.
    # (With rtol 1e-10 a 1-ulp change in the communication points alone moves the outputs ~5e-9.)
    ref = run_fmpy(NONLINEAR, np.arange(n + 1) * h_ns / 1e9)
    diffs = {v: np.max(np.abs(osp[:, i] - ref[v][1:])) / np.max(np.abs(ref[v])) for i, v in enumerate(OUTPUTS)}
    identical = sum(int(np.sum(osp[:, i] != ref[v][1:])) for i, v in enumerate(OUTPUTS))
    print("FIGURE 4b libcosim vs fmpy, 1 ms x 3000: " + ", ".join(f"{k} {e:.3g}" for k, e in diffs.items())
          + f"; values not bit-identical: {identical} of {len(OUTPUTS) * n}")
    assert max(diffs.values()) < 1e-9


def test_two_instances_stepped_alternately_are_bit_identical_to_each_alone():
    a_values = NONLINEAR_FULL
    b_values = dict(rig=2, stiffness=1, damping=1, slack=True, EA=3500.0, c0=5.0, x0=-0.4, rtol=1e-9)
    h, n = 2e-3, 1000
    times = np.arange(n + 1) * h
    alone = []
    for values in (a_values, b_values):
        inst = H.cs(values)
        alone.append(H.run_cs(inst, times, OUTPUTS))
        inst.free()
    alone_a, alone_b = alone

    a, b = H.cs(a_values), H.cs(b_values)  # same extracted FMU, same shared library
    refs = [H.vr(v) for v in OUTPUTS]
    rows_a, rows_b = [a.get_reals_raw(refs)[1]], [b.get_reals_raw(refs)[1]]
    for k in range(n):
        for inst, rows in ((a, rows_a), (b, rows_b)):
            inst.check(inst.do_step(times[k], times[k + 1] - times[k]), "fmi2DoStep")
            st, vals = inst.get_reals_raw(refs)
            inst.check(st, "fmi2GetReal")
            rows.append(vals)
    a.free()
    b.free()
    rows_a, rows_b = np.array(rows_a), np.array(rows_b)
    mismatches = 0
    for i, v in enumerate(OUTPUTS):
        mismatches += np.sum(rows_a[:, i] != alone_a[v]) + np.sum(rows_b[:, i] != alone_b[v])
    print(f"FIGURE 4c two interleaved instances: {mismatches} values differ from the runs alone "
          f"({2 * len(OUTPUTS) * (n + 1)} compared)")
    assert mismatches == 0
    assert not np.array_equal(rows_a, rows_b)  # they really were different simulations


@pytest.mark.parametrize("new_instance", ["just instantiated", "initialised with other parameters"])
def test_serialized_state_restored_in_new_instance_continues_bit_for_bit(new_instance):
    h = 1e-3
    t_save, n_after = 1.0, 2000
    original = H.cs(NONLINEAR_FULL, categories=["logEvents"])
    original_times = np.arange(int(round(t_save / h)) + 1) * h
    H.run_cs(original, original_times, OUTPUTS)  # passes slack / taut events
    assert any("goes slack" in m for m in original.log.in_category("logEvents"))

    fmu = original.fmu
    state = fmu.getFMUstate()
    blob = bytes(fmu.serializeFMUstate(state))
    fmu.freeFMUstate(state)
    after = t_save + np.arange(n_after + 1) * h
    cont = H.run_cs(original, after, OUTPUTS + ["balance_elongation"])
    original.free()

    if new_instance == "just instantiated":
        copy = H.Instance("cs")
    else:
        copy = H.cs(dict(rig=2, stiffness=1, damping=1, slack=False, L0=8.0, x0=0.01, integrator=2))
    restored_state = copy.fmu.deSerializeFMUstate(blob)
    copy.fmu.setFMUstate(restored_state)
    copy.fmu.freeFMUstate(restored_state)
    again = H.run_cs(copy, after, OUTPUTS + ["balance_elongation"])
    copy.free()
    diff = {v: int(np.sum(cont[v] != again[v])) for v in OUTPUTS + ["balance_elongation"]}
    print(f"FIGURE 4d restore into a new instance ({new_instance}), {len(blob)} bytes, "
          f"{n_after} steps on: values differing {diff}")
    assert all(d == 0 for d in diff.values())
