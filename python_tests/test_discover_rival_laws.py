"""The rival laws of the effects beside the hysteresis (rival.other_rival_laws, the plan's stage
"other rival laws"): where the final model still misses the record, a named effect whose law names
a rival (Law.rival) is fitted again with the rival in its place. Checked on a free vibration drawn
by the engine with the bilinear elastic law and fitted first with the cubic, and the elastic laws'
tension and curve fits against their closed forms. 'FIGURE ...' lines print what was measured."""
from __future__ import annotations

import numpy as np
import pytest

from tether import discover as D
from tether import identify_native as idn
from tether.discover import judge, laws, rival, samples, scales
from tether.discover.fitting import ModelFit, _heldout
from tether.fit.elastic import cubic_from_curve, elastic_from_curve, elastic_tension
from tether.models import parse_model
from tether.traces import read_trace

M, G, L0, NOISE, X0 = 1.5, 9.81, 16.0, 5e-5, -0.05
TOE = {"EA": 3400.0, "toe_EA": 1200.0, "toe_eps": 0.006, "toe_width": 0.0008}


def _toe_tension(eps):
    """The bilinear law written out (docs/models.md): toe_EA eps + (EA - toe_EA) w (softplus((eps -
    toe_eps)/w) - softplus(-toe_eps/w))."""
    w = TOE["toe_width"]
    sp = lambda y: np.logaddexp(0.0, y)  # noqa: E731
    return TOE["toe_EA"] * eps + (TOE["EA"] - TOE["toe_EA"]) * w * (sp((eps - TOE["toe_eps"]) / w)
                                                                   - sp(-TOE["toe_eps"] / w))


@pytest.fixture(scope="module")
def toe_record(tmp_path_factory):
    """A free vibration of 1.5 kg on a toe-linear tether drawn by the engine (balance strain 0.0097,
    released 0.05 m above it: the strain falls to 0.0066, into the toe's rounded corner; 6 s at
    250 Hz, noise 5e-5 m), the part held-out tests fit and the samples they hold out, and the cubic model's fit to it from the linear one's (as
    a step adds the cubic: 25.7 x noise)."""
    d = tmp_path_factory.mktemp("rival_laws")
    t = np.arange(0.0, 6.0, 0.004)
    settings = dict(rig=2, stiffness=4, hysteresis=1, damping=1, creep=0, slack=0, m=M, g=G, L0=L0, x0=X0,
                    v0=0.0, c0=0.8, **TOE)
    x = idn.simulate(idn.Experiment(t, settings={k: float(v) for k, v in settings.items()}))
    x = x + np.random.default_rng(3).normal(0.0, NOISE, t.size)
    (d / "toe.json").write_text(
        '{"format": "tether-trace/1", "experiment": "free_vibration", "tether": {"length_m": 16.0}, '
        '"payload_mass_kg": 1.5, "initial_displacement_m": %s, "initial_velocity_m_s": 0.0}' % X0)
    np.savetxt(d / "toe.csv", np.column_stack([t, x]), delimiter=",", header="time,displacement", comments="")
    tr = read_trace(d / "toe")
    part, held_out = samples.heldout_split(tr, judge.CRITERIA.fit_part)
    sc = scales._scales(tr)
    cubic = parse_model("linear+cubic", tr.experiment)
    lin = D.fit_model(tr, parse_model("linear", tr.experiment), (), [None], sc)
    cur = D.fit_model(tr, cubic, ("nonlinear_stiffness",), [{**lin.params, "a1": lin.params["EA"], "a2": 0.0,
                                                             "a3": 0.0}, None], sc)
    return tr, part, held_out, sc, cur


def _fit(sc, sc_part, part):
    def fit(tr, sp, eff, starts, baseline_rms=None, **options):
        return D.fit_model(tr, sp, eff, starts, sc_part if tr is part else sc, baseline_rms=baseline_rms, **options)
    return fit


def test_the_elastic_laws_tension_and_curve_fits_follow_their_closed_forms():
    """elastic_tension is each law's closed form; cubic_from_curve recovers a cubic's coefficients
    from its own samples; the bilinear law fitted to the toe's samples recovers its two slopes and
    corner (on its grid of corners: within 2 %)."""
    eps = np.linspace(0.002, 0.02, 200)
    assert np.allclose(elastic_tension("bilinear", TOE, eps), _toe_tension(eps), rtol=1e-12)
    cubic = {"a1": 3000.0, "a2": 2.0e5, "a3": -1.0e6}
    F = 3000.0 * eps + 2.0e5 * eps ** 2 - 1.0e6 * eps ** 3
    assert np.allclose(elastic_tension("cubic", cubic, eps), F, rtol=1e-12)
    got = cubic_from_curve(eps, F)
    assert all(abs(got[k] / v - 1) < 1e-8 for k, v in cubic.items()), got
    assert cubic_from_curve(eps, -F) is None                  # a law that falls is no elastic law
    toe = elastic_from_curve("bilinear", eps, _toe_tension(eps))
    for k in ("EA", "toe_EA", "toe_eps"):
        assert abs(toe[k] / TOE[k] - 1) < 0.02, (k, toe[k])


def test_a_cubic_that_misses_a_toe_gives_way_to_its_rival_the_bilinear_law(toe_record):
    """The cubic fitted to the toe-linear record misses it (above CRITERIA.within_noise); the stage
    fits the bilinear law in its place and keeps it: the error falls to the noise, and the toe's two
    slopes and corner are the engine's within 2 %."""
    tr, part, held_out, sc, cur = toe_record
    assert cur.ok and cur.rms > judge.CRITERIA.within_noise * NOISE, cur.rms / NOISE
    part_fit = D.fit_model(part, cur.spec, cur.effects, [cur.params], scales._scales(part))
    held = _heldout(tr, cur.spec, part_fit.params, held_out)
    said = []
    new, new_held, refs = rival.other_rival_laws(tr, part, held_out, cur, held, NOISE,
                                                 _fit(sc, scales._scales(part), part), {}, said.append, sc=sc)
    (r,) = refs
    print(f"FIGURE rival law on a toe-linear free vibration: cubic {cur.rms / NOISE:.2f} x noise -> "
          f"{new.spec.stiffness} {new.rms / NOISE:.3f} x; " + ", ".join(
              f"{k} {new.params[k]:.5g} (truth {v})" for k, v in TOE.items() if k in new.params))
    assert r.accepted and r.law == "cubic -> bilinear", r.verdict
    assert new.spec.stiffness == "bilinear" and new.rms < 1.05 * NOISE
    for k in ("EA", "toe_EA", "toe_eps"):
        assert abs(new.params[k] / TOE[k] - 1) < 0.02, (k, new.params[k])
    assert any("cubic -> bilinear: kept" in s for s in said)


def test_a_model_within_the_noise_tries_no_rival(toe_record):
    """Where the model reproduces the record within CRITERIA.within_noise, no rival is fitted."""
    tr, part, held_out, sc, cur = toe_record
    calls = []
    within = ModelFit(spec=cur.spec, effects=cur.effects, params=cur.params, free=cur.free,
                     rms=NOISE, predicted=cur.predicted)
    out = rival.other_rival_laws(tr, part, held_out, within, NOISE, NOISE,
                                 lambda *a, **k: calls.append(a), {}, lambda s: None, sc=sc)
    assert calls == [] and out[0] is within and out[2] == []


def test_every_rival_law_is_a_law_of_the_same_effect_that_names_it_back():
    """Law.rival pairs laws of one effect: each rival is in the registry under the same effect, and
    names the law back (cubic and bilinear, c(x) and dry friction, Bouc-Wen and the Iwan bank)."""
    pairs = {}
    for e in laws.EFFECTS:
        for law in e.laws:
            if law.rival:
                other = e.law(law.rival)
                assert other is not None, (e.name, law.name, law.rival)
                assert other.rival == law.name, (e.name, law.name)
                pairs[e.name] = tuple(sorted((law.name, other.name)))
    assert pairs == {"nonlinear_stiffness": ("bilinear", "cubic"), "hysteresis": ("boucwen", "iwan"),
                     "nonlinear_damping": ("coulomb", "displacement")}
