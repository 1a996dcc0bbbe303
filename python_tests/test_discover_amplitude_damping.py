"""The amplitude law of nonlinear damping as the wider law of c(x) (rival.wider_law, the plan's stage
"wider laws"): a forced sweep through the resonance of a tether whose damping saturates with the
swing's amplitude, drawn by the engine, which c(x) misses; the stage fits the amplitude law in its
place, with its table of c(.) where the polynomial is not enough, and keeps it. 'FIGURE ...' lines
print what was measured."""
from __future__ import annotations

import numpy as np
import pytest

from tether import discover as D
from tether import identify_native as idn
from tether.discover import judge, rival, samples, scales
from tether.discover.fitting import _heldout
from tether.discover.laws import _replaced
from tether.models import parse_model
from tether.traces import read_trace

M, G, L0, EA, NOISE = 4.3, 9.81, 16.0, 5300.0, 5e-5
#: c(A) = c0 + table(A): saturating, from 0.4 at rest to 2.55 N s/m beyond A = 0.03 m
C0, DX = 0.4, 0.005
TABLE = {"c_table_1": 0.8, "c_table_2": 1.4, "c_table_3": 1.8, "c_table_4": 2.0, "c_table_5": 2.1,
         "c_table_6": 2.15}


@pytest.fixture(scope="module")
def sweep_record(tmp_path_factory):
    """A force of 1 N sweeping 0.4 -> 2.4 Hz over 16 s at 125 Hz through the payload's resonance
    (1.4 Hz), the damping the amplitude law's saturating table (noise 5e-5 m, amplitude up to 0.026 m);
    the part held-out tests fit and the samples they hold out, and the fit of c(x) (the polynomial
    c0 + c1 |x| + c2 x^2, as the damping step adds it) with its held-out error."""
    d = tmp_path_factory.mktemp("amplitude_damping")
    t = np.arange(0.0, 16.0, 0.008)
    f = np.sin(2 * np.pi * (0.4 * t + 0.5 * (2.0 / t[-1]) * t ** 2))
    settings = dict(rig=2, stiffness=1, hysteresis=1, damping=4, creep=0, slack=0, m=M, g=G, L0=L0, EA=EA,
                    x0=0.0, v0=0.0, c0=C0, c1=0.0, c2=0.0, c_table_dx=DX, **TABLE)
    e = idn.Experiment(t, settings={k: float(v) for k, v in settings.items()}, input_kind=idn.INPUT_FORCE,
                       input=f, input_der=idn.spline_derivatives(t, f))
    x = idn.simulate(e) + np.random.default_rng(5).normal(0.0, NOISE, t.size)
    (d / "sweep.json").write_text(
        '{"format": "tether-trace/1", "experiment": "forced", "tether": {"length_m": 16.0}, '
        '"payload_mass_kg": 4.3, "initial_displacement_m": 0.0, "initial_velocity_m_s": 0.0}')
    np.savetxt(d / "sweep.csv", np.column_stack([t, f, x]), delimiter=",", header="time,force,displacement",
               comments="")
    tr = read_trace(d / "sweep")
    part, held_out = samples.heldout_split(tr, judge.CRITERIA.fit_part)
    sc, sc_part = scales._scales(tr), scales._scales(part)
    spec = parse_model("linear+nonlinear_damping", tr.experiment)
    cur = D.fit_model(tr, spec, ("nonlinear_damping",), [None], sc)
    part_fit = D.fit_model(part, spec, cur.effects, [cur.params], sc_part)
    return tr, part, held_out, sc, sc_part, cur, _heldout(tr, spec, part_fit.params, held_out)


def _fit(sc, sc_part, part):
    """The stage's fit, as the search gives it: shape terms ``extra`` free, the terms they replace held."""
    def fit(tr, sp, eff, starts, baseline_rms=None, extra=()):
        return D.fit_model(tr, sp, eff, starts, sc_part if tr is part else sc, extra=extra, held=_replaced(extra),
                           baseline_rms=baseline_rms)
    return fit


def test_c_of_x_that_misses_a_damping_of_the_amplitude_gives_way_to_the_amplitude_law(sweep_record):
    """c(x) misses the sweep (above CRITERIA.within_noise); the wider-law stage puts the amplitude
    law in its place and keeps it within the noise, its c(.) within 5 % of the engine's at the
    amplitudes the sweep reaches."""
    tr, part, held_out, sc, sc_part, cur, held = sweep_record
    assert cur.ok and cur.rms > 1.5 * NOISE, cur.rms / NOISE
    said = []
    new, new_held, refs = rival.wider_law(tr, part, held_out, cur, held, NOISE, _fit(sc, sc_part, part),
                                          said.append, sc=sc)
    kept = [r for r in refs if r.accepted]
    p = new.params
    a = np.array([0.005, 0.01, 0.015, 0.02])
    truth = C0 + np.interp(a, DX * np.arange(7), [0.0] + list(TABLE.values()))
    knots = p.get("c_table_dx", 0.0) * np.arange(7)
    fitted = (p["c0"] + p.get("c1", 0.0) * a + p.get("c2", 0.0) * a ** 2
              + (np.interp(a, knots, [0.0] + [p[k] for k in TABLE]) if knots[-1] > 0 else 0.0))
    print(f"FIGURE wider law on a forced sweep with a damping of the amplitude: c(x) {cur.rms / NOISE:.2f} x noise "
          f"-> {new.spec.damping} {new.rms / NOISE:.3f} x; c(A) at A = {a.tolist()} m: {np.round(fitted, 3).tolist()} "
          f"(engine {np.round(truth, 3).tolist()}); " + "; ".join(f"{r.law}: {r.verdict}" for r in refs))
    assert len(kept) == 1 and kept[0].law == "displacement -> amplitude", [r.verdict for r in refs]
    assert new.spec.damping == "amplitude" and new.rms < 1.1 * NOISE
    assert np.max(np.abs(fitted / truth - 1.0)) < 0.05
    assert any("displacement -> amplitude: kept" in s for s in said)

