"""modelDescription.xml's ModelStructure against the FMU's behaviour.

The dependencies an importer reads from <Outputs> and <Derivatives> decide where it sees algebraic
loops, so they must not lie. Model Exchange lets us evaluate the FMU at one instant without a
step: perturb one input or one continuous state, and the outputs and derivatives that move at once
are the ones that depend on it directly. ModelStructure is one for all configurations, so:
- every dependency observed in any configuration (each rig with each law) must be declared;
- every declared dependency must be observed in at least one configuration (no padding).
"""
from ctypes import POINTER, c_double, c_size_t

import numpy as np
import pytest

import fmu_harness as H

INPUTS = ["L0", "elongation", "elongation_rate", "force", "load"]

# laws and states chosen so that every coupling is active: taut tether, creep with the load past
# slip_load_half, Bouc-Wen away from z = 0, the Iwan bank in motion
CREEP = dict(creep=True, creep_J1=2e-5, creep_J2=1e-5, creep_J3=5e-6)
CONFIGURATIONS = {
    "payload boucwen creep": dict(rig=2, stiffness=2, damping=2, hysteresis=3, x0=0.05, v0=0.2, z0=1.0) | CREEP,
    "payload kawabata": dict(rig=2, hysteresis=2, damping=2, x0=0.05, v0=0.2),
    "payload iwan": dict(rig=2, stiffness=1, hysteresis=4, x0=0.05, v0=0.2),
    "element boucwen creep": dict(rig=1, stiffness=2, damping=2, hysteresis=3, z0=1.0, elongation=0.3,
                                  elongation_rate=0.1) | CREEP,
    "element iwan": dict(rig=1, stiffness=1, hysteresis=4, elongation=0.2, elongation_rate=0.1),
    "load boucwen creep": dict(rig=3, stiffness=2, hysteresis=3, z0=1.0, load=60.0) | CREEP,
    "load kawabata": dict(rig=3, hysteresis=2, load=60.0),
    "load iwan creep": dict(rig=3, stiffness=1, hysteresis=4, load=60.0) | CREEP,
}


def declared():
    """{unknown name: set of the names it depends on}, for Outputs and Derivatives (no
    dependencies attribute: FMI's default, every input and state)."""
    md = H.model_description()
    out = {}
    for u in list(md.outputs) + list(md.derivatives):
        deps = u.dependencies
        out[u.variable.name] = set(INPUTS + H.STATE_NAMES) if deps is None else {d.name for d in deps}
    return out


class MEPoint:
    """A Model Exchange instance in continuous-time mode, evaluated without stepping."""

    def __init__(self, values):
        self.inst = H.Instance("me")
        self.inst.initialize(values)
        self.inst.check(self.inst.call("fmi2EnterContinuousTimeMode", []), "fmi2EnterContinuousTimeMode")
        self.n = len(H.STATE_NAMES)

    def _array_call(self, function, values=None):
        arr = (c_double * self.n)(*(values or [0.0] * self.n))
        self.inst.check(self.inst.call(function, [POINTER(c_double), c_size_t], arr, self.n), function)
        return list(arr)

    def states(self):
        return self._array_call("fmi2GetContinuousStates")

    def set_states(self, x):
        self._array_call("fmi2SetContinuousStates", x)

    def snapshot(self, unknowns):
        """{name: value} of the outputs (fmi2GetReal) and derivatives (fmi2GetDerivatives)."""
        ders = dict(zip(["der(%s)" % s for s in H.STATE_NAMES], self._array_call("fmi2GetDerivatives")))
        outs = [u for u in unknowns if u not in ders]
        st, vals = self.inst.get_reals_raw([H.vr(u) for u in outs])
        self.inst.check(st, "fmi2GetReal")
        return dict(zip(outs, vals)) | {u: ders[u] for u in unknowns if u in ders}

    def free(self):
        self.inst.free()


def bump(v):
    return v + 1e-6 * max(1.0, abs(v))


def observed(values, unknowns):
    """{unknown: set of the inputs and states whose perturbation moves it}, at one instant."""
    p = MEPoint(values)
    try:
        base = p.snapshot(unknowns)
        seen = {u: set() for u in unknowns}

        def record(cause, now):
            for u in unknowns:
                if now[u] != base[u]:
                    seen[u].add(cause)

        for name in INPUTS:
            v = p.inst.get(name)
            p.inst.check(p.inst.set_real([H.vr(name)], [bump(v)]), f"set {name}")
            record(name, p.snapshot(unknowns))
            p.inst.check(p.inst.set_real([H.vr(name)], [v]), f"reset {name}")
        x = p.states()
        for i, name in enumerate(H.STATE_NAMES):
            p.set_states(x[:i] + [bump(x[i])] + x[i + 1:])
            record(name, p.snapshot(unknowns))
            p.set_states(x)
        assert p.snapshot(unknowns) == base, "the instance did not return to its starting point"
        assert not p.inst.get("is_slack"), "the configuration should keep the tether taut"
        return seen
    finally:
        p.free()


@pytest.fixture(scope="module")
def observations():
    unknowns = list(declared())
    return {label: observed(values, unknowns) for label, values in CONFIGURATIONS.items()}


def test_model_structure_lists_every_output_and_derivative():
    md = H.model_description()
    outputs = sorted(v.name for v in md.modelVariables if v.causality == "output")
    assert sorted(u.variable.name for u in md.outputs) == outputs
    assert "total_elongation" in outputs
    assert [u.variable.name for u in md.derivatives] == ["der(%s)" % s for s in H.STATE_NAMES]
    # FMI 2.0: the outputs and states calculated at initialization, the derivatives and the
    # calculated parameters, no more
    initial = [u.variable.name for u in md.initialUnknowns]
    calculated = [v.name for v in md.modelVariables if v.causality == "calculatedParameter"]
    assert sorted(initial) == sorted(set(outputs) | set(H.STATE_NAMES) | {"der(%s)" % s for s in H.STATE_NAMES}
                                     | set(calculated))
    index = {v.name: i for i, v in enumerate(md.modelVariables)}
    assert [index[n] for n in initial] == sorted(index[n] for n in initial)


def test_every_dependency_the_fmu_shows_is_declared(observations):
    decl = declared()
    missing = {}
    for label, seen in observations.items():
        for u, causes in seen.items():
            extra = causes - decl[u]
            if extra:
                missing.setdefault(u, set()).update(f"{c} ({label})" for c in extra)
    assert not missing, f"undeclared dependencies: {missing}"


def test_every_declared_dependency_shows_in_some_configuration(observations):
    decl = declared()
    union = {u: set().union(*(seen[u] for seen in observations.values())) for u in decl}
    padding = {u: decl[u] - union[u] for u in decl if decl[u] - union[u]}
    assert not padding, f"declared but never observed: {padding}"


def test_payload_tension_depends_on_the_state_not_on_the_input_force():
    """The issue's example: no direct feedthrough from force to tension (no spurious loop)."""
    decl = declared()
    assert "force" not in decl["tension"] and "displacement" in decl["tension"]
    assert "force" in decl["der(velocity)"]


@pytest.mark.parametrize("rig, values", [
    (1, dict(elongation=0.3, elongation_rate=0.1)),
    (2, dict(x0=0.05, v0=0.2)),
    (3, dict(load=60.0)),
])
def test_total_elongation_is_the_elongation_in_every_rig(rig, values):
    """The output total_elongation: the load rig's result (once only readable through the input
    variable elongation, which still reads it back), the input in the element rig, the balance
    stretch plus the displacement in the payload rig; strain L0 in all three."""
    inst = H.cs(dict(rig=rig, stiffness=1, damping=1, L0=16.0) | values)
    r = H.run_cs(inst, np.arange(201) * 1e-3, ["total_elongation", "elongation", "strain", "displacement"])
    bal = inst.get("balance_elongation")
    inst.free()
    u = r["total_elongation"]
    assert np.array_equal(u, r["elongation"])
    assert np.allclose(u, 16.0 * r["strain"], rtol=1e-14, atol=0.0)
    if rig == 1:
        assert np.all(u == 0.3)
    elif rig == 2:
        assert np.allclose(u, bal + r["displacement"], rtol=1e-14, atol=0.0) and u[0] == bal + 0.05
    else:
        assert np.allclose(u, 16.0 * 60.0 / float(H.variables()["EA"].start), rtol=1e-6)


def test_python_package_switch_values_are_the_fmus():
    """tether.models names the switch values; the FMU's descriptions list them: the same pairs."""
    import re

    from tether import models
    md = {v.name: v for v in H.model_description().modelVariables}
    for name, table in {"rig": models.RIG, "stiffness": models.STIFFNESS, "damping": models.DAMPING,
                        "hysteresis": models.HYSTERESIS}.items():
        listed = {label: int(k) for k, label in re.findall(r"\b(\d+) = ([a-z_]+)\b", md[name].description)}
        assert listed == table, name


def test_tension_feeds_through_from_a_new_elongation_at_once_across_slack():
    """ModelStructure says the element rig's tension depends directly on its elongation: set a
    new elongation and the tension answers before any step, also where the tether goes from slack
    to taut (libcosim reads outputs so at the start; an iterating master at every step)."""
    ea, L0, u = 3500.0, 16.0, 0.34
    inst = H.cs(dict(rig=1, stiffness=1, damping=1, slack=True, EA=ea, L0=L0))   # u = 0: slack
    assert inst.get("tension") == 0.0 and inst.get("is_slack")
    inst.check(inst.set_real([H.vr("elongation")], [u]), "set elongation")
    assert inst.get("tension") == pytest.approx(ea * u / L0, rel=1e-12) and not inst.get("is_slack")
    inst.check(inst.set_real([H.vr("elongation")], [-0.01]), "set elongation")
    assert inst.get("tension") == 0.0 and inst.get("is_slack")
    inst.free()


def test_reading_outputs_after_new_inputs_changes_nothing_in_the_fmu_state():
    """The slack switch made for outputs read between steps is made on a copy: the FMU state (its
    serialized bytes) is the same before and after the read; the next step makes the switch."""
    inst = H.cs(dict(rig=1, stiffness=1, damping=1, slack=True))      # u = 0: slack
    inst.check(inst.set_real([H.vr("elongation")], [0.34]), "set elongation")

    def blob():
        state = inst.fmu.getFMUstate()
        data = bytes(inst.fmu.serializeFMUstate(state))
        inst.fmu.freeFMUstate(state)
        return data

    before = blob()
    assert not inst.get("is_slack")
    assert blob() == before
    inst.check(inst.do_step(0.0, 1e-4), "fmi2DoStep")
    assert not inst.get("is_slack") and blob() != before
    inst.free()


@pytest.mark.parametrize("kind", ["cs", "me"])
def test_an_input_set_in_initialization_mode_after_a_read_is_used(kind):
    """An importer may read outputs in initialization mode, then set the inputs it connected
    (libcosim does): the initial state must follow the inputs as they stand at the end."""
    ea, L0, load = 3500.0, 16.0, 60.0
    inst = H.Instance(kind)
    inst.check(inst.setup(), "fmi2SetupExperiment")
    inst.set_all(dict(rig=3, stiffness=1, EA=ea, L0=L0))
    inst.check(inst.enter_init(), "fmi2EnterInitializationMode")
    assert inst.get("strain") == 0.0        # load 0: unstretched
    inst.check(inst.set_real([H.vr("load")], [load]), "set load")
    inst.check(inst.exit_init(), "fmi2ExitInitializationMode")
    assert inst.get("strain") == pytest.approx(load / ea, rel=1e-12)
    inst.free()


def test_fmu_carries_its_icon():
    """model.png at the root of the FMU (FMI 2.0, section 2.3): a PNG of icon size."""
    import struct
    import zipfile
    with zipfile.ZipFile(H.require_fmu()) as z:
        png = z.read("model.png")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[12:16] == b"IHDR"
    width, height = struct.unpack(">II", png[16:24])
    assert 32 <= width <= 512 and width == height
