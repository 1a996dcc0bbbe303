"""Creep in every rig, and milliseconds (vibration) with months (creep) in one simulation.

Independent expectations: the tether is a mechanical element in series with a creep element, so
- payload rig: when the vibration has died out the tension equals the weight m g and the payload
  has sunk by exactly the creep elongation L0 * eps_c (the mechanical strain is back at balance);
- element rig: the tension is the cubic law of the mechanical strain eps - eps_c at every instant,
  and with the elongation held it relaxes monotonically (stress relaxation);
- the first seconds of vibration are the creep-free vibration (creep is slow).
"""
import time

import numpy as np

import fmu_harness as H

CUBIC = dict(a1=1200.0, a2=2.0e5, a3=-2.0e6)


def cubic(eps):
    return eps * (CUBIC["a1"] + eps * (CUBIC["a2"] + eps * CUBIC["a3"]))


def payload_run(creep, steps):
    inst = H.cs(dict(rig=2, stiffness=2, damping=2, slack=True, creep=creep, m=10.0, x0=0.05, L0=16.0, **CUBIC))
    t, rows = 0.0, []
    for h in steps:
        assert inst.do_step(t, h) == 0
        t += h
        rows.append((t, *inst.get("displacement", "creep_total", "tension")))
    inst.free()
    return np.array(rows)


def test_payload_rig_vibration_and_a_month_of_creep():
    steps = [1e-3] * 2000 + [1.0] * 3598 + [3600.0] * (24 * 30 - 1)   # 2 s at 1 ms, then to 30 days
    t0 = time.perf_counter()
    with_creep = payload_run(True, steps)
    wall = time.perf_counter() - t0
    without = payload_run(False, steps[:2000])
    vib_diff = np.max(np.abs(with_creep[:2000, 1] - without[:, 1]))
    t_end, x_end, eps_c_end, T_end = with_creep[-1]
    print(f"FIGURE creep payload: 30 days (2000 steps of 1 ms, then 1 s and 1 h steps) in {wall:.2f} s wall; "
          f"first 2 s differ from the creep-free vibration by {vib_diff:.2e} m; after 30 days creep strain "
          f"{eps_c_end:.4e}, x = {x_end:.6f} m vs L0 eps_c = {16.0 * eps_c_end:.6f} m, tension {T_end:.9f} N")
    assert vib_diff < 1e-4                                  # the vibration is resolved, creep barely acts
    assert abs(T_end - 10.0 * 9.81) < 1e-6                  # at rest: the tension carries the weight
    assert abs(x_end - 16.0 * eps_c_end) < 1e-6             # the payload sank by the creep elongation
    hours = with_creep[:, 0] >= 3600.0
    assert np.all(np.diff(with_creep[hours, 2]) > 0)        # creep grows under a constant load
    assert 5e-4 < eps_c_end < 5e-3


def test_element_rig_stress_relaxation_follows_the_series_law():
    inst = H.cs(dict(rig=1, stiffness=2, damping=1, slack=True, creep=True, L0=16.0, elongation=0.35,
                     elongation_rate=0.0, **CUBIC))
    t, rows = 0.0, []
    for h in [60.0] * (24 * 60 * 3):
        assert inst.do_step(t, h) == 0
        t += h
        rows.append((t, *inst.get("tension", "creep_total", "strain")))
    inst.free()
    r = np.array(rows)
    T, eps_c, eps = r[:, 1], r[:, 2], r[:, 3]
    law = cubic(eps - eps_c)
    rel = np.max(np.abs(T - law) / law)
    print(f"FIGURE creep element: held at 0.35 m for 3 days, tension {T[0]:.3f} -> {T[-1]:.3f} N; "
          f"max |T - F(eps - eps_c)| / F = {rel:.2e}")
    assert np.all(np.abs(eps - 0.35 / 16.0) < 1e-15)
    assert rel < 1e-12
    assert np.all(np.diff(T) < 0) and T[-1] < 0.97 * T[0]  # relaxes, monotonically
