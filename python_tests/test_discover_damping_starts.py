"""Where a damping candidate starts when the current model's viscous damping has collapsed: a
hysteresis law fitted first can take over all the damping, and its c0 falls towards zero (to
4e-238 N s/m on a development record of the second generator). The damping candidates' starts are
scaled by c0; from the collapsed value they gave the damping nothing to grow from (its terms are
scaled by their starts), so the candidate could not gain. starts._viscous_reference keeps that scale
at the fit's floor (fit.parameters.c0_floor). A free vibration drawn by the engine with a damping
that grows with |x| shows it: the candidate from the collapsed base gains what it gains from the
base's own damping, where before it ended at 400 x noise. 'FIGURE ...' lines print what was measured."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from tether import identify_native as idn
from tether.discover import scales
from tether.discover.fitting import fit_model
from tether.discover.starts import _viscous_reference, candidate_starts
from tether.fit.parameters import c0_floor
from tether.models import parse_model
from tether.traces import read_trace

M, G, L0, EA, NOISE = 4.0, 9.81, 12.0, 3000.0, 4e-5
C0, C1, C2 = 0.3, 20.0, 600.0          # c(x) = c0 + c1 |x| + c2 x^2 [N s/m], x up to 0.05 m


@pytest.fixture(scope="module")
def damped_swing(tmp_path_factory):
    """A free vibration released 0.05 m below its balance, 12 s at 100 Hz, c(x) as above."""
    d = tmp_path_factory.mktemp("damping_starts")
    t = np.arange(0.0, 12.0, 0.01)
    settings = dict(rig=2, stiffness=1, hysteresis=1, damping=2, creep=0, slack=0, m=M, g=G, L0=L0, EA=EA,
                    x0=0.05, v0=0.0, c0=C0, c1=C1, c2=C2)
    e = idn.Experiment(t, settings={k: float(v) for k, v in settings.items()})
    x = idn.simulate(e) + np.random.default_rng(11).normal(0.0, NOISE, t.size)
    (d / "swing.json").write_text(
        '{"format": "tether-trace/1", "experiment": "free_vibration", "tether": {"length_m": 12.0}, '
        '"payload_mass_kg": 4.0, "initial_displacement_m": 0.05, "initial_velocity_m_s": 0.0}')
    np.savetxt(d / "swing.csv", np.column_stack([t, x]), delimiter=",", header="time,displacement", comments="")
    return read_trace(d / "swing")


def test_a_damping_candidate_grows_from_a_collapsed_viscous_damping(damped_swing):
    tr = damped_swing
    sc = scales._scales(tr)
    linear = parse_model("linear", tr.experiment)
    base = fit_model(tr, linear, (), [None], sc)
    collapsed = SimpleNamespace(params={**base.params, "c0": 4e-238}, spec=base.spec, effects=())
    new = parse_model("linear+nonlinear_damping", tr.experiment)
    floor = c0_floor(sc.k, sc.k / sc.omega ** 2)
    starts = candidate_starts(collapsed, new, sc, tr)
    assert all(s["c0"] >= 0.7 * floor and s["c1"] > 0 and s["c2"] > 0 for s in starts if s is not None)
    # a base damping above the floor is the reference as it is
    assert base.params["c0"] > floor and _viscous_reference(base, sc) == base.params["c0"]
    assert _viscous_reference(collapsed, sc) == floor
    fits = {name: fit_model(tr, new, ("nonlinear_damping",), candidate_starts(b, new, sc, tr), sc)
            for name, b in (("warm", base), ("collapsed", collapsed))}
    print(f"FIGURE c(x) from the linear fit's c0 ({base.params['c0']:.3g} N s/m): "
          f"{fits['warm'].rms / NOISE:.2f} x noise; from c0 = 4e-238 (starts at the floor {floor:.3g}): "
          f"{fits['collapsed'].rms / NOISE:.2f} x noise; linear {base.rms / NOISE:.2f} x")
    assert base.rms > 3 * NOISE                       # the damping is plain in the record
    # from the collapsed c0 the candidate gains what it gains from the base's own damping, near the
    # noise (before the floor: 400 x noise, the damping's terms stuck at zero)
    assert base.rms - fits["collapsed"].rms >= 0.95 * (base.rms - fits["warm"].rms)
    assert fits["collapsed"].rms <= 1.25 * NOISE
