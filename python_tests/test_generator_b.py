"""Generator B (bench/generator_b): each law against a closed form or a second implementation,
and its files against the trace format."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.generator_b import GenerationError, generate, read_trace, suite, write_trace  # noqa: E402
from bench.generator_b import cli, dynamic, quasistatic  # noqa: E402
from bench.generator_b.experiments import REVEALABLE, payload_model  # noqa: E402
from bench.generator_b.laws import (AmplitudeDamping, BurgersCreep, CoulombViscousDamping,  # noqa: E402
                                    DahlHysteresis, ExponentialElastic, FindleyCreep, LinearElastic,
                                    StopBankHysteresis, ToeLinearElastic, ViscousDamping)

G = 9.81


def payload(elastic, damping, hysteresis=None, slack=False, L=16.0, m=4.3):
    u_b = L * quasistatic.elastic_strain_for(elastic, m * G)
    return dynamic.PayloadModel(L, m, G, elastic, damping, hysteresis, slack, u_b)


# ---------------------------------------------------------------------------------------------
# dynamic tests


def test_linear_free_vibration_is_the_damped_oscillator():
    L, m, EA, c = 16.0, 4.3, 3000.0, 1.2
    model = payload(LinearElastic(EA), ViscousDamping(c), L=L, m=m)
    t = np.arange(0, 15.0, 1 / 200)
    x = dynamic.simulate(model, t, -0.1669, 0.0).x
    w = math.sqrt(EA / L / m)
    zeta = c / (2 * m * w)
    wd = w * math.sqrt(1 - zeta ** 2)
    exact = -0.1669 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    assert np.max(np.abs(x - exact)) < 1e-9


def test_forced_nonlinear_payload_matches_a_second_integrator():
    """Exponential stiffness, Coulomb + viscous and amplitude damping under a multisine:
    the fixed-step RK4 against scipy's DOP853 at tight tolerance on the same equations."""
    L, m = 12.0, 3.0
    elastic = ExponentialElastic(EA0=1800.0, eps_c=0.02)
    for damping in (CoulombViscousDamping(c0=0.3, F_c=0.4, v_s=0.05),
                    AmplitudeDamping(c0=0.1, c1=1.5, A_d=0.02, omega=8.0)):
        model = payload(elastic, damping, L=L, m=m)
        t = np.arange(0, 8.0, 1 / 250)

        def force(tt):
            tt = np.asarray(tt, float)
            return 3.0 * np.sin(2 * np.pi * 1.1 * tt) + 2.0 * np.cos(2 * np.pi * 1.9 * tt + 0.3)

        x = dynamic.simulate(model, t, 0.0, 0.0, force).x

        def rhs(tt, y):
            u, v = y
            T = elastic.tension(u / L) + damping.force(u - model.u_balance, v)
            return [v, G + (float(force(tt)) - T) / m]

        ref = solve_ivp(rhs, (0, t[-1]), [model.u_balance, 0.0], t_eval=t, method="DOP853",
                        rtol=1e-12, atol=1e-14).y[0] - model.u_balance
        assert np.max(np.abs(x - ref)) < 1e-8 * max(1.0, np.max(np.abs(ref)) / 0.01)


def test_toe_tether_with_dahl_friction_matches_a_second_integrator():
    L, m = 14.0, 4.0
    elastic = ToeLinearElastic(k_toe=900.0, EA=3500.0, eps_t=0.009, width=0.0015)
    law = DahlHysteresis(k=30000.0, F_sat=0.8, asym=-0.3)
    model = payload(elastic, ViscousDamping(0.2), law, L=L, m=m)
    t = np.arange(0, 6.0, 1 / 200)

    def force(tt):
        return 4.0 * np.sin(2 * np.pi * 1.3 * np.asarray(tt, float))

    x = dynamic.simulate(model, t, 0.03, 0.0, force).x

    def rhs(tt, y):
        u, v, z = y
        T = elastic.tension(u / L) + 0.2 * v + z
        return [v, G + (float(force(tt)) - T) / m, law.rate(z, v / L)]

    ref = solve_ivp(rhs, (0, t[-1]), [model.u_balance + 0.03, 0.0, 0.0], t_eval=t, method="DOP853",
                    rtol=1e-12, atol=1e-14, max_step=2e-3).y[0] - model.u_balance
    assert np.max(np.abs(x - ref)) < 1e-8


def test_stop_bank_free_vibration_matches_jenkins_cells_integrated_by_scipy():
    """Three stop cells as Jenkins elements (a spring state that stops growing at +-r_i),
    integrated by DOP853 as ODEs; generator B carries them as a strain-path memory instead."""
    L, m, EA, c = 12.0, 3.5, 3000.0, 0.05
    law = StopBankHysteresis(stiffness=500.0, r_max=2.5e-3, alpha=1.0, count=3)
    model = payload(LinearElastic(EA), ViscousDamping(c), law, L=L, m=m)
    t = np.arange(0, 3.0, 1 / 200)
    x = dynamic.simulate(model, t, 0.06, 0.0).x
    w, r = np.array(law.weights), np.array(law.radii)

    def rhs(tt, y):
        u, v, s = y[0], y[1], y[2:]
        rate = v / L
        slipping = ((s >= r) & (rate > 0)) | ((s <= -r) & (rate < 0))
        T = EA * u / L + c * v + w @ np.clip(s, -r, r)
        return np.concatenate([[v, G - T / m], np.where(slipping, 0.0, rate)])

    y0 = np.concatenate([[model.u_balance + 0.06, 0.0], np.zeros(3)])
    ref = solve_ivp(rhs, (0, t[-1]), y0, t_eval=t, method="DOP853", rtol=1e-10, atol=1e-13,
                    max_step=1e-3).y[0] - model.u_balance
    assert np.max(np.abs(x - ref)) < 1e-7


def test_undamped_exponential_tether_conserves_energy():
    L, m = 10.0, 5.0
    law = ExponentialElastic(EA0=2500.0, eps_c=0.015)
    model = payload(law, ViscousDamping(0.0), L=L, m=m)
    t = np.arange(0, 10.0, 1 / 100)
    res = dynamic.simulate(model, t, 0.08, 0.0)
    u = res.x + model.u_balance
    eps = u / L
    stored = L * law.EA0 * law.eps_c * (law.eps_c * np.expm1(eps / law.eps_c) - eps)
    energy = 0.5 * m * res.v ** 2 + stored - m * G * u
    assert np.ptp(energy) < 1e-9 * stored.max()


def test_slack_flight_is_a_parabola_and_its_events_are_located():
    """Undamped linear tether released at rest 2 static stretches above balance: free fall to the
    natural length, a taut arc of 2 delta / omega, a parabolic flight of 2 v1 / g, and again."""
    L, m, EA = 16.0, 4.3, 3000.0
    model = payload(LinearElastic(EA), ViscousDamping(0.0), slack=True, L=L, m=m)
    u_b = model.u_balance
    t = np.arange(0, 6.0, 1 / 100)
    res = dynamic.simulate(model, t, -2 * u_b, 0.0)
    w = math.sqrt(EA / L / m)
    t1 = math.sqrt(2 * u_b / G)
    v1 = G * t1
    delta = math.atan2(v1 / w, -u_b)
    taut, flight = 2 * delta / w, 2 * v1 / G
    expected, kinds, now = [], [], t1
    while now < t[-1]:
        expected.append(now)
        kinds.append("slack_exit")
        now += taut
        if now < t[-1]:
            expected.append(now)
            kinds.append("slack_entry")
        now += flight
    assert res.starts_slack
    assert [k for _, k in res.events] == kinds
    assert np.max(np.abs(np.array([tt for tt, _ in res.events]) - expected)) < 1e-9
    entry = expected[1]
    in_flight = (t > entry) & (t < entry + flight)
    s = t[in_flight] - entry
    parabola = -v1 * s + 0.5 * G * s ** 2 - u_b
    assert in_flight.sum() > 20
    assert np.max(np.abs(res.x[in_flight] - parabola)) < 1e-9
    bounds = [0.0] + expected + [t[-1]]
    assert res.slack_time_s == pytest.approx(sum(bounds[i + 1] - bounds[i] for i in range(0, len(bounds) - 1, 2)),
                                             abs=1e-9)


def test_taut_record_never_clamps_without_slack_hidden():
    model = payload(LinearElastic(3000.0), ViscousDamping(0.5), slack=False)
    res = dynamic.simulate(model, np.arange(0, 3.0, 0.01), -0.5 * model.u_balance, 0.0)
    assert res.min_tension_candidate > 0 and res.events == []


# ---------------------------------------------------------------------------------------------
# hysteresis


@pytest.mark.parametrize("asym", [0.0, 0.35])
def test_dahl_rate_law_loop_reaches_its_steady_state_closed_form(asym):
    """Strain driven as A sin(w t): after a few cycles z at the turning point is the steady loop's
    (F tanh(k A / F) when symmetric), and the rising branch from -A is
    F_up - (F_up - z_low) exp(-k (eps + A) / F_up)."""
    law = DahlHysteresis(k=4000.0, F_sat=2.0, asym=asym)
    A, w = 1.2e-3, 2 * np.pi

    def rhs(t, z):
        return [law.rate(z[0], A * w * math.cos(w * t))]

    t = np.linspace(0, 8.0, 8001)
    z = solve_ivp(rhs, (0, 8.0), [0.0], t_eval=t, rtol=1e-11, atol=1e-13, max_step=1e-3).y[0]
    z_top = law.steady_loop_peak(A)
    if asym == 0.0:
        assert z_top == pytest.approx(law.F_sat * math.tanh(law.k * A / law.F_sat), rel=1e-12)
    assert z[np.argmin(np.abs(t - 7.25))] == pytest.approx(z_top, rel=1e-6)
    z_low = z[np.argmin(np.abs(t - 6.75))]
    rising = (t >= 6.75) & (t <= 7.25)
    eps = A * np.sin(w * t[rising])
    branch = law.F_up - (law.F_up - z_low) * np.exp(-law.k * (eps + A) / law.F_up)
    assert np.max(np.abs(z[rising] - branch)) < 1e-6 * law.F_sat
    assert law.branch(z_low, 2 * A) == pytest.approx(z_top, rel=1e-6)


def test_stop_bank_virgin_curve_masing_branch_and_dissipation():
    law = StopBankHysteresis(stiffness=800.0, r_max=2e-3, alpha=1.7, count=16)
    q_top = 2.6e-3
    p = [0.0] * law.count
    for q in np.linspace(0, q_top, 300)[1:]:
        assert law.force(p, q) == pytest.approx(law.virgin(q), rel=1e-12, abs=1e-12)
        p = law.outputs(p, q)
    z_top = law.force(p, q_top)
    for q in np.linspace(q_top, -q_top, 400)[1:]:
        assert z_top - law.force(p, q) == pytest.approx(2 * law.virgin((q_top - q) / 2), rel=1e-12, abs=1e-12)
        p = law.outputs(p, q)
    # a steady symmetric cycle of amplitude a dissipates sum 4 w r (a - r) over the slipped cells
    a, work = 1.5e-3, 0.0
    path = a * np.cos(np.linspace(0, 2 * np.pi, 4001))
    for _ in range(2):
        work = 0.0
        for q0, q1 in zip(path[:-1], path[1:]):
            work += 0.5 * (law.force(p, q0) + law.force(law.outputs(p, q1), q1)) * (q1 - q0)
            p = law.outputs(p, q1)
    expected = sum(4 * w * r * (a - r) for w, r in zip(law.weights, law.radii) if r < a)
    assert work > 0 and work == pytest.approx(expected, rel=2e-3)


def test_quasi_static_dahl_loop_follows_the_closed_form_branches():
    """Linear tether with Dahl friction, loaded 3 -> 40 N and unloaded to 10 N in 0.5 N steps: the
    virgin branch is EA (e - e0) + F (1 - exp(-k (e - e0) / F)) = load - load0, the unloading
    branch EA e - F + (F + z_top) exp(-k (e_top - e) / F); at the same load it is longer."""
    EA, k, F = 3000.0, 40000.0, 2.5
    elastic, law = LinearElastic(EA), DahlHysteresis(k=k, F_sat=F)
    up, down = np.arange(3.0, 40.25, 0.5), np.arange(40.0, 9.75, -0.5)
    load = np.concatenate([up, down[1:]])
    eps = quasistatic.elastic_strains(elastic, law, load)
    e0, n_up = eps[0], len(up)
    rise = eps[:n_up] - e0
    assert np.max(np.abs(EA * rise + F * (-np.expm1(-k * rise / F)) - (up - 3.0))) < 1e-9
    e_top = eps[n_up - 1]
    z_top = up[-1] - EA * e_top
    e = eps[n_up:]
    branch = EA * e - F + (F + z_top) * np.exp(-k * (e_top - e) / F)
    assert np.max(np.abs(branch - down[1:])) < 1e-9
    at_20_up, at_20_down = eps[np.flatnonzero(up == 20.0)[0]], eps[n_up - 1 + np.flatnonzero(down == 20.0)[0]]
    assert at_20_down - at_20_up > 1e-4


def test_quasi_static_stop_bank_follows_the_virgin_curve_then_masing():
    EA = 3000.0
    law = StopBankHysteresis(stiffness=600.0, r_max=3e-3, alpha=0.8, count=20)
    up, down = np.linspace(4.0, 45.0, 83), np.linspace(45.0, 12.0, 67)
    eps = quasistatic.elastic_strains(LinearElastic(EA), law, np.concatenate([up, down[1:]]))
    rise = eps[:len(up)] - eps[0]
    virgin = np.array([law.virgin(q) for q in rise])
    assert np.max(np.abs(EA * rise + virgin - (up - 4.0))) < 1e-9
    fall = eps[len(up) - 1] - eps[len(up):]
    masing = np.array([2 * law.virgin(d / 2) for d in fall])
    assert np.max(np.abs(EA * fall + masing - (45.0 - down[1:]))) < 1e-9


# ---------------------------------------------------------------------------------------------
# elastic and creep laws


def test_elastic_laws_tangent_is_the_derivative_and_toe_has_two_slopes():
    toe = ToeLinearElastic(k_toe=800.0, EA=4000.0, eps_t=0.006, width=0.0005)
    laws = [ExponentialElastic(EA0=2000.0, eps_c=0.01), toe, LinearElastic(3500.0)]
    for law in laws:
        for e in (0.001, 0.005, 0.012):
            h = 1e-7
            numeric = (law.tension(e + h) - law.tension(e - h)) / (2 * h)
            assert law.tangent(e) == pytest.approx(numeric, rel=1e-6)
        assert law.tension(0.0) == pytest.approx(0.0, abs=1e-12)
    assert toe.tangent(0.0005) == pytest.approx(800.0, rel=1e-4)
    assert toe.tangent(0.02) == pytest.approx(4000.0, rel=1e-9)


def test_burgers_step_load_and_recovery_closed_form():
    """Hung at t = 0 (a 1 us ramp), held for t2, unloaded (1 us): while loaded
    eps = F/EA + F/K (1 - e^-t/tau) + F t / eta; after, the Kelvin part decays from its value at
    t2 and the dashpot's flow F t2 / eta stays."""
    EA, F, K, tau, eta, t2, ramp = 3000.0, 100.0, 4e5, 1800.0, 3e9, 7200.0, 1e-6
    loaded_t = ramp + np.arange(0, t2 + 1.0, 30.0)
    rest_t = loaded_t[-1] + ramp + np.arange(0, 3600.0, 30.0)
    t = np.concatenate([[0.0], loaded_t, rest_t])
    load = np.concatenate([[0.0], np.full(len(loaded_t), F), np.zeros(len(rest_t))])
    eps = quasistatic.elongation(10.0, LinearElastic(EA), None, BurgersCreep(K=K, tau=tau, eta=eta),
                                 t, load)["elongation"] / 10.0
    s = loaded_t - ramp
    exact = F / EA + F / K * (1 - np.exp(-s / tau)) + F * s / eta
    assert np.max(np.abs(eps[1:len(loaded_t) + 1] - exact)) < 1e-10
    s = rest_t - rest_t[0]
    exact = F / K * (1 - math.exp(-t2 / tau)) * np.exp(-s / tau) + F * t2 / eta
    assert np.max(np.abs(eps[len(loaded_t) + 1:] - exact)) < 1e-10


def test_burgers_under_ramps_matches_a_second_integrator():
    law = BurgersCreep(K=2e5, tau=300.0, eta=1e9)
    t = np.linspace(0, 2000.0, 201)
    load = 5 + 45 * np.clip(t / 600, 0, 1) - 30 * np.clip((t - 1200) / 400, 0, 1)
    got = law.strain(t, load)

    def rhs(tt, y):
        F = np.interp(tt, t, load)
        return [(F / law.K - y[0]) / law.tau, F / law.eta]

    ref = solve_ivp(rhs, (0, 2000.0), [load[0] / law.K, 0.0], t_eval=t, rtol=1e-11, atol=1e-15,
                    max_step=5.0).y.sum(axis=0)
    assert np.max(np.abs(got - ref)) < 1e-10


def test_findley_step_creep_and_recovery_by_superposition():
    law = FindleyCreep(b=3e-7, n=0.3, F_s=80.0, preload_age=1000.0)
    F, ramp, t1 = 60.0, 1e-4, 5000.0
    t = np.concatenate([[0.0], ramp + np.arange(0, t1, 50.0), [t1 + ramp], t1 + 2 * ramp + np.arange(0, 5000, 50.0)])
    load = np.where((t > 0) & (t <= t1 + ramp - 1e-9), F, 0.0)
    load[np.searchsorted(t, t1 + ramp)] = F
    eps = law.strain(t, load)
    G = law.F_s * math.sinh(F / law.F_s)
    loaded = (t > 10) & (t < t1)
    assert np.max(np.abs(eps[loaded] - law.b * G * t[loaded] ** law.n) / (law.b * G * t[loaded] ** law.n)) < 1e-5
    after = t > t1 + 10
    recovery = law.b * G * (t[after] ** law.n - (t[after] - t1) ** law.n)
    assert np.max(np.abs(eps[after] - recovery)) < 1e-5 * law.b * G * t1 ** law.n
    assert np.all(np.diff(eps[after]) < 0)


# ---------------------------------------------------------------------------------------------
# the suite and its files


def test_suite_draw_is_reproducible_and_composed_as_promised():
    a, b = suite(48, seed=11), suite(48, seed=11)
    assert json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    assert json.dumps(a, sort_keys=True) != json.dumps(suite(48, seed=12), sort_keys=True)
    counts = {e: sum(s["experiment"] == e for s in a) for e in REVEALABLE}
    assert counts == {"free_vibration": 16, "forced": 16, "load_unload": 8, "creep": 8}
    nulls = [s for s in a if not s["effects"]]
    assert 8 <= len(nulls) <= 12
    for s in a:
        assert set(s["effects"]) <= set(REVEALABLE[s["experiment"]]) and len(s["effects"]) <= 3
        assert len({s["name"] for s in a}) == 48
        if not s["effects"]:
            assert s["laws"] == {"elastic": "linear", "damping": "viscous", "hysteresis": None,
                                 "creep": None, "slack": False}


def _short(spec: dict) -> dict:
    """The same spec on a short, coarse record (keeps the test fast)."""
    spec = json.loads(json.dumps(spec))
    if "record" in spec:
        spec["record"] = {"fs_hz": 100, "duration_s": 6.0}
        if spec["experiment"] == "forced" and spec["input"]["kind"] == "sweep":
            spec["input"]["sweep_s"] = 6.0
    return spec


def test_written_traces_follow_the_format_and_carry_the_truth(tmp_path):
    from tether.traces import read_trace as product_read_trace

    specs = {}
    for s in suite(48, seed=5):
        if s["laws"]["hysteresis"] != "pi_stop" or s["experiment"] != "forced":   # the slowest to calibrate
            specs.setdefault((s["experiment"], bool(s["effects"])), s)
    assert len(specs) == 8
    for spec in specs.values():
        spec = _short(spec)
        columns, meta = generate(spec)
        stem = write_trace(tmp_path, spec["name"], columns, meta)
        back, meta2 = read_trace(stem)
        product = product_read_trace(stem)          # the product's own reader takes it as it is
        assert product.experiment == spec["experiment"] and product.n == len(back["time"])
        assert meta2["format"] == "tether-trace/1" and meta2["experiment"] == spec["experiment"]
        assert np.all(np.diff(back["time"]) > 0)
        hidden = meta2["hidden"]
        assert hidden["effects"] == sorted(spec["effects"])
        assert set(hidden["effects"]) <= set(hidden["revealable"])
        assert hidden["noise_sigma"] == spec["noise_sigma"] and "parameters" in hidden
        if spec["experiment"] == "forced":
            continue   # calibrated again on a second run; the other experiments show the noise
        clean, _ = generate(dict(spec, noise_sigma=0.0))
        measured = "displacement" if "displacement" in back else "elongation"
        noise = back[measured] - clean[measured]
        assert np.std(noise) == pytest.approx(spec["noise_sigma"], rel=0.15)
        if spec["experiment"] == "free_vibration":
            assert meta2["initial_displacement_m"] == clean["displacement"][0]
    assert not list(tmp_path.glob("*.part"))


def test_null_free_vibration_is_exactly_the_format_baseline():
    spec = next(s for s in suite(48, seed=3) if s["experiment"] == "free_vibration" and not s["effects"])
    spec = dict(_short(spec), noise_sigma=0.0)
    columns, meta = generate(spec)
    L, m = meta["tether"]["length_m"], meta["payload_mass_kg"]
    EA, c = meta["hidden"]["parameters"]["elastic"]["EA"], meta["hidden"]["parameters"]["damping"]["c0"]
    w = math.sqrt(EA / L / m)
    zeta = c / (2 * m * w)
    wd = w * math.sqrt(1 - zeta ** 2)
    t, x0 = columns["time"], meta["initial_displacement_m"]
    exact = x0 * np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    assert np.max(np.abs(columns["displacement"] - exact)) < 1e-9


def test_hidden_slack_that_never_acts_is_refused():
    spec = _short(next(s for s in suite(48, seed=3) if s["experiment"] == "free_vibration"
                       and s["laws"]["slack"]))
    spec["input"]["x0_m"] = -0.2 * payload_model(spec).u_balance
    with pytest.raises(GenerationError, match="never goes slack"):
        generate(spec)


def test_command_line_writes_a_suite_and_refuses_a_full_directory(tmp_path, capsys):
    out = tmp_path / "draw"
    specs = [_short(s) for s in suite(6, seed=9) if s["experiment"] != "forced"]
    cli.write_suite(specs, out, progress=None)
    names = sorted(p.stem for p in out.glob("*.json"))
    assert json.loads((out / "suite.manifest").read_text())["traces"] == [s["name"] for s in specs]
    assert names == sorted(s["name"] for s in specs)
    with pytest.raises(SystemExit):
        cli.main(["--n", "2", "--seed", "1", "--out", str(out)])
    assert "not an empty directory" in capsys.readouterr().err


def test_command_line_leaves_nothing_when_a_trace_fails(tmp_path, monkeypatch):
    calls = []

    def failing(spec):
        calls.append(spec["name"])
        if len(calls) == 2:
            raise GenerationError(f"{spec['name']}: refused for the test")
        return generate(_short(spec))

    monkeypatch.setattr(cli, "generate", failing)
    out = tmp_path / "draw"
    with pytest.raises(GenerationError):
        cli.main(["--n", "4", "--seed", "9", "--out", str(out)])
    assert len(calls) == 2 and not out.exists() and not list(tmp_path.iterdir())
