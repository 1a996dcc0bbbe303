"""The bilinear elastic law (stiffness = 4): a toe of stiffness toe_EA while the braid's yarns
straighten, then EA beyond the strain toe_eps, the corner rounded over toe_width. Against its
closed form in the FMU (fmpy) and in the identification engine, and fitted by `tether fit`.

The closed form is written out here from docs/models.md (softplus, its derivative the logistic);
inverses are scipy's brentq on it, never the product's own inverse. Measured figures are printed
as 'FIGURE ...' lines (pytest -s shows them).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import fmu_harness as H
from tether import identify_native as idn

M, G, L0 = 4.3, 9.81, 16.0
TOE_EA, EA, TOE_EPS, TOE_WIDTH = 1200.0, 3400.0, 0.006, 0.0008
BILINEAR = dict(stiffness=4, hysteresis=1, creep=False, EA=EA, toe_EA=TOE_EA, toe_eps=TOE_EPS, toe_width=TOE_WIDTH)


def _softplus(y):
    return math.log1p(math.exp(-abs(y))) + max(y, 0.0)


def tension(eps):
    """T = toe_EA eps + (EA - toe_EA) w (softplus((eps - toe_eps)/w) - softplus(-toe_eps/w))."""
    w = TOE_WIDTH
    return TOE_EA * eps + (EA - TOE_EA) * w * (_softplus((eps - TOE_EPS) / w) - _softplus(-TOE_EPS / w))


def stiffness(eps):
    """dT/deps = toe_EA + (EA - toe_EA) / (1 + exp(-(eps - toe_eps)/w))."""
    return TOE_EA + (EA - TOE_EA) / (1.0 + math.exp(-(eps - TOE_EPS) / TOE_WIDTH))


def strain_at(T):
    return brentq(lambda e: tension(e) - T, -1.0, 1.0, xtol=1e-16, rtol=1e-15)


def _ramp_load(t):
    return 4.0 * t          # N, 0 to 40 N over 10 s: through the toe (about 7 N) and far beyond


def test_bilinear_law_load_ramp_and_balance_follow_the_closed_form_in_the_fmu_and_the_engine():
    inst = H.cs(BILINEAR | dict(rig=3, damping=1, c0=1.5, L0=L0, load=0.0))
    r = H.run_cs(inst, H.grid(10.0, 0.05), ["strain", "tension"], inputs=lambda t: {"load": _ramp_load(t)})
    inst.free()
    T = np.asarray(r["tension"])
    use = T > 0.2
    expected = np.array([strain_at(v) for v in T[use]])
    worst_fmu = float(np.max(np.abs(np.asarray(r["strain"])[use] - expected) / expected))
    t = np.linspace(0.0, 10.0, 201)
    exp = idn.Experiment(t, settings={**{k: float(v) for k, v in BILINEAR.items()}, "rig": 3, "L0": L0},
                         input_kind=idn.INPUT_LOAD, input=_ramp_load(t), output="strain")
    strain = idn.simulate(exp)
    on = _ramp_load(t) > 0.2
    worst_engine = float(np.max(np.abs(strain[on] / np.array([strain_at(v) for v in _ramp_load(t)[on]]) - 1)))
    inst = H.cs(BILINEAR | dict(rig=2, damping=1, slack=True, m=M, g=G, L0=L0))
    balance = inst.get("balance_elongation") / L0
    inst.free()
    at_balance = strain_at(M * G)
    print(f"FIGURE bilinear law (toe_EA {TOE_EA} N to EA {EA} N at {TOE_EPS}, width {TOE_WIDTH}): load ramp 0-40 N, "
          f"max |strain - closed form| / strain: FMU {worst_fmu:.3g} ({int(use.sum())} samples), engine "
          f"{worst_engine:.3g}; payload balance {balance:.15g} vs {at_balance:.15g}")
    assert use.sum() > 190
    assert worst_fmu < 1e-8 and worst_engine < 1e-6
    assert abs(balance - at_balance) < 1e-12 * at_balance


@pytest.mark.parametrize("mass, where", [(0.5, "in the toe"), (M, "beyond the toe")])
def test_bilinear_law_small_vibration_period_at_a_preload_in_the_fmu_and_the_engine(mass, where):
    """omega = sqrt(k(eps_0) / (m L0)) at the balance eps_0 of the weight m g: in the toe (0.5 kg,
    eps_0 = 0.0041) and beyond it (4.3 kg, 0.0163)."""
    eps0 = strain_at(mass * G)
    period = 2 * math.pi / math.sqrt(stiffness(eps0) / (mass * L0))
    values = BILINEAR | dict(rig=2, damping=1, c0=0.0, slack=False, m=mass, g=G, L0=L0, x0=1e-5, v0=0.0, rtol=1e-10)
    grid = H.grid(40 * period, period / 200)
    inst = H.cs(values)
    r = H.run_cs(inst, grid, ["displacement"])
    inst.free()
    p_fmu, n = H.period_by_zero_crossings(np.asarray(r["time"]), np.asarray(r["displacement"]))
    x = idn.simulate(idn.Experiment(np.asarray(grid, float), settings={k: float(v) for k, v in values.items()}))
    p_eng, _ = H.period_by_zero_crossings(np.asarray(grid, float), x)
    print(f"FIGURE bilinear law, small vibration {where} (m = {mass} kg, eps_0 = {eps0:.4g}): period "
          f"{period:.10g} s, FMU rel {p_fmu / period - 1:.2g} ({n} crossings), engine rel {p_eng / period - 1:.2g}")
    # the amplitude's own share: O((x0 k'' / (L0 k))^2), far below 1e-6 at x0 = 1e-5 m
    assert abs(p_fmu / period - 1) < 1e-6 and abs(p_eng / period - 1) < 1e-6


@pytest.mark.parametrize("name, value, text", [("toe_EA", 0.0, "toe_EA = 0 N"), ("toe_eps", -0.01, "toe_eps = -0.01"),
                                               ("toe_width", 0.0, "toe_width = 0"), ("EA", 0.0, "EA = 0 N")])
def test_bilinear_law_refuses_a_value_that_is_not_positive_with_its_value(name, value, text):
    exp = idn.Experiment(np.array([0.0, 1.0]), settings={**{k: float(v) for k, v in BILINEAR.items()},
                                                         "rig": 3, "L0": L0, name: value},
                         input_kind=idn.INPUT_LOAD, input=np.array([10.0, 10.0]), output="strain")
    with pytest.raises(RuntimeError, match=text):
        idn.simulate(exp)


def test_fit_bilinear_model_from_the_load_elongation_curve(write_trace, tmp_path, run_cli):
    """A load-unload test drawn by the engine from the bilinear law (0-40 N, noise 5e-5 m): the
    start (the corner on a grid, the two slopes linear) within 10 %, the fit within 2 %."""
    t = np.linspace(0.0, 200.0, 801)
    load = 40.0 * np.sin(np.pi * t / 200.0) ** 2
    exp = idn.Experiment(t, settings={**{k: float(v) for k, v in BILINEAR.items()}, "rig": 3, "L0": L0},
                         input_kind=idn.INPUT_LOAD, input=load, output="elongation")
    noise = 5e-5
    u = idn.simulate(exp) + np.random.default_rng(3).normal(0.0, noise, t.size)
    stem = write_trace("toe_load", write_trace.meta("load_unload"), {"time": t, "load": load, "elongation": u})
    from tether.fit import initial_estimate
    from tether.traces import read_trace
    start = initial_estimate([read_trace(stem)], "bilinear")
    out = tmp_path / "P.json"
    status, _, err = run_cli("fit", stem, "--model", "bilinear", "--out", out)
    assert status == 0, err
    fitted = json.loads(out.read_text())["parameters"]
    truth = {"toe_EA": TOE_EA, "EA": EA, "toe_eps": TOE_EPS, "toe_width": TOE_WIDTH}
    print("FIGURE fit of the bilinear law on a load test: " + ", ".join(
        f"{k} start {start[k]:.4g} fitted {fitted[k]:.5g} (truth {v})" for k, v in truth.items()))
    for k in ("toe_EA", "EA", "toe_eps"):
        assert abs(start[k] / truth[k] - 1) < 0.1, k
        assert abs(fitted[k] / truth[k] - 1) < 0.02, k
    assert abs(fitted["toe_width"] / TOE_WIDTH - 1) < 0.2


def test_fit_bilinear_model_of_a_free_vibration_that_reaches_into_the_toe(write_trace):
    """A free vibration of 1.5 kg drawn by the engine (balance strain 0.0097, released 0.1 m above
    it, so the strain falls to 0.0035, inside the toe; noise 5e-5 m): the start from the restoring
    force the equation error leaves, and the fit, recover the two slopes and the corner."""
    from tether.fit import fit_traces, initial_estimate
    from tether.traces import read_trace
    m = 1.5
    t = np.arange(0.0, 8.0, 0.002)
    settings = BILINEAR | dict(rig=2, damping=1, slack=False, m=m, g=G, L0=L0, x0=-0.1, v0=0.0, c0=0.8)
    x = idn.simulate(idn.Experiment(t, settings={k: float(v) for k, v in settings.items()}))
    x = x + np.random.default_rng(1).normal(0.0, 5e-5, t.size)
    meta = write_trace.meta("free_vibration", payload_mass_kg=m, initial_displacement_m=-0.1, initial_velocity_m_s=0.0)
    trace = read_trace(write_trace("toe_fv", meta, {"time": t, "displacement": x}))
    start = initial_estimate([trace], "bilinear")
    fit = fit_traces([trace], "bilinear")
    v = fit.values
    truth = {"toe_EA": TOE_EA, "EA": EA, "toe_eps": TOE_EPS}
    print(f"FIGURE bilinear law, free vibration into the toe: RMS {fit.rms / 5e-5:.3f} x noise; " + ", ".join(
        f"{k} start {start[k]:.4g} fitted {v[k]:.5g} (truth {tv})" for k, tv in truth.items()))
    for k, tv in truth.items():
        assert abs(start[k] / tv - 1) < 0.3, k      # measured: toe_EA 23 % low, EA 1 %, toe_eps 10 %
        assert abs(v[k] / tv - 1) < 0.02, k
    assert fit.rms < 1.05 * 5e-5


def test_model_strings_name_the_bilinear_law():
    from tether.models import ModelError, parse_model
    spec = parse_model("linear+bilinear+slack")
    assert spec.switches["stiffness"] == 4 and spec.effects == ["nonlinear_stiffness", "slack"]
    assert spec.parameters[:4] == ["EA", "toe_EA", "toe_eps", "toe_width"]
    assert spec.canonical == "linear+bilinear+slack"
    with pytest.raises(ModelError, match="'cubic' conflicts with 'bilinear'"):
        parse_model("bilinear+cubic")
    with pytest.raises(ModelError, match="Kawabata branches replace the elastic law"):
        parse_model("kawabata+bilinear")
