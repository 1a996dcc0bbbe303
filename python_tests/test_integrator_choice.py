"""integrator = auto (docs/models.md, "Integrator"): BDF on the payload rig where a dissipative law
relaxes far faster than the payload swings, Adams elsewhere. Checked on the FMU (auto gives the
bits of the method it should pick), against the other method (the choice changes the cost, not
the answer), and on the engine, which must pick as the FMU does (it runs the FMU's physics)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import fmu_harness as H

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))
from tether import identify_native as idn  # noqa: E402

AUTO, BDF, ADAMS = 1, 2, 3
# a 9.4 m tether and a 2.45 kg payload (the payload swings at about 16 rad/s), released 6 cm below balance
RIG = dict(rig=2, stiffness=1, damping=1, creep=False, slack=False, m=2.45, g=9.81, L0=9.4, EA=5918.0, c0=0.3,
           x0=-0.06, rtol=1e-8)


def bouc_wen(loop_m: float) -> dict:
    """A Bouc-Wen force (n = 1) whose loop closes within loop_m of displacement (1 / (beta + gamma))
    and whose bound A / (beta + gamma) is 0.37 N."""
    psi = 1.0 / loop_m
    return dict(hysteresis=3, bw_n=1.0, bw_beta=0.864 * psi, bw_gamma=0.136 * psi, bw_A=0.372 * psi)


def dry_friction(coulomb_v: float) -> dict:
    return dict(damping=3, c_coulomb=0.415, coulomb_v=coulomb_v)


CASES = {  # the law, the method auto must pick; the rate ratio to the swing in the comment
    "narrow Bouc-Wen loop": (bouc_wen(1e-5), BDF),      # 0.094 m/s / 1e-5 m = 9,400 /s: 590 x the swing
    "wide Bouc-Wen loop": (bouc_wen(1e-2), ADAMS),      # 9.4 /s: 0.6 x
    "sharp dry friction": (dry_friction(1e-4), BDF),     # 0.415 / 1e-4 / 2.45 = 1,700 /s: 106 x
    "smooth dry friction": (dry_friction(0.05), ADAMS),  # 3.4 /s
}


def fmu_run(values: dict, integrator: int) -> np.ndarray:
    inst = H.cs(dict(RIG, **values, integrator=integrator))
    try:
        return H.run_cs(inst, H.grid(5.0, 1e-2), ["displacement"])["displacement"]
    finally:
        inst.free()


@pytest.mark.parametrize("case", list(CASES))
def test_auto_takes_the_method_the_relaxation_calls_for_and_both_methods_agree(case):
    law, expected = CASES[case]
    auto, bdf, adams = (fmu_run(law, i) for i in (AUTO, BDF, ADAMS))
    picked = BDF if np.array_equal(auto, bdf) else ADAMS if np.array_equal(auto, adams) else None
    swing = float(np.ptp(adams))
    gap = float(np.max(np.abs(bdf - adams)))
    print(f"FIGURE integrator {case}: auto = {'bdf' if picked == BDF else 'adams' if picked else '?'}, "
          f"|bdf - adams| <= {gap:.2g} m over a swing of {swing:.3g} m")
    assert picked == expected
    assert swing > 0.05 and gap < 1e-5 * swing


@pytest.mark.parametrize("case", list(CASES))
def test_the_engine_picks_as_the_fmu_does(case):
    law, _ = CASES[case]
    t = H.grid(5.0, 1e-2)
    engine = idn.simulate(idn.Experiment(t, settings=dict(RIG, **law)))
    assert np.max(np.abs(engine - fmu_run(law, AUTO))) <= 1e-9
