"""The campaigns of the project's generator (campaign_records) are of ONE tether: every record's
elastic law is the same function of the strain, whichever experiment it comes from."""

from __future__ import annotations

import json

import numpy as np
import pytest

import campaign_records as cr
import hidden_effects as he
from tether.discover.fitting import predict
from tether.fit import fit_traces
from tether.traces import read_trace


@pytest.mark.parametrize("law", ["logcosh", "power"])
def test_a_campaign_s_tether_has_one_elastic_law_in_every_experiment(law):
    material = {**cr.tether_material(11), "stiffness_law": law}
    material["stiff_ref_strain"] = cr.reference_strain(material)   # as campaign_records.record sets it
    strains = np.linspace(-0.02, 0.04, 13)
    in_load_test = he._make_elastic(material, {"nonlinear_stiffness"}).force_vec(strains)
    for static_strain in (0.004, 0.013, 0.03):   # payload records of several masses and lengths
        in_payload = he._make_elastic(material, {"nonlinear_stiffness"}, static_strain).force_vec(strains)
        assert np.array_equal(in_payload, in_load_test), static_strain


def test_one_parameter_set_of_the_engine_reproduces_a_power_law_tether_s_records(tmp_path):
    # the engine's cubic with its power term is the generator's power law exactly (a1 -> 0): the
    # load test's law, with the free vibration's damping fitted, reproduces the free vibration.
    # (Before the reference strain was the tether's, the payload record's law was scaled with its
    # own static strain: this free vibration stayed at 38 x its noise.)
    recs, _, material = cr.campaign(11, effects={"nonlinear_stiffness"}, experiments=("free_vibration", "load_unload"),
                                    sizes=cr.TINY, stiffness_law="power")
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    sigma = [json.loads(t.csv_path.with_suffix(".json").read_text())["hidden"]["noise_sigma_m"] for t in traces]
    ref = cr.reference_strain(material)
    law = {"a1": 1e-6, "a2": 0.0, "a3": 0.0, "pow_F": material["EA_N"] * ref, "pow_eps": ref,
           "pow_n": material["stiff_p"]}
    free_vibration, load_test = traces
    y = predict(load_test, "cubic", law)
    assert np.sqrt(np.mean((y - load_test.measured) ** 2)) < 1.2 * sigma[1]
    fitted = fit_traces([free_vibration], "cubic", free=["c0"], start={"c0": 1.0}, fixed=law)
    assert fitted.rms < 1.2 * sigma[0], (fitted.rms / sigma[0], fitted.parameters["c0"])
