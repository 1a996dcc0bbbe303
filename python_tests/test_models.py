"""tether.models: model strings, their FMU switches/effects/parameters, and parameter files."""

from __future__ import annotations

import json
import os

import pytest

from tether.models import (EFFECTS, PRESETS, ModelError, ModelSpec, ParamsError, parse_model, read_params,
                           write_params)

# FMU enumeration values, written out independently of the package (modelDescription.xml)
LINEAR, CUBIC = 1, 2
VISCOUS, DISPLACEMENT, COULOMB = 1, 2, 3
NONE, KAWABATA, BOUCWEN = 1, 2, 3
PAYLOAD, LOAD = 2, 3


def sw(stiffness, damping, hysteresis, creep=False, slack=False, rig=PAYLOAD):
    return {"rig": rig, "stiffness": stiffness, "damping": damping, "hysteresis": hysteresis,
            "creep": creep, "slack": slack}


# ---------------------------------------------------------------------------------------------
# presets
@pytest.mark.parametrize("name, switches", [
    ("linear", sw(LINEAR, VISCOUS, NONE)),
    ("cubic", sw(CUBIC, VISCOUS, NONE)),
    ("simplified", sw(CUBIC, DISPLACEMENT, NONE)),
    ("kawabata", sw(LINEAR, VISCOUS, KAWABATA)),
    ("full", sw(CUBIC, DISPLACEMENT, BOUCWEN)),
])
def test_presets(name, switches):
    spec = parse_model(name)
    assert spec.switches == switches
    assert spec.canonical == name


def test_linear_is_exactly_the_trace_format_baseline():
    # a linear spring (also in compression: no slack) and a constant viscous damper, nothing else
    spec = parse_model("linear")
    assert spec.switches == {"rig": 2, "stiffness": 1, "damping": 1, "hysteresis": 1, "creep": False, "slack": False}
    assert spec.effects == []
    assert spec.parameters == ["EA", "c0"]


# ---------------------------------------------------------------------------------------------
# effects and laws
@pytest.mark.parametrize("text, switches, effects", [
    ("linear+nonlinear_stiffness", sw(CUBIC, VISCOUS, NONE), ["nonlinear_stiffness"]),
    ("linear+cubic", sw(CUBIC, VISCOUS, NONE), ["nonlinear_stiffness"]),
    ("linear+hysteresis", sw(LINEAR, VISCOUS, BOUCWEN), ["hysteresis"]),
    ("linear+boucwen", sw(LINEAR, VISCOUS, BOUCWEN), ["hysteresis"]),
    ("linear+kawabata", sw(LINEAR, VISCOUS, KAWABATA), ["nonlinear_stiffness", "hysteresis"]),
    ("linear+nonlinear_damping", sw(LINEAR, DISPLACEMENT, NONE), ["nonlinear_damping"]),
    ("linear+creep", sw(LINEAR, VISCOUS, NONE, creep=True), ["creep"]),
    ("linear+slack", sw(LINEAR, VISCOUS, NONE, slack=True), ["slack"]),
    ("linear+coulomb", sw(LINEAR, COULOMB, NONE), ["nonlinear_damping"]),
    ("cubic+boucwen+coulomb+slack", sw(CUBIC, COULOMB, BOUCWEN, slack=True),
     ["nonlinear_stiffness", "hysteresis", "nonlinear_damping", "slack"]),
    ("simplified+slack", sw(CUBIC, DISPLACEMENT, NONE, slack=True), ["nonlinear_stiffness", "nonlinear_damping", "slack"]),
    ("full+creep+slack", sw(CUBIC, DISPLACEMENT, BOUCWEN, True, True), list(EFFECTS)),
    ("cubic+boucwen", sw(CUBIC, VISCOUS, BOUCWEN), ["nonlinear_stiffness", "hysteresis"]),
    ("kawabata+nonlinear_damping+creep", sw(LINEAR, DISPLACEMENT, KAWABATA, creep=True),
     ["nonlinear_stiffness", "hysteresis", "nonlinear_damping", "creep"]),
    # a string may start with an effect: it builds on linear
    ("slack+creep", sw(LINEAR, VISCOUS, NONE, True, True), ["creep", "slack"]),
    (" Linear + BoucWen ", sw(LINEAR, VISCOUS, BOUCWEN), ["hysteresis"]),
])
def test_effects(text, switches, effects):
    spec = parse_model(text)
    assert spec.switches == switches
    assert spec.effects == effects


def test_vocabulary_names_equal_law_names():
    assert parse_model("linear+hysteresis") == parse_model("linear+boucwen")
    assert parse_model("linear+nonlinear_stiffness") == parse_model("cubic")
    assert parse_model("cubic+nonlinear_damping") == parse_model("simplified")
    assert parse_model("simplified+hysteresis") == parse_model("full")


@pytest.mark.parametrize("text", [
    "linear", "cubic", "simplified", "kawabata", "full", "linear+boucwen", "linear+slack", "cubic+boucwen",
    "linear+nonlinear_damping", "kawabata+creep+slack", "full+creep+slack", "simplified+slack",
    "linear+boucwen+nonlinear_damping", "slack+nonlinear_stiffness+creep", "linear+coulomb", "cubic+coulomb+slack",
    "cubic+boucwen+coulomb",
])
def test_canonical_round_trip(text):
    spec = parse_model(text)
    again = parse_model(spec.canonical)
    assert again == spec
    assert again.canonical == spec.canonical
    assert str(spec) == spec.canonical


def test_canonical_uses_largest_preset():
    assert parse_model("linear+cubic+nonlinear_damping+boucwen").canonical == "full"
    assert parse_model("linear+nonlinear_damping+nonlinear_stiffness+slack").canonical == "simplified+slack"
    assert parse_model("slack+boucwen").canonical == "linear+boucwen+slack"


@pytest.mark.parametrize("text, params", [
    ("linear", ["EA", "c0"]),
    ("cubic", ["a1", "a2", "a3", "pow_F", "pow_eps", "pow_n", "c0"]),
    ("simplified", ["a1", "a2", "a3", "pow_F", "pow_eps", "pow_n", "c0", "c1", "c2", "c_table_dx"]
     + [f"c_table_{k}" for k in range(1, 7)] + ["c_drag", "c_coulomb", "coulomb_v"]),
    ("linear+slack", ["EA", "c0"]),
    ("linear+coulomb", ["EA", "c0", "c_coulomb", "coulomb_v"]),
])
def test_parameters_exact(text, params):
    assert parse_model(text).parameters == params


def test_parameters_of_laws():
    bw = parse_model("linear+boucwen").parameters
    assert {"EA", "c0", "bw_A", "bw_beta", "bw_gamma", "bw_n", "z0"} <= set(bw)
    assert "a1" not in bw and "c1" not in bw
    kaw = parse_model("kawabata").parameters
    assert {"kaw_LT", "kaw_RT", "kaw_eps_ref", "kaw_F_ref", "kaw_residual", "c0"} <= set(kaw)
    assert "EA" not in kaw and "a1" not in kaw          # Kawabata replaces the elastic law
    cr = parse_model("linear+creep").parameters
    assert {"creep_J1", "creep_tau1", "creep_J2", "creep_tau2", "creep_J3", "creep_tau3", "slip_rate"} <= set(cr)
    full = parse_model("full").parameters
    assert {"a1", "a2", "a3", "c0", "c1", "c2", "bw_A", "bw_beta", "bw_gamma", "bw_n"} <= set(full)


def test_parameters_exist_in_the_fmu(fmu_path):
    from tether.fmu import model_description

    fmu_params = model_description().parameters
    for name in PRESETS:
        for text in (name, "linear+boucwen+creep", "linear+coulomb"):
            for p in parse_model(text).parameters:
                assert p in fmu_params, p


@pytest.mark.parametrize("experiment, rig", [("free_vibration", PAYLOAD), ("forced", PAYLOAD),
                                             ("load_unload", LOAD), ("creep", LOAD)])
def test_rig_follows_experiment(experiment, rig):
    assert parse_model("full", experiment).switches["rig"] == rig
    assert parse_model("linear").for_experiment(experiment).switches["rig"] == rig


# ---------------------------------------------------------------------------------------------
# errors
@pytest.mark.parametrize("text, fragments", [
    ("kawabata+boucwen", ("'boucwen' conflicts with 'kawabata'",)),
    ("linear+boucwen+kawabata", ("'kawabata' conflicts with 'boucwen'",)),
    ("full+kawabata", ("'kawabata' conflicts with 'full'",)),
    ("linear+hysteresis+boucwen", ("'boucwen' is already in the model (from 'hysteresis')",)),
    ("simplified+cubic", ("'cubic' is already in the model (from 'simplified')",)),
    ("cubic+nonlinear_stiffness", ("'nonlinear_stiffness' is already in the model (from 'cubic')",)),
    ("linear+slack+slack", ("'slack' is already in the model",)),
    ("full+nonlinear_damping", ("'nonlinear_damping' is already in the model (from 'full')",)),
    ("simplified+coulomb", ("'coulomb' conflicts with 'simplified'", "damping")),
    ("linear+nonlinear_damping+coulomb", ("'coulomb' conflicts with 'nonlinear_damping'",)),
    ("kawabata+cubic", ("'kawabata' conflicts with 'cubic'", "replace the elastic law")),
    ("cubic+kawabata", ("'kawabata' conflicts with 'cubic'",)),
    ("kawabata+nonlinear_stiffness", ("conflicts", "nonlinear_stiffness")),
    ("linear+full", ("preset 'full' may only come first",)),
    ("linear++slack", ("empty term",)),
    ("", ("empty",)),
])
def test_conflicts(text, fragments):
    with pytest.raises(ModelError) as ei:
        parse_model(text)
    msg = str(ei.value)
    assert "\n" not in msg
    for f in fragments:
        assert f in msg, msg


@pytest.mark.parametrize("text, bad", [("linaer", "linaer"), ("linear+friction", "friction"),
                                       ("cubic+bouc-wen", "bouc-wen")])
def test_unknown_names_list_valid_names(text, bad):
    with pytest.raises(ModelError) as ei:
        parse_model(text)
    msg = str(ei.value)
    assert f"unknown name '{bad}'" in msg
    for valid in ("linear", "cubic", "simplified", "kawabata", "full", "nonlinear_stiffness", "hysteresis",
                  "nonlinear_damping", "creep", "slack", "boucwen"):
        assert valid in msg


def test_unknown_experiment():
    with pytest.raises(ModelError, match="experiment 'tensile'"):
        parse_model("linear", "tensile")


# ---------------------------------------------------------------------------------------------
# parameter files
def write_json(path, obj):
    path.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return path


def test_read_canonical(tmp_path, fmu_path):
    p = write_json(tmp_path / "p.json", {"model": "linear+boucwen", "parameters": {"EA": 5e4, "bw_n": 1},
                                         "intervals": {"EA": [4e4, 6e4]}, "format": "x", "source": "fit"})
    pf = read_params(p)
    assert pf.model == "linear+boucwen"
    assert pf.parameters == {"EA": 5e4, "bw_n": 1.0}
    assert pf.extra == {"intervals": {"EA": [4e4, 6e4]}, "format": "x", "source": "fit"}


def test_read_flat(tmp_path, fmu_path):
    pf = read_params(write_json(tmp_path / "p.json", {"EA": 3500, "c0": 1.5, "rtol": 1e-10, "integrator": 2}))
    assert pf.model is None
    assert pf.parameters == {"EA": 3500.0, "c0": 1.5, "rtol": 1e-10, "integrator": 2.0}


def test_trace_names_accepted(tmp_path, fmu_path):
    pf = read_params(write_json(tmp_path / "p.json", {"L0": 16, "m": 4.3, "g": 9.81, "x0": 0.1, "v0": 0}))
    assert set(pf.parameters) == {"L0", "m", "g", "x0", "v0"}


@pytest.mark.parametrize("obj, fragments", [
    ({"EA": 5e4, "stiff": 3}, ("key 'stiff'", "not a parameter of the FMU", "EA")),
    ({"parameters": {"bw_Z": 1}}, ("key 'parameters.bw_Z'", "not a parameter")),
    ({"EA": "5e4"}, ("key 'EA'", 'value "5e4"', "not a number")),
    ({"EA": True}, ("key 'EA'", "value true", "not a number")),
    ({"EA": None}, ("key 'EA'", "value null", "not a number")),
    ({"parameters": {"c0": [1]}}, ("key 'parameters.c0'", "value [1]", "not a number")),
    ({"EA": -1}, ("key 'EA'", "value -1", "below the minimum 0")),
    ({"kaw_LT": 2.5}, ("key 'kaw_LT'", "value 2.5", "above the maximum 1.95")),
    ({"parameters": {"bw_n": 0.01}}, ("key 'parameters.bw_n'", "value 0.01", "below the minimum 0.1")),
    ({"rtol": 0.5}, ("key 'rtol'", "above the maximum 0.01")),
    ({"integrator": 1.5}, ("key 'integrator'", "not a whole number")),
    ({"integrator": 7}, ("key 'integrator'", "above the maximum 3")),
    ({"L0": 0}, ("key 'L0'", "below the minimum")),
    ({"stiffness": 2}, ("key 'stiffness'", "structural switch", "--model")),
    ({"slack": True}, ("key 'slack'", "structural switch")),
    ({"model": "linear+foo", "parameters": {}}, ("key 'model'", "unknown name 'foo'")),
    ({"model": 3, "parameters": {}}, ("key 'model'", "value 3", "not a string")),
    ({"model": "linear", "parameters": [1, 2]}, ("key 'parameters'", "not an object")),
    ("[1, 2]", ("top level is list", "expected a JSON object")),
    ("{\"EA\": 5e4,\n \"c0\": }", ("line 2", "invalid JSON")),
    ("", ("empty file",)),
])
def test_params_errors(tmp_path, fmu_path, obj, fragments):
    p = write_json(tmp_path / "bad.json", obj)
    with pytest.raises(ParamsError) as ei:
        read_params(p)
    msg = str(ei.value)
    assert "\n" not in msg
    assert str(p) in msg
    for f in fragments:
        assert f in msg, msg


def test_params_file_missing(tmp_path):
    with pytest.raises(ParamsError, match="not found"):
        read_params(tmp_path / "nope.json")


def test_write_params_round_trip(tmp_path, fmu_path):
    p = tmp_path / "fit.json"
    params = {"EA": 50000.123456789012, "c0": 1e-3 / 3, "bw_gamma": -1100.0}
    write_params(p, parse_model("linear+hysteresis"), params, {"intervals": {"EA": [1, 2]}, "source": "test"})
    doc = json.loads(p.read_text())
    assert doc["model"] == "linear+boucwen"
    assert doc["parameters"] == params                # floats survive exactly
    assert doc["intervals"] == {"EA": [1, 2]} and doc["source"] == "test"
    pf = read_params(p)
    assert pf.model == "linear+boucwen" and pf.parameters == params
    assert os.listdir(tmp_path) == ["fit.json"]       # no temporary file left


def test_write_params_atomic_on_failure(tmp_path):
    p = tmp_path / "fit.json"
    p.write_text("original")
    with pytest.raises(ValueError):
        write_params(p, "linear", {"EA": float("nan")})   # JSON has no NaN: the write fails
    assert p.read_text() == "original"
    assert os.listdir(tmp_path) == ["fit.json"]
    with pytest.raises(ValueError, match="overwrite"):
        write_params(p, "linear", {"EA": 1.0}, {"parameters": {}})
    assert p.read_text() == "original"


def test_model_spec_is_value_object():
    a = parse_model("linear+slack")
    b = ModelSpec(slack=True)
    assert a == b and hash(a) == hash(b)
