#!/usr/bin/env python3
"""Write the bundled discovery trace (reference_results/discovery/freevib_hidden.{csv,json}).

    python reference_results/discovery/make.py          (from the repository root)

The trace comes from the independent generator of the tests (python_tests/hidden_effects.py: its
own laws and integrator, not the FMU), so the demo's discovery run faces model-form mismatch the
way a real record would. The JSON's extra key ``hidden`` holds the truth; discovery never reads
it, the demo report shows it beside what was named. Deterministic: same arguments, same bytes.
"""
from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1] / "python_tests"))
import hidden_effects as he  # noqa: E402

STEM = "freevib_hidden"
SPEC = dict(experiment="free_vibration", effects={"nonlinear_stiffness", "slack"}, seed=7, noise=1e-4,
            rate=200.0, duration_s=10.0, stiffness_law="power")


def main() -> int:
    kw = dict(SPEC)
    desc = ("SYNTHETIC free vibration, 10 s at 200 Hz, from python_tests/hidden_effects.py (independent laws "
            "and integrator); two effects are hidden (see the key 'hidden', which discovery does not read)")
    tr = he.generate(kw.pop("experiment"), kw.pop("effects"), kw.pop("seed"), description=desc, **kw)
    tr.write(HERE, STEM)
    print(f"{HERE / STEM}.csv: {len(tr.time)} samples, hidden effects {sorted(tr.revealed)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
