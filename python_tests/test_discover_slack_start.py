"""The slack candidate of a forced record that goes slack (the development draw's b26, generator B,
seed 11: a linear tether with viscous damping, slack 14 times, its stated mass the truth). The
linear start model bends its law and its nuisance values to stand in for slack (x0 1.3 mm where
the record starts at rest), and the record's own data-based nuisance reading put the mass at the
band's edge (the equation error's acceleration column took up what the linear law lacks). Slack
from the base fit's values stopped at 1.59 x noise and a bilinear toe was named in its place at
1.28 x; the true model reproduces the record at 1.03 x. Now the record's own reading is what it
states where the linear equation does not describe it (discover.nuisance.nuisance_start), and
slack's starts include the data-based estimate of the whole model (starts.slack_starts)."""
from __future__ import annotations

from tether.discover.nuisance import nuisance_parameters
from tether.discover.search import Search
from tether.discover.starts import candidate_starts
from tether.models import parse_model


def test_slack_beside_a_bent_linear_fit_reaches_the_tether(slack_forced_b26):
    spec, tr = slack_forced_b26
    s = Search(tr, "linear", None, 4, 2, None, nuisance_parameters(tr))
    assert s.cur.rms > 20 * s.sigma and abs(s.cur.params["x0"]) > 1e-3
    slack = parse_model("linear+slack", "forced")
    starts = candidate_starts(s.cur, slack, s.sc, s.trace)
    assert None in starts
    warm = s.fit(s.trace, slack, ("slack",), starts[:2], s.sc, baseline_rms=s.cur.rms)
    fm = s.fit(s.trace, slack, ("slack",), starts, s.sc, baseline_rms=s.cur.rms)
    assert warm.rms > 1.3 * s.sigma                       # from the bent fit's values
    assert fm.rms < 1.1 * s.sigma                         # the tether's own
    assert abs(fm.params["EA"] / spec["params"]["elastic"]["EA"] - 1) < 0.01
    assert abs(fm.params["m"] / tr.payload_mass_kg - 1) < 0.01
