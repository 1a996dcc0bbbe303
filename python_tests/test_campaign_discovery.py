"""Discovery over a test campaign (issue 29; tether.discover.campaign): several records of one
tether from the project's generator (campaign_records over hidden_effects), one model for all."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import campaign_records as cr
from tether.discover.campaign import CampaignInputError, check_campaign, discover_campaign
from tether.discover.campaign_document import campaign_document
from tether.discover.fitting import predict
from tether.discover.nuisance import baked
from tether.models import parse_model
from tether.traces import read_trace

# a tether with creep; its free vibration released high enough to go slack: slack shows only in
# the free vibration, creep only in the creep test (the generator's seed 11 tether), on the tests'
# small records (campaign_records.TINY: 301 and 631 samples)
SPLIT_SEED = 11
SPLIT_EFFECTS = {"creep", "slack"}
SPLIT_EXPERIMENTS = ("free_vibration", "creep")


@pytest.fixture(scope="module")
def split_campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("split")
    recs, effects, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, experiments=SPLIT_EXPERIMENTS, sizes=cr.TINY)
    stems = cr.write_campaign(recs, folder)
    traces = [read_trace(s) for s in stems]
    lines = []
    # two steps for the two effects (a third, measured 2026-11-27, added nothing and cost as much as
    # both); no wall-time bound: a loaded machine
    d = discover_campaign(traces, progress=lines.append, budget=None, max_steps=2)
    return recs, traces, d, campaign_document(d), lines


def test_campaign_records_are_small_and_split():
    """The generator's campaign: three experiments of one tether, hundreds to ~2,000 samples
    each (tens to hundreds on the tests' sizes), its effects split between them (slack only in
    the free vibration, creep only in the load tests)."""
    recs, effects, material = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS)
    assert [r.experiment for r in recs] == ["free_vibration", "load_unload", "creep"]
    assert all(100 <= len(r.time) <= 2500 for r in recs), [len(r.time) for r in recs]
    assert {r.meta["hidden"]["params"]["EA_N"] for r in recs} == {material["EA_N"]}
    assert recs[0].revealed == {"slack"}
    assert "creep" in recs[2].revealed and "slack" not in recs[1].revealed | recs[2].revealed
    assert cr.hidden_union(recs) == SPLIT_EFFECTS
    tiny, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, sizes=cr.TINY)
    assert all(50 <= len(t.time) < len(r.time) for t, r in zip(tiny, recs)), [len(t.time) for t in tiny]
    assert [t.revealed for t in tiny] == [r.revealed for r in recs]


def test_campaign_names_the_union_and_who_revealed_it(split_campaign):
    recs, traces, d, doc, lines = split_campaign
    assert set(doc["added_effects"]) == cr.hidden_union(recs) == SPLIT_EFFECTS
    by_name = {r["name"]: r for r in doc["records"]}
    fv, creep = (t.name for t in traces)
    # the record that can show an effect revealed it; the one that cannot calls it undetermined
    assert by_name[fv]["revealed"] == ["slack"]
    assert by_name[creep]["revealed"] == ["creep"]
    assert by_name[creep]["effects"]["slack"]["verdict"] == "undetermined"
    assert by_name[fv]["effects"]["creep"]["verdict"] == "undetermined"
    assert doc["effects"]["slack"]["verdict"] == doc["effects"]["creep"]["verdict"] == "present"
    assert doc["contradicting"] == []
    # per step each record's error before and after: the revealing record's gap shrinks
    for s in doc["steps"]:
        if s["effect"]:
            for x in s["records"]:
                if x["revealed"]:
                    assert x["rmse_after"] < x["rmse_before"]
    assert any("noise" in ln for ln in lines)


@pytest.mark.parametrize("experiment", SPLIT_EXPERIMENTS)
def test_every_record_within_one_and_a_half_noise(split_campaign, experiment):
    """Issue 29's acceptance on each record. The free vibration (noise 1.1e-5 m, 1/15,000 of its
    amplitude) stayed at 2.54 x its noise until each step fitted the current model as its candidates
    are (Campaign.refit_current: in step 2 it takes that record from 31.7 to 1.4 x before creep is
    judged; measured 2026-11-27, docs/campaign-discovery.md)."""
    _, _, _, doc, _ = split_campaign
    r = next(r for r in doc["records"] if r["experiment"] == experiment)
    assert r["rmse_final"] <= 1.5 * r["noise_estimate"], (r["name"], r["rmse_final_over_noise"])


def test_campaign_document_is_a_params_file(split_campaign, tmp_path):
    """final_params (and the top level) make OUT.json a --params file of the discovered model."""
    from tether.models import read_params

    _, _, d, doc, _ = split_campaign
    p = tmp_path / "out.json"
    p.write_text(json.dumps(doc))
    pf = read_params(p)
    assert parse_model(pf.model).canonical == d.final.model
    assert pf.parameters == pytest.approx(d.final.params)


def test_campaign_report_tells_each_step_and_who_revealed_it(split_campaign, tmp_path):
    """DIR/index.html: one figure per step with a panel per record, the table of who revealed what."""
    from tether.campaign_report import write_campaign_report

    _, traces, d, doc, _ = split_campaign
    write_campaign_report(tmp_path, d, doc)
    page = (tmp_path / "index.html").read_text()
    added = [s for s in d.steps if s.effect]
    assert all((tmp_path / f"step{k}.png").is_file() for k in range(len(added) + 1))
    assert "Which record revealed what" in page
    for s in added:
        assert f"<b>{s.effect}</b>" in page
    assert page.count("<b>revealed</b>") == sum(len(s.revealed_by) for s in added)
    assert json.loads((tmp_path / "discovery.json").read_text())["added_effects"] == doc["added_effects"]


def test_a_record_of_another_tether_is_flagged_by_name(tmp_path):
    """Two records of one tether and a load test of another (60 % stiffer): the odd record is named.
    The start model alone (max_steps=0: the flagging judges the final model, whichever it is); the
    free vibration, bent by the compromise, misfits too, and the leave-one-out clears it."""
    recs, _, material = cr.campaign(5, effects=set(), experiments=("free_vibration", "load_unload"), sizes=cr.TINY)
    odd = cr.record("load_unload", set(), {**material, "EA_N": 1.6 * material["EA_N"]}, 74, cr.TINY)
    stems = cr.write_campaign(recs + [odd], tmp_path)
    traces = [read_trace(s) for s in stems]
    lines = []
    d = discover_campaign(traces, progress=lines.append, budget=None, max_steps=0)
    assert [c["name"] for c in d.contradicting] == [traces[2].name], d.contradicting
    c = d.contradicting[0]
    assert c["rmse_final_over_noise"] > 20 and c["rmse_alone_over_noise"] < c["rmse_final_over_noise"]
    ea = [p for p in c["parameters_differ"] if p["name"] == "EA"]
    assert ea and ea[0]["alone"] / ea[0]["campaign"] > 1.2, c["parameters_differ"]   # the stiffer tether
    assert any(traces[2].name in ln and "CONTRADICTING" in ln for ln in lines)


def test_a_record_the_model_cannot_explain_alone_is_not_flagged(tmp_path):
    """The split campaign's tether (slack in the free vibration, creep in the creep test) under the
    start model alone (max_steps=0): the linear law misses both records grossly, and the creep
    test's own linear fit earns its parameters against the shared one (the old rule flagged it);
    but neither record is reproduced by the linear model even alone, so the misfit cannot be told
    from what the model still lacks: no record is flagged, and each says why."""
    recs, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, experiments=SPLIT_EXPERIMENTS, sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    lines = []
    d = discover_campaign(traces, progress=lines.append, budget=None, max_steps=0)
    gross = [r.name for r, e in zip(d.records, d.final.rms_records) if e > 20 * r.sigma]
    assert gross == [t.name for t in traces], [e / r.sigma for r, e in zip(d.records, d.final.rms_records)]
    assert d.contradicting == [], d.contradicting
    fv, creep = (d.alone[t.name] for t in traces)
    assert fv["rmse_over_noise"] > 1.5 and fv["contradiction"].startswith("no: its own law does not earn"), fv
    assert creep["rmse_over_noise"] > 1.5 and creep["contradiction"].startswith("not judged"), creep
    assert not any("CONTRADICTING" in ln for ln in lines)


def test_baked_record_predicts_as_its_nuisance_values(tmp_path):
    """A record with its nuisance values baked in predicts, with the law alone, what the record
    predicts with the law and the nuisance values (the engine's own account of them)."""
    rec = cr.record("free_vibration", set(), cr.tether_material(3), 3)
    rec.write(tmp_path, "fv")
    tr = read_trace(tmp_path / "fv")
    spec = parse_model("linear").for_experiment(tr.experiment)
    law = {"EA": rec.meta["hidden"]["params"]["EA_N"], "c0": 2.0}
    nz = {"offset_measured": 3e-3, "x0": float(tr.initial_displacement_m) * 0.8}
    y_engine = predict(tr, spec, {**law, **nz})
    y_baked = predict(baked(tr, nz), spec, law) + nz["offset_measured"]
    assert np.max(np.abs(y_engine - y_baked)) <= 1e-9 * np.max(np.abs(y_engine))
    assert np.max(np.abs(y_engine - predict(tr, spec, law))) > 1e-3     # the values do act


def test_a_record_given_twice_is_refused(tmp_path):
    rec = cr.record("load_unload", set(), cr.tether_material(3), 3)
    rec.write(tmp_path, "lu")
    tr = read_trace(tmp_path / "lu")
    with pytest.raises(CampaignInputError, match="lu.csv: the record is given twice"):
        check_campaign([tr, read_trace(tmp_path / "lu.json")])


def _linear_pair(folder: Path) -> list[Path]:
    recs, _, _ = cr.campaign(4, effects=set(), experiments=("load_unload", "creep"))
    return cr.write_campaign(recs, folder)


def test_cli_campaign_writes_records(run_cli, tmp_path):
    stems = _linear_pair(tmp_path)
    out = tmp_path / "OUT.json"
    status, stdout, stderr = run_cli("discover", *stems, "--json", out, "--report", tmp_path / "rep")
    assert status == 0, stderr
    doc = json.loads(out.read_text())
    assert [r["name"] for r in doc["records"]] == [s.name for s in stems]
    for r in doc["records"]:
        for k in ("trace", "experiment", "noise_estimate", "rmse_initial", "rmse_final", "steps", "effects"):
            assert k in r
        assert r["rmse_final"] <= 1.5 * r["noise_estimate"]
    assert doc["added_effects"] == [] and doc["contradicting"] == []
    assert (tmp_path / "rep" / "index.html").is_file()
    assert "campaign of 2 records" in stdout


@pytest.mark.parametrize("bad", ["missing", "twice"])
def test_cli_campaign_bad_input_exits_2_naming_the_file(run_cli, tmp_path, bad):
    stems = _linear_pair(tmp_path)
    out = tmp_path / "OUT.json"
    if bad == "missing":
        args, name = [stems[0], tmp_path / "nope"], "nope"
    else:
        args, name = [stems[0], stems[1], stems[0]], stems[0].name
    status, stdout, stderr = run_cli("discover", *args, "--json", out)
    assert status == 2, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and name in lines[0], stderr
    assert not out.exists()


def test_an_effect_a_later_one_makes_redundant_is_removed(tmp_path):
    """The re-test of a named effect once a later one is in (the one-record search's, on the
    campaign with the one judge): a campaign of a linear tether whose model carries creep, as if an
    earlier step had named it, and a cubic law just added; creep earns nothing and is removed,
    on record as a removal, and the document's added effects leave it out."""
    from tether.discover.campaign import Campaign, CampaignStep

    recs, _, _ = cr.campaign(4, effects=set(), experiments=("load_unload", "creep"), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    camp = Campaign(traces, "linear", None, 5, 2, None, None, False)
    camp.fit_start()
    start = camp.cur
    spec = parse_model("cubic+creep")
    ea = start.params["EA"]
    weak_creep = {"creep_J1": 1e-9, "creep_J2": 1e-9, "creep_J3": 1e-9, "slip_capacity0": 1e-9}
    camp.cur = camp.fit(spec, ("nonlinear_stiffness", "creep"), [{**start.params, "a1": ea, "a2": 0.0, "a3": 0.0,
                                                                 **weak_creep}])
    assert camp.cur.ok, camp.cur.message
    camp.fits.append(camp.cur)
    step = CampaignStep(effect="nonlinear_stiffness", model_before="linear+creep", model_after=camp.cur.model,
                        rms_before=start.rms, rms_after=camp.cur.rms, records_before=start.rms_records,
                        records_after=camp.cur.rms_records)
    camp.steps = [CampaignStep(effect="creep", model_before="linear", model_after="linear+creep",
                               rms_before=start.rms, rms_after=camp.cur.rms, records_before=start.rms_records,
                               records_after=camp.cur.rms_records), step]
    camp.retest_named(step)
    assert [t.effect for t in step.retests] == ["creep"] and not step.retests[0].kept, step.retests
    assert [x.effect for x in camp.removals] == ["creep"]
    assert not camp.cur.spec.creep and camp.cur.rms <= 1.1 * start.rms


def test_a_record_beyond_its_share_is_searched_thinned_and_reported_whole(tmp_path):
    """A campaign of two records, a free vibration of more than SEARCH_SAMPLES / 2 samples and a
    small creep test: the free vibration is searched on every 2nd sample (samples.search_thinning
    with its share; the creep test, whose load steps a thinned record would smear, keeps every
    sample), and the document reports the whole records: their samples, and errors that are those
    of the final model on every sample."""
    from tether.discover.samples import SEARCH_SAMPLES

    sizes = {**cr.TINY, "free_vibration": {"rate": 250.0, "duration_s": 10.0}}
    recs, _, _ = cr.campaign(4, effects=set(), experiments=("free_vibration", "creep"), sizes=sizes)
    assert len(recs[0].time) > SEARCH_SAMPLES // 2 > len(recs[1].time)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    lines = []
    d = discover_campaign(traces, progress=lines.append, budget=None)
    thinned = [ln for ln in lines if "searched on every" in ln]
    assert len(thinned) == 1 and traces[0].name in thinned[0] and "every 2nd sample" in thinned[0], lines
    doc = campaign_document(d)
    for tr, r, y in zip(traces, doc["records"], d.final.predicted):
        assert r["samples"] == len(tr.time) == len(y)
        assert r["rmse_final"] == pytest.approx(float(np.sqrt(np.mean((y - tr.measured) ** 2))), rel=1e-9)
        assert r["rmse_final_over_noise"] <= 1.5
    assert doc["added_effects"] == []


def test_the_held_out_test_goes_on_while_no_candidate_passes_it():
    """Three candidates pass on the whole campaign; the best two by the BIC fail the held-out test:
    the third is tested and wins (the one-record search's rule, Search.heldout_tests). Where the
    first passes, the second is tested too and the third is not."""
    from tether.discover.campaign import Campaign, CampaignCandidate, CampaignFit
    from tether.discover.judge import heldout_verdict

    def cand(effect, rms, held):
        f = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=rms, rms_records=[rms],
                        predicted=[])
        f.held = held
        return CampaignCandidate(effect=effect, fit=f, added_parameters=1, bic_change=-1.0, accepted=True)

    camp = Campaign.__new__(Campaign)
    camp.say, camp.heldout_candidates = (lambda s: None), 2
    camp.cur = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=10.0, rms_records=[10.0],
                           predicted=[])
    camp.cur_held = 10.0
    camp.records = []
    camp.heldout_of = lambda f, among=None: f.held
    assert not heldout_verdict(1.0, 10.0, 50.0, 10.0, 5.0)[0] and heldout_verdict(1.0, 10.0, 2.0, 10.0, 5.0)[0]
    passing = [cand("nonlinear_stiffness", 5.0, 50.0), cand("nonlinear_damping", 5.0, 40.0), cand("creep", 5.0, 2.0)]
    win = camp.heldout_tests(passing)
    assert win is passing[2] and [c.accepted for c in passing] == [False, False, True]
    passing = [cand("creep", 5.0, 2.0), cand("nonlinear_damping", 5.0, 40.0), cand("nonlinear_stiffness", 5.0, 3.0)]
    win = camp.heldout_tests(passing)
    assert win is passing[0] and math.isnan(passing[2].heldout_rms) and "not tested" in passing[2].verdict


def test_an_effects_held_out_test_reads_only_the_records_that_can_reveal_it(tmp_path):
    """Creep, which a free vibration cannot reveal, is judged on the held-out part of the creep
    test alone: the free vibration's part moves with the shared law, not with creep (campaign 1000
    of bench/campaign_eval.py: creep took its creep test from 14.11 to 1.05 x noise and was refused
    because the pooled parts went from 8.54 to 10.70 sigma). An effect every record can reveal is
    judged on every part, as before (test_the_held_out_test_goes_on_while_no_candidate_passes_it)."""
    from tether.discover.campaign import Campaign, CampaignCandidate, CampaignFit
    from tether.discover.judge import heldout_verdict

    recs, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, experiments=SPLIT_EXPERIMENTS, sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    # each record's held-out error in noise units, before and with the candidate: the creep test's
    # part improves five-fold, the free vibration's gets worse
    held = {"current": (8.0, 10.0), "creep": (12.0, 2.0)}

    def heldout_of(f, among=None):
        parts = held[f.tag]
        among = range(len(parts)) if among is None else among
        return math.sqrt(sum(parts[i] ** 2 for i in among) / len(among))

    def fit(label, rms):
        f = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=rms,
                        rms_records=[rms, rms], predicted=[])
        f.tag = label
        return f

    camp = Campaign.__new__(Campaign)
    camp.say, camp.heldout_candidates = (lambda s: None), 2
    camp.records = [type("R", (), {"trace": t, "name": t.name, "sigma": 1.0})() for t in traces]
    camp.cur = fit("current", 10.0)
    camp.heldout_of = heldout_of
    camp.cur_held = heldout_of(camp.cur)
    camp.reveals = lambda *a: True       # the creep test shows creep (the free vibration cannot)
    creep = CampaignCandidate(effect="creep", fit=fit("creep", 5.0), added_parameters=3, bic_change=-50.0,
                              accepted=True)
    # pooled over both parts the gap shrinks only from 9.00 to 8.54 sigma: the old rule refused it
    assert not heldout_verdict(1.0, camp.cur_held, heldout_of(creep.fit))[0]
    assert camp.heldout_tests([creep]) is creep and creep.accepted
    assert creep.heldout_rms == pytest.approx(2.0) and "show it" in creep.verdict
    # added, the current held-out error is again every record's, not the creep test's alone
    from tether.discover.campaign_records import CampaignStep

    camp.settle, camp.fits = (lambda f: f), []
    camp.add(CampaignStep(effect=None, model_before="linear", model_after=None, rms_before=10.0, rms_after=None,
                          records_before=[10.0, 10.0], records_after=None), creep)
    assert camp.cur is creep.fit and camp.cur_held == pytest.approx(heldout_of(creep.fit)) != creep.heldout_rms
    camp.cur = fit("current", 10.0)
    camp.cur_held = heldout_of(camp.cur)
    held["creep"] = (12.0, 9.0)          # the creep test's own part barely improves: refused
    creep = CampaignCandidate(effect="creep", fit=fit("creep", 5.0), added_parameters=3, bic_change=-50.0,
                              accepted=True)
    assert camp.heldout_tests([creep]) is None and not creep.accepted


def test_an_effects_held_out_test_reads_the_records_that_show_it(tmp_path):
    """Of the records that can reveal creep (the load test, the creep test), the held-out test reads
    those where the candidate meets the one-record rule on their own samples (Steps.revealing): the
    other record's part moves with the shared law. The figures are tuning campaign 1008's step 3
    (docs/campaign-discovery.md, session 39): creep took its creep test from 4.76 to 1.03 x noise
    and the load test from 4.27 to 3.50 (its gap not halved); held out, the creep test went from
    5.45 to 2.07 x and the load test from 4.69 to 5.82. Where no record shows it alone, the parts
    of every record that can reveal it are read, as before."""
    from tether.discover.campaign import Campaign, CampaignCandidate, CampaignFit
    from tether.discover.judge import heldout_verdict

    recs, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, sizes=cr.TINY,
                             experiments=("free_vibration", "load_unload", "creep"))
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    held = {"current": (1.38, 4.69, 5.45), "creep": (3.68, 5.82, 2.07)}
    whole = {"current": [1.08, 4.27, 4.76], "creep": [1.07, 3.50, 1.03]}

    def heldout_of(f, among=None):
        among = range(3) if among is None else among
        return math.sqrt(sum(held[f.tag][i] ** 2 for i in among) / len(among))

    def fit(label):
        f = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=2.0,
                        rms_records=list(whole[label]), predicted=[])
        f.tag = label
        return f

    camp = Campaign.__new__(Campaign)
    camp.say, camp.heldout_candidates = (lambda s: None), 2
    camp.records = [type("R", (), {"trace": t, "name": t.name, "sigma": 1.0, "n": 1000})() for t in traces]
    camp.cur = fit("current")
    camp.heldout_of = heldout_of
    camp.cur_held = heldout_of(camp.cur)
    creep = CampaignCandidate(effect="creep", fit=fit("creep"), added_parameters=3, bic_change=-500.0, accepted=True)
    assert camp.revealing(creep) == [2]
    # on the parts of both records that can reveal it, the gap shrinks only from 5.02 to 4.24 sigma
    assert not heldout_verdict(1.0, heldout_of(camp.cur, (1, 2)), heldout_of(creep.fit, (1, 2)))[0]
    assert camp.heldout_tests([creep]) is creep and creep.accepted
    assert creep.heldout_rms == pytest.approx(2.07)
    # where no record shows it alone, both records that can reveal it judge it: refused
    whole["creep"] = [1.07, 3.50, 3.90]
    creep = CampaignCandidate(effect="creep", fit=fit("creep"), added_parameters=3, bic_change=-500.0, accepted=True)
    assert camp.revealing(creep) == []
    assert camp.heldout_tests([creep]) is None and not creep.accepted


def test_an_effects_gap_is_read_on_the_records_that_can_reveal_it(tmp_path):
    """Creep, which a free vibration cannot reveal, earns its place where it closes the creep test's
    gap, however far the free vibration is missed (campaign 1000 --large, 2026-11-27: creep took
    its creep test from 15.62 to 1.18 x noise, the free vibration stayed at 20.6 x, and the pooled
    gap shrank only from 15.03 to 11.38 sigma: refused). The expectation is the one-record rule on
    the creep test alone. So is an effect every record can reveal, where one record reveals it alone
    (tuning campaign 1005: the free vibration and the creep test, each missed for the effect the
    other reveals); where none does, on the whole campaign. The re-test of a named effect reads the
    same records."""
    from tether.discover.campaign import Campaign, CampaignFit
    from tether.discover.judge import _bic, full_data_verdict

    recs, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, experiments=SPLIT_EXPERIMENTS, sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    assert [t.experiment for t in traces] == ["free_vibration", "creep"]
    camp = Campaign.__new__(Campaign)
    # the records' sizes of campaign 1000 --large (its free vibration and creep test)
    camp.records = [type("R", (), {"trace": t, "name": t.name, "sigma": 1.0, "n": n})()
                    for t, n in zip(traces, (4001, 3961))]
    camp.n = sum(r.n for r in camp.records)

    def fit(errors, free):
        z = math.sqrt(sum(r.n * e ** 2 for r, e in zip(camp.records, errors)) / camp.n)
        return CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=list(free), rms=z,
                           rms_records=list(errors), predicted=[])

    camp.cur = fit([20.6, 15.62], ["k"])
    creep = camp.judge("creep", fit([20.6, 1.18], ["k", "a", "b", "c"]))
    n_creep = camp.records[1].n
    alone = full_data_verdict(1.0, 15.62, 1.18, _bic(1.18, 3, n_creep) - _bic(15.62, 0, n_creep), 3)
    assert alone[0] and creep.accepted and "reveal" in creep.verdict
    # the pooled rule refused it
    assert not full_data_verdict(1.0, camp.cur.rms, creep.fit.rms, creep.bic_change, 3)[0]
    # the creep test's own gap barely shrinks: refused, as on that record alone
    weak = camp.judge("creep", fit([20.6, 12.0], ["k", "a", "b", "c"]))
    assert not weak.accepted and not full_data_verdict(1.0, 15.62, 12.0, -1.0, 3)[0]
    # a cubic law, which both records can reveal, gaining the same on the creep test alone: read on
    # the record that reveals it, as creep is (the free vibration may be missed for another effect)
    cubic = camp.judge("nonlinear_stiffness", fit([20.6, 1.18], ["k", "a", "b", "c"]))
    assert cubic.accepted and "the records that reveal it" in cubic.verdict
    assert not full_data_verdict(1.0, camp.cur.rms, cubic.fit.rms, cubic.bic_change, 3)[0]
    # gaining a little on both, neither record revealing it alone: pooled, refused
    assert not any(camp.reveals(i, b, a, 3) for i, (b, a) in enumerate(zip([20.6, 15.62], [19.0, 12.0])))
    spread = camp.judge("nonlinear_stiffness", fit([19.0, 12.0], ["k", "a", "b", "c"]))
    assert not spread.accepted and "reveal" not in spread.verdict and spread.bic_change < 0
    # removing creep again is judged on the creep test too: kept
    keep, why = camp.effect_verdict("creep", camp.cur, creep.fit, creep.bic_change, 3)
    assert keep and "reveal" in why


def test_slack_that_goes_slack_only_where_the_fits_see_is_not_asked_the_held_out_test(tmp_path):
    """The one-record rule (judge.slack_heldout_unasked) in the campaign's step: slack adds no
    parameter, and where no record that can reveal it goes slack in its held-out part, that part
    cannot judge it (campaign 1005 of bench/campaign_eval.py: slack took the campaign from 63.9 to
    42.5 x noise and was refused on the free vibration's held-out part, 36.9 -> 51.7 sigma, and the
    search named nothing). Where a record goes slack in its held-out part, the test is asked."""
    from tether.discover.campaign import Campaign, CampaignCandidate, CampaignFit

    recs, _, _ = cr.campaign(SPLIT_SEED, effects=SPLIT_EFFECTS, experiments=SPLIT_EXPERIMENTS, sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]

    def fit(rms):
        return CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=rms,
                           rms_records=[rms, rms], predicted=[])

    camp = Campaign.__new__(Campaign)
    camp.say, camp.heldout_candidates = (lambda s: None), 2
    camp.records = [type("R", (), {"trace": t, "name": t.name, "sigma": 1.0, "n": 1000})() for t in traces]
    camp.cur, camp.cur_held = fit(63.9), 36.9
    camp.heldout_of = lambda f, among=None: 36.9 if f is camp.cur else 51.7
    for slack_after_first, accepted in ((False, True), (True, False)):
        asked = []
        camp.slack_in_held_parts = lambda f, among: asked.append(among) or slack_after_first
        slack = CampaignCandidate(effect="slack", fit=fit(42.5), added_parameters=0, bic_change=-2269.0,
                                  accepted=True)
        assert (camp.heldout_tests([slack]) is slack) is accepted and slack.accepted is accepted
        assert asked == [(0,)]       # the free vibration: the creep test cannot reveal slack
        assert ("held-out test not asked" in slack.verdict) is accepted


def _hysteresis_campaign(folder: Path):
    """A tether with the generator's Iwan friction (twelve elements): a load-unload test and a creep
    test (the tests' sizes: 409 and 631 samples), its start model fitted."""
    from tether.discover.campaign import Campaign

    recs, _, _ = cr.campaign(3, effects={"hysteresis"}, experiments=("load_unload", "creep"), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, folder)]
    camp = Campaign(traces, "linear", None, 5, 2, None, None, False)
    camp.fit_start()
    return camp


def _boucwen_named_iwan_on_record(camp) -> dict:
    """``camp`` as after a hysteresis step that fitted both laws and named Bouc-Wen (the Iwan bank's
    fit on record for the rival law); the two fits by law."""
    start = camp.cur
    fits = {law: camp.fit(parse_model(f"linear+{law}"), ("hysteresis",), [start.params, None])
            for law in ("boucwen", "iwan")}
    camp.rivals = {"hysteresis": {law: f.params for law, f in fits.items()}}
    _hysteresis_named(camp, fits["boucwen"])
    return fits


def _hysteresis_named(camp, fit) -> None:
    """``camp`` as after a step that named the hysteresis with ``fit`` (settled) from its start model."""
    from tether.discover.campaign import CampaignStep

    start = camp.cur
    camp.cur = camp.settle(fit)
    camp.cur_held = camp.heldout_of(camp.cur)
    camp.fits.append(camp.cur)
    camp.steps = [CampaignStep(effect="hysteresis", model_before=start.model, model_after=camp.cur.model,
                               rms_before=start.rms, rms_after=camp.cur.rms, records_before=start.rms_records,
                               records_after=camp.cur.rms_records)]


def test_the_rival_hysteresis_law_is_fitted_in_its_place_at_the_end(tmp_path):
    """The one-record search's rival law on the campaign: the hysteresis step chose Bouc-Wen (here
    set so: the step's fits of both laws on record, Bouc-Wen in the model), which leaves the load
    test of the generator's Iwan friction at 2.6 x its noise; at the end the Iwan bank is fitted in
    its place from its own fit of the step, kept by the rival-law rule (a lower BIC and error, the
    held-out parts no worse), and brings every record within 1.5 x its noise."""
    camp = _hysteresis_campaign(tmp_path)
    fits = _boucwen_named_iwan_on_record(camp)
    before = [e / r.sigma for e, r in zip(camp.cur.rms_records, camp.records)]
    assert max(before) > 2.0, before
    camp.rival_law()
    assert [(x.law, x.accepted) for x in camp.refinements] == [("boucwen -> iwan", True)], camp.refinements
    assert camp.cur.spec.hysteresis == "iwan" and camp.cur.rms < fits["boucwen"].rms
    assert all(e <= 1.5 * r.sigma for e, r in zip(camp.cur.rms_records, camp.records)), camp.cur.rms_records


def _iwan_friction_campaign(folder: Path):
    """A free vibration and a load-unload test of the generator's twelve-element Iwan friction (the
    tests' sizes: 301 and 351 samples), its start model fitted."""
    from tether.discover.campaign import Campaign

    seed, experiments = 3, ("free_vibration", "load_unload")
    material = cr.tether_material(seed)
    recs = [cr.record(x, {"hysteresis"}, material, 1000 * seed + i, cr.TINY) for i, x in enumerate(experiments)]
    assert recs[0].meta["hidden"]["params"]["hyst_n"] == 12
    camp = Campaign([read_trace(s) for s in cr.write_campaign(recs, folder)], "linear", None, 5, 2, None, None, False)
    camp.fit_start()
    return camp


def test_the_steps_resume_where_a_last_stage_kept_a_law(tmp_path, monkeypatch):
    """Where a last stage keeps a law and a record is still missed, the steps run once more beside
    it (Campaign.resume_steps); where none is kept they do not. Bouc-Wen named on a tether of Iwan
    friction alone (measured 67.3 and 19.4 x noise): at the end the Iwan rival, made finer, is kept
    and leaves the free vibration above its noise (measured 1.36 x); the step that follows finds
    nothing more to name, and names nothing. That step is offered the stiffness alone: each candidate
    beside the finer bank costs 90-195 s of CPU, and all four (measured 2026-11-29) were refused alike."""
    import tether.discover.campaign_step as campaign_step

    camp = _iwan_friction_campaign(tmp_path)
    monkeypatch.setattr(campaign_step, "EFFECTS", ("nonlinear_stiffness",))
    _boucwen_named_iwan_on_record(camp)
    camp.resume_steps([])
    assert len(camp.steps) == 1
    kept = camp.last_stages()
    assert kept == ["hysteresis"] and camp.cur.spec.hysteresis == "iwan", camp.refinements
    assert not camp.within_noise(camp.cur), camp.per_record(camp.cur)
    camp.resume_steps(kept)
    assert len(camp.steps) == 2 and camp.steps[-1].effect is None, camp.steps[-1]
    assert camp.named() == ["hysteresis"] and camp.cur.spec.hysteresis == "iwan"


def test_a_finer_iwan_bank_fitted_to_the_record_that_shows_it_worst_and_then_jointly(tmp_path):
    """The one-record search's finer bank on the campaign: a free vibration and a load-unload test of
    the generator's twelve-element Iwan friction, fitted jointly with the search's bank of eight on
    its fixed slip strains, leave the free vibration far above its noise (measured 15.2 x). The bank
    made finer (sixteen elements, every slip strain free), fitted to that record first and then to
    both, is kept by the shape rule and brings both near their noise (measured 1.72 and 0.90 x), as
    the generator's own friction would; its terms stay free in the fits that follow (settle), and a
    bank already of sixteen is left alone. A rival law's fit that fits better but predicts the
    held-out parts worse is judged again with its bank made finer (reseeded_rival)."""
    from tether.models import IWAN_EPS, IWAN_K

    camp = _iwan_friction_campaign(tmp_path)
    start = camp.cur
    _hysteresis_named(camp, camp.fit(parse_model("linear+iwan"), ("hysteresis",), [start.params, None]))
    eight = [e / r.sigma for e, r in zip(camp.cur.rms_records, camp.records)]
    assert sum(n in camp.cur.free for n in IWAN_K) == 8 and max(eight) > 5.0, eight
    # the same move on a rival law's fit, judged as the rival is against the law in place (here
    # Bouc-Wen, measured 67.3 and 19.4 x): the finer bank, not the bank of eight, is what is judged
    boucwen = camp.fit(parse_model("linear+boucwen"), ("hysteresis",), [start.params, None])
    rival, _, bic, ok, verdict = camp.reseeded_rival(boucwen, camp.cur, float("nan"), 0.0, "", "boucwen")
    assert ok and bic < 0 and "bank made finer" in verdict, verdict
    assert set(IWAN_K + IWAN_EPS) <= set(rival.free) and rival.rms < 0.5 * camp.cur.rms, (rival.rms, camp.cur.rms)
    assert not camp.refinements and camp.cur.spec.hysteresis == "iwan"     # judged, not taken
    camp.finer_bank()
    assert [(x.finer, x.accepted) for x in camp.refinements] == [(True, True)], camp.refinements
    sixteen = [e / r.sigma for e, r in zip(camp.cur.rms_records, camp.records)]
    assert max(sixteen) < 2.0 and all(a < b for a, b in zip(sixteen, eight)), (eight, sixteen)
    assert set(IWAN_K + IWAN_EPS) <= set(camp.cur.free)
    assert set(IWAN_K + IWAN_EPS) <= set(camp.settle(camp.cur).free)     # carried into a later fit
    camp.finer_bank()
    assert len(camp.refinements) == 1


def test_the_named_effects_are_tested_again_after_a_law_is_put_in(tmp_path):
    """Once a last stage put another law in (a rival or wider law, on record as a kept Refinement
    after the last step's re-tests), every named effect but the one whose law changed is tested
    again beside it (the one-record search's retest_after_refinements): on a linear tether, creep
    carried beside a cubic law whose law was just refined earns nothing and is removed. Without a
    kept refinement nothing is tested."""
    from tether.discover.campaign import Campaign, CampaignStep
    from tether.discover.records import Refinement

    recs, _, _ = cr.campaign(4, effects=set(), experiments=("load_unload", "creep"), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    camp = Campaign(traces, "linear", None, 5, 2, None, None, False)
    camp.fit_start()
    start = camp.cur
    weak_creep = {"creep_J1": 1e-9, "creep_J2": 1e-9, "creep_J3": 1e-9, "slip_capacity0": 1e-9}
    camp.cur = camp.fit(parse_model("cubic+creep"), ("nonlinear_stiffness", "creep"),
                        [{**start.params, "a1": start.params["EA"], "a2": 0.0, "a3": 0.0, **weak_creep}])
    assert camp.cur.ok, camp.cur.message
    camp.fits.append(camp.cur)
    camp.steps = [CampaignStep(effect=e, model_before="linear", model_after=camp.cur.model, rms_before=start.rms,
                               rms_after=camp.cur.rms, records_before=start.rms_records,
                               records_after=camp.cur.rms_records) for e in ("creep", "nonlinear_stiffness")]
    refined = Refinement("nonlinear_stiffness", (), camp.cur.rms, camp.cur.rms, 1.0, 1.0, -1.0, False, "not kept",
                         law="cubic -> exponential")
    camp.refinements = [refined]
    camp.retest_after_refinements()
    assert camp.steps[-1].retests == [] and camp.cur.spec.creep     # nothing kept: nothing tested
    camp.refinements = [replace(refined, accepted=True, verdict="kept")]
    camp.retest_after_refinements()
    assert [(t.effect, t.kept) for t in camp.steps[-1].retests] == [("creep", False)], camp.steps[-1].retests
    assert "refined laws (nonlinear_stiffness)" in camp.steps[-1].retests[0].beside
    assert [x.effect for x in camp.removals] == ["creep"] and not camp.cur.spec.creep


def test_load_tests_beyond_their_share_are_thinned_keeping_every_load_step(tmp_path):
    """A load-unload test and a creep test, whose loads are ramps and holds: beyond their share of
    the search's samples they are searched thinned, every corner of the load kept with the samples
    beside it (samples._input_corners), so that the load rebuilt from the kept samples is the
    record's own at every dropped sample (before: a creep test's load steps rebuilt from every 2nd
    sample missed by 36 x the noise, and such records were searched on every sample)."""
    from tether.discover.samples import search_thinning, thinned, thinned_input_miss
    from tether.noise import estimate_noise

    sizes = {**cr.TINY, "load_unload": {"rate": 10.0}}
    recs, _, _ = cr.campaign(4, effects=set(), experiments=("load_unload", "creep"), sizes=sizes)
    for tr, share in zip((read_trace(s) for s in cr.write_campaign(recs, tmp_path)), (700, 200)):
        sigma = estimate_noise(tr).sigma
        k = search_thinning(tr, sigma, share)
        assert k == math.ceil(len(tr.time) / share), (tr.name, k, len(tr.time))
        assert thinned_input_miss(tr, k) <= 1e-6 * sigma
        th = thinned(tr, k)
        assert len(th.time) <= 1.1 * len(tr.time) / k + 1
        steps = np.flatnonzero(np.abs(np.diff(tr.input, 2)) > 1e-6 * np.max(np.abs(tr.input))) + 1
        assert len(steps) >= 3 and set(tr.time[steps]) <= set(th.time)   # every corner of the load kept


def test_an_effect_whose_law_misses_the_record_that_reveals_it_is_fitted_with_its_wider_law(tmp_path):
    """A step fits an effect's wider law (laws.WIDER_LAWS: primary creep for the Kelvin cells and
    slip) beside its own where its own law does not reveal it on its lead record and leaves that
    record unexplained (Campaign.wider_candidates). A tether with the generator's log-kernel creep,
    a load-unload test and a creep test: the Kelvin law fitted reveals it (no wider law is fitted);
    a Kelvin law that cannot follow the creep test (here its compliances held at nothing, as the
    Kelvin cells beside an Iwan bank left campaign 1000's creep test at 14 x its noise) brings the
    primary law into the step, which wins it and brings the creep test within 1.5 x its noise. Before,
    the wider law was tried only at the end and only for a named effect: the step named nothing."""
    from tether.discover.campaign import Campaign

    recs, _, material = cr.campaign(1000, effects={"creep"}, experiments=("load_unload", "creep"), sizes=cr.TINY)
    assert material["creep_kernel"] == "log"
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    lines = []
    camp = Campaign(traces, "linear", lines.append, 5, 2, None, None, False)
    camp.fit_start()
    kelvin = [c for c in camp.candidate_models() if c[0] == "creep"]
    (effect, spec, lead, starts), = kelvin
    assert spec.creep_law == "kelvin_slip" and traces[lead].experiment == "creep"
    effects = camp.cur.effects + ("creep",)
    fitted = camp.candidate_fit(effect, spec, effects, lead, starts)
    assert fitted.rms_records[lead] < 1.5 * camp.records[lead].sigma, fitted.rms_records
    assert camp.wider_candidates(kelvin, [fitted]) == []
    weak_creep = {"creep_J1": 1e-12, "creep_J2": 1e-12, "creep_J3": 1e-12, "slip_capacity0": 1e-12}
    missing = camp.evaluate(spec, effects, {**camp.cur.params, **weak_creep}, camp.law_names(spec), camp.cur.nz)
    assert missing.rms_records[lead] > 3 * camp.records[lead].sigma, missing.rms_records
    wider = camp.wider_candidates(kelvin, [missing])
    assert [(e, m.creep_law, i) for e, m, i, _ in wider] == [("creep", "primary", lead)]

    own_fit = camp.candidate_fit
    camp.candidate_models = lambda: kelvin
    camp.candidate_fit = lambda e, m, *a, **k: missing if m.creep_law == "kelvin_slip" else own_fit(e, m, *a, **k)
    assert camp.step()
    assert camp.steps[-1].effect == "creep" and camp.cur.spec.creep_law == "primary", camp.steps[-1].candidates
    assert all(e <= 1.5 * r.sigma for e, r in zip(camp.cur.rms_records, camp.records)), camp.per_record(camp.cur)
    assert any("the wider law primary is fitted too" in ln for ln in lines), lines


def test_an_effect_refused_only_on_its_held_out_parts_is_fitted_with_its_wider_law(tmp_path, monkeypatch):
    """Every candidate that passed on the whole campaign failed its held-out test: before the step
    ends with nothing, an effect refused there in its own law is fitted with its wider law and
    judged the same way (Campaign.wider_after_heldout). Tuning campaign 1009 stopped so: the Kelvin
    cells fitted every record within 1.14 x noise but predicted the creep test's recovery at 4.68 x
    (2.48 x without creep); the primary creep fitted them within 1.04 x and predicted it at 1.70 x.
    Here the Kelvin law's held-out error is made gross, and the held-out test asked however gross
    the campaign's gap (this tiny campaign's 24 sigma would skip it); the step must name creep in
    the primary law and bring every record within 1.5 x its noise (it used to name nothing)."""
    import dataclasses

    from tether.discover import judge
    from tether.discover.campaign import Campaign

    monkeypatch.setattr(judge, "CRITERIA", dataclasses.replace(judge.CRITERIA, gross_gap=math.inf))

    recs, _, material = cr.campaign(1000, effects={"creep"}, experiments=("load_unload", "creep"), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    lines = []
    camp = Campaign(traces, "linear", lines.append, 5, 2, None, None, False)
    camp.fit_start()
    own_heldout = camp.heldout_of
    camp.heldout_of = lambda f, among=None: (1e3 if f.spec.creep and f.spec.creep_law == "kelvin_slip"
                                             else own_heldout(f, among))
    assert camp.step()
    kelvin = [c for c in camp.steps[-1].candidates if c.effect == "creep" and c.fit.spec.creep_law == "kelvin_slip"]
    assert kelvin and not kelvin[0].accepted and "held-out" in kelvin[0].verdict, kelvin
    assert camp.steps[-1].effect == "creep" and camp.cur.spec.creep_law == "primary", camp.steps[-1].candidates
    assert all(e <= 1.5 * r.sigma for e, r in zip(camp.cur.rms_records, camp.records)), camp.per_record(camp.cur)
    assert any("no candidate passes its held-out test" in ln for ln in lines), lines


def test_a_step_ranks_its_candidates_by_each_record_against_its_own_error(tmp_path):
    """Two candidates pass the judge on the campaign's error in noise units. One takes part of a
    quiet record's misfit alone (a damping on a free vibration missed at 27.7 x its noise by the
    shared law); the other lowers every record a little more in proportion (the figures of the
    creep that campaign 1000's step took, measured 2026-11-27: free vibration 27.68 -> 10.15, load
    test 1.80 -> 1.22, creep test 14.33 -> 14.14 x noise; given here to a cubic law, which every
    record can reveal, so that its gap is read on the whole campaign as the damping's is on the
    free vibration: Campaign.effect_verdict). In noise units the first is ahead (the free vibration,
    with a tenth of the others' noise, outweighs them); read per record against its own error
    (campaign_records.ranked_bic_change, each record's variance its own) the second is, and the
    step names it. Before, the step ranked by the campaign's error in noise units and named the first."""
    from tether.discover.campaign import Campaign, CampaignFit

    recs, _, _ = cr.campaign(1000, effects=set(), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    camp = Campaign(traces, "linear", None, 5, 2, None, None, False)
    n = [r.n for r in camp.records]
    assert [t.experiment for t in traces] == ["free_vibration", "load_unload", "creep"] and n == [301, 294, 631], n

    def fit(model, over_noise, free):
        return CampaignFit(spec=parse_model(model), effects=tuple(parse_model(model).effects), params={}, free=free,
                           rms=math.sqrt(sum(k * z * z for k, z in zip(n, over_noise)) / sum(n)),
                           rms_records=[z * r.sigma for z, r in zip(over_noise, camp.records)], predicted=[],
                           nz=[{}] * 3)

    camp.cur = fit("linear", (27.68, 1.80, 14.33), ["EA", "c0"])
    camp.fits, camp.cur_held = [camp.cur], 20.0
    damping = fit("linear+nonlinear_damping", (9.0, 1.80, 14.33), ["EA", "c0", "c1", "c2"])
    cubic = fit("cubic", (10.15, 1.22, 14.14), ["EA", "c0", "k3"])
    assert damping.rms < cubic.rms < camp.cur.rms                                     # noise units: damping first
    by_record = [sum(k * math.log((a / b) ** 2) for k, a, b in zip(n, f.rms_records, camp.cur.rms_records))
                 for f in (damping, cubic)]
    assert by_record[1] + math.log(sum(n)) < by_record[0] + 2 * math.log(sum(n))   # per record: the cubic first

    cands = [("nonlinear_damping", damping.spec, 0, []), ("nonlinear_stiffness", cubic.spec, 2, [])]
    camp.candidate_models = lambda: cands
    camp.candidate_fit = lambda e, *a, **k: damping if e == "nonlinear_damping" else cubic
    camp.wider_candidates = lambda c, f: []
    # both pass the held-out test (20 -> 10 sigma), on whichever records can reveal them
    camp.heldout_of = lambda f, among=None: 20.0 if f is camp.cur else 10.0
    camp.settle = lambda f: f
    camp.retest_named = lambda step: None
    camp.refit_current = lambda factor: None   # the current model as fitted (its refit: the test below)
    assert camp.step()
    step = camp.steps[-1]
    assert [c.effect for c in step.candidates] == ["nonlinear_stiffness", "nonlinear_damping"]
    assert step.effect == "nonlinear_stiffness"
    assert all(c.accepted == (c.effect == "nonlinear_stiffness") for c in step.candidates), [
        c.verdict for c in step.candidates]


def test_a_step_judges_its_candidates_against_the_current_model_fitted_as_they_are(tmp_path):
    """A step fits each candidate harder than the model it extends was fitted (its lead record alone,
    that record's nuisance free, several starts, every record's nuisance refitted); a current model
    left short of its own best fit credits a candidate with the refit's gain (campaign 1000's step 3:
    the current model fitted the candidates' way reached 10.75 x noise, the candidates 10.96-11.01 x).
    A linear tether, a free vibration and a load test; the current model the linear law fitted with
    the free vibration's offset held five noise levels off: the step fits the model as a candidate is,
    carries that fit on, and names nothing, the records reproduced. Before, it named an effect."""
    from tether.discover.campaign import Campaign

    recs, _, _ = cr.campaign(4, effects=set(), experiments=("free_vibration", "load_unload"), sizes=cr.TINY)
    traces = [read_trace(s) for s in cr.write_campaign(recs, tmp_path)]
    camp = Campaign(traces, "linear", None, 5, 2, None, None, True)
    camp.fit_start()
    best = camp.cur
    assert camp.within_noise(best), camp.per_record(best)
    bent = [dict(nz) for nz in best.nz]
    bent[0]["offset_measured"] += 5 * camp.records[0].sigma
    camp.cur = camp.fit(best.spec, best.effects, [best.params], nzs=bent)
    for r, nz in zip(camp.records, bent):
        r.nz = dict(nz)
    camp.cur_held = camp.heldout_of(camp.cur)
    camp.fits.append(camp.cur)
    assert camp.cur.rms_records[0] > 3 * camp.records[0].sigma, camp.per_record(camp.cur)
    assert camp.step() and [s.effect for s in camp.steps] == []
    assert camp.cur.spec.canonical == "linear" and camp.within_noise(camp.cur), camp.per_record(camp.cur)


@pytest.mark.parametrize("terms, loops", [({"bw_beta": 1e-3, "bw_gamma": -1.3}, False),
                                           ({"bw_beta": 15.0, "bw_gamma": 5.0}, True)])
def test_a_campaign_credits_hysteresis_only_where_its_loops_open(tmp_path, terms, loops):
    """A free vibration and a load test of one tether whose force is a Bouc-Wen law: with beta ~ 0
    and gamma < 0 the law traces no loop (dz/dx depends on z alone), a stiffening elastic curve, and
    the campaign must not name hysteresis for it however well it fits; with beta = 15, gamma = 5
    (the FMU's defaults) it loops, and must. Records: our own model's prediction plus noise of a
    thousandth of each record's range, so the law is exact."""
    from tether.discover.campaign import Campaign

    recs, _, _ = cr.campaign(4, effects=set(), experiments=("free_vibration", "load_unload"), sizes=cr.TINY)
    spec, rng = parse_model("linear+boucwen"), np.random.default_rng(4)
    params = {"EA": 3620.0, "c0": 1.0, "bw_A": 60.0, "bw_beta": 0.0, "bw_gamma": 0.0, **terms}
    traces = []
    for t in (read_trace(s) for s in cr.write_campaign(recs, tmp_path)):
        y = predict(t, spec, params)
        traces.append(replace(t, measured=y + rng.normal(0.0, 1e-3 * np.ptp(y), y.size)))
    camp = Campaign(traces, "linear", None, 5, 2, None, None, False)
    fit = camp.evaluate(spec, ("hysteresis",), params, ["EA", "c0", "bw_A", "bw_beta", "bw_gamma"], [{}] * 2)
    camp.cur = camp.evaluate(parse_model("linear"), (), {"EA": 3620.0, "c0": 1.0}, ["EA", "c0"], [{}] * 2)
    c = camp.judge("hysteresis", fit)
    print(f"FIGURE campaign, Bouc-Wen {terms}: {fit.rms:.2f} x noise (linear {camp.cur.rms:.1f}): {c.verdict}")
    assert fit.rms < 1.1 and camp.cur.rms > 100.0
    assert c.accepted is loops, c.verdict


def test_an_effect_added_removed_and_added_again_is_named_once():
    """added_effects (OUT.json, the bench's named set) lists each effect of the final model once,
    at the addition that stands: the held-out campaign 2005 (2026-11-28) added creep, removed it in
    a re-test and added it again, and was reported as named ['creep', 'creep', 'hysteresis']. An
    effect removed for good is not named; the one-record Discovery reads the same rule."""
    from tether.discover.campaign_records import CampaignDiscovery
    from tether.discover.records import Discovery

    step = lambda e: type("S", (), {"effect": e})()     # noqa: E731 - a step's effect is all the rule reads
    final = type("F", (), {"effects": ("hysteresis", "creep")})()
    steps = [step("creep"), step("hysteresis"), step("slack"), step("creep"), step(None)]
    for cls in (CampaignDiscovery, Discovery):
        d = cls.__new__(cls)
        d.steps, d.fits = steps, [final]
        assert d.added_effects == ["hysteresis", "creep"]


def test_a_record_reveals_an_effect_added_again_once(split_campaign):
    """OUT.json's records[].revealed reads the same rule as added_effects: the split campaign's
    steps with the first one's addition repeated (added, removed, added again) list each revealed
    effect once per record."""
    _, _, d, doc, _ = split_campaign
    again = replace(d, steps=list(d.steps) + [d.steps[0]])
    assert d.steps[0].effect in d.final.effects and d.steps[0].revealed_by
    for before, after in zip(doc["records"], campaign_document(again)["records"]):
        assert after["revealed"] == ([e for e in before["revealed"] if e != d.steps[0].effect]
                                     + [d.steps[0].effect] * (before["name"] in d.steps[0].revealed_by))
        assert len(set(after["revealed"])) == len(after["revealed"])


def test_the_shape_of_a_named_law_is_refined_on_the_campaign(tmp_path):
    """The one-record search's shapes on the campaign (Campaign.refine_shapes): a free vibration and a
    load-unload test of a tether whose stiffness grows as a power of its strain (the generator's
    power law, seed 1005's tether). The cubic law names the nonlinear stiffness, but one cubic
    cannot follow the power law over both records' strains (measured 1.36 and 3.69 x noise); its
    power term freed (pow_F, pow_n), fitted to the record that shows it worst and then to both, is
    the generator's law in our family, and brings both within the noise (measured 1.04 and 0.95 x).
    Its terms stay free in the fits that follow; a law whose shape is free is not refined again."""
    from tether.discover.campaign import Campaign

    recs, _, material = cr.campaign(1005, effects={"nonlinear_stiffness"},
                                    experiments=("free_vibration", "load_unload"), sizes=cr.TINY)
    assert material["stiffness_law"] == "power"
    camp = Campaign([read_trace(s) for s in cr.write_campaign(recs, tmp_path)], "linear", None, 5, 2, None, None, True)
    camp.fit_start()
    assert camp.step() and camp.named() == ["nonlinear_stiffness"] and camp.cur.spec.stiffness == "cubic"
    cubic = [e / r.sigma for e, r in zip(camp.cur.rms_records, camp.records)]
    assert max(cubic) > 2.0, cubic
    camp.refine_shapes()
    assert [(x.parameters, x.accepted) for x in camp.refinements] == [(("pow_F", "pow_n"), True)], camp.refinements
    shaped = [e / r.sigma for e, r in zip(camp.cur.rms_records, camp.records)]
    assert max(shaped) < 1.5, shaped
    assert {"pow_F", "pow_n"} <= set(camp.settle(camp.cur).free)        # carried into a later fit
    camp.within_noise = lambda m: False         # as if a record were still missed: no group left to free
    camp.refine_shapes()
    assert len(camp.refinements) == 1


def test_a_candidate_is_led_by_the_record_that_shows_it_best(tmp_path):
    """A candidate is fitted alone first to the record that shows it best (Campaign.lead_fit), not
    merely the one the model misses most: a load test and a creep test of a tether whose stiffness
    grows as a power of its strain and that creeps (the generator's seed 3000 tether). The linear
    start misses the load test by its elastic law (measured 1,108.8 x noise) and the creep test by
    its creep (51.1 x). Creep fitted to the load test alone gains nothing there (to 1,108.7 x); to
    the creep test it takes that record to its last few noise levels (measured 4.97 x): the creep
    test leads, whichever record was offered first."""
    from tether.discover.campaign import Campaign
    from tether.discover.laws import _models_for

    recs, _, material = cr.campaign(3000, effects={"nonlinear_stiffness", "creep"},
                                    experiments=("load_unload", "creep"), sizes=cr.TINY)
    assert material["stiffness_law"] == "power"
    camp = Campaign([read_trace(s) for s in cr.write_campaign(recs, tmp_path)], "linear", None, 5, 2, None, None, True)
    camp.fit_start()
    load, creep = camp.records
    assert camp.worst_record(camp.cur) == 0 and camp.cur.rms_records[1] > 20 * creep.sigma, camp.per_record(camp.cur)
    spec = _models_for(camp.cur.spec, "creep", load.trace)[0]
    for offered in (0, 1):
        lead, alone = camp.lead_fit("creep", spec, ("creep",), offered, camp.starts_on(offered, spec), False, None)
        assert lead == 1 and alone.rms < 0.2 * camp.cur.rms_records[1], (offered, lead, alone.rms / creep.sigma)
    assert camp.other_leads("", spec, 0) == []          # the current model refitted keeps its lead
    f = camp.candidate_fit("creep", spec, ("creep",), 0, camp.starts_on(0, spec))
    assert f.ok and f.lead == 1


def test_shapes_judged_before_the_budget_ran_out_are_not_kept():
    """Where the time budget runs out during one shape group's fit (Campaign.refine_shapes), a group
    judged and kept before it is on record as not kept, as the one-record search reports it
    (judge._not_kept_for_budget), and no model is adopted: the steps resumed read a kept refinement
    as a law put in. A cubic and Bouc-Wen: three groups; the first kept, the budget spent in the
    second, the third not fitted."""
    from types import SimpleNamespace

    from tether.discover.campaign_shapes import Shapes

    class Stage(Shapes):
        pass

    stage = Stage()
    stage.cur = SimpleNamespace(spec=parse_model("cubic+boucwen"), effects=("nonlinear_stiffness", "hysteresis"),
                                shape=(), free=["a1", "a2", "a3", "bw_A"], rms=3.0)
    stage.refinements, stage.budget_hit, stage.cur_held, adopted, fitted = [], False, 3.0, [], []
    stage.within_noise = lambda m: False
    stage.say = lambda s: None
    stage.per_record = lambda m: ""
    stage.adopt = lambda m, held: adopted.append(m)

    def shape_fit(m, effect, group):
        fitted.append(group)
        stage.budget_hit = len(fitted) == 2      # the budget runs out while the second group is fitted
        return SimpleNamespace(ok=True, rms=2.0, params={})

    stage.shape_fit = shape_fit
    stage.shape_verdict = lambda cur, fm, refused: (not stage.budget_hit, "kept", float("nan"), -10.0)
    stage.refine_shapes()
    assert len(fitted) == 2 and len(stage.refinements) == 2 and adopted == [], (fitted, stage.refinements)
    assert not any(r.accepted for r in stage.refinements), stage.refinements
    assert "time budget ran out" in stage.refinements[0].verdict


def test_a_candidate_led_by_one_record_starts_its_joint_fit_also_with_the_others_nuisance_under_its_law(tmp_path):
    """A free vibration and a creep test of a tether with Iwan friction that goes slack (the
    generator's seed 3005 tether, the tests' sizes), slack named: the Iwan bank fitted to the free
    vibration alone reaches its noise, and the joint fit from that law starts also with the creep
    test's nuisance (its offset, mass, start) refitted under it, not only held where the law
    without friction left it (Campaign.lead_starts). The candidate brings both records within 1.5 x
    their noise, as the generator's own model would (measured 1.23 and 1.06 x; with the creep
    test's nuisance held, 18.81 and 17.86 x). (The split campaign's creep, led by its creep test,
    needs the other start: the free vibration's nuisance held.)"""
    from tether.discover.campaign import Campaign
    from tether.discover.laws import _models_for

    recs, effects, _ = cr.campaign(3005, experiments=("free_vibration", "creep"), sizes=cr.TINY)
    assert effects == {"hysteresis", "slack"}
    camp = Campaign([read_trace(s) for s in cr.write_campaign(recs, tmp_path)], "linear", None, 5, 2, None, None, True)
    camp.fit_start()
    slack = _models_for(camp.cur.spec, "slack", camp.records[0].trace)[0]
    camp.adopt(camp.candidate_fit("slack", slack, ("slack",), 0, camp.starts_on(0, slack)))
    assert all(e > 5 * r.sigma for e, r in zip(camp.cur.rms_records, camp.records)), camp.per_record(camp.cur)
    iwan = parse_model("linear+iwan+slack")
    f = camp.candidate_fit("hysteresis", iwan, camp.cur.effects + ("hysteresis",), 0, camp.starts_on(0, iwan))
    assert f.ok and f.lead == 0
    assert all(e <= 1.5 * r.sigma for e, r in zip(f.rms_records, camp.records)), camp.per_record(f)


def test_a_campaign_tests_each_effect_whose_law_changed_beside_the_other_changed_law():
    """The campaign's re-test after the last stages (Campaign.retest_after_refinements) where two
    laws changed (a finer Iwan bank and the cubic's shape): every named effect is tested, each of
    the two beside the other's new law; where one law changed, every effect but its own."""
    from types import SimpleNamespace

    from tether.discover.campaign import Campaign
    from tether.discover.records import Refinement

    def refined(effect):
        return Refinement(effect, ("p",), 4.7, 2.6, 5.8, 4.7, -1800.0, True, "")

    for changed, expected in ((("hysteresis", "nonlinear_stiffness"), ["hysteresis", "slack", "nonlinear_stiffness"]),
                              (("hysteresis",), ["slack", "nonlinear_stiffness"])):
        c = Campaign.__new__(Campaign)
        c.refinements, c.retested_at, c.budget_hit, c.base_effects = [refined(e) for e in changed], 0, False, ()
        c.steps = [SimpleNamespace(effect="slack")]
        c.cur = SimpleNamespace(effects=("hysteresis", "slack", "nonlinear_stiffness"))
        asked = []
        c.retest = lambda effects, step, beside: asked.append(list(effects)) and False
        c.retest_after_refinements()
        assert asked == [expected], (changed, asked)
        assert c.retested_at == len(changed)


def test_a_campaign_does_not_test_an_effect_beside_a_changed_law_the_re_test_removed():
    """Two laws changed (a finer Iwan bank and the cubic's shape) and the first re-test removes the
    cubic: the hysteresis is then not tested again, since its own law is the only changed one left
    in the model; slack still is."""
    from types import SimpleNamespace

    from tether.discover.campaign import Campaign
    from tether.discover.records import Refinement

    c = Campaign.__new__(Campaign)
    c.refinements = [Refinement(e, ("p",), 4.7, 2.6, 5.8, 4.7, -1800.0, True, "")
                     for e in ("hysteresis", "nonlinear_stiffness")]
    c.retested_at, c.budget_hit, c.base_effects = 0, False, ()
    c.steps = [SimpleNamespace(effect="slack")]
    c.cur = SimpleNamespace(effects=("hysteresis", "slack", "nonlinear_stiffness"))
    asked = []

    def retest(effects, step, beside):
        asked.append(list(effects))
        if "nonlinear_stiffness" in c.cur.effects:
            c.cur = SimpleNamespace(effects=("hysteresis", "slack"))
            return True
        return False

    c.retest = retest
    c.retest_after_refinements()
    assert asked == [["hysteresis", "slack", "nonlinear_stiffness"], ["slack"]], asked


def test_a_step_near_the_noise_refines_the_named_laws_before_it_fits_a_further_effect():
    """Where the campaign's error leaves a gap below CRITERIA.unexplained_gap in noise units (1.36 x:
    a gap of 0.92), a step first runs the last stages (the named laws' shapes, the finer bank, ...)
    and fits no candidate; once for each set of named effects, again after another is named, and not
    where the gap is larger (1.5 x: 1.12), nothing is named yet, or the last stages last ran for the
    same named effects (the steps resumed after them)."""
    from types import SimpleNamespace

    from tether.discover.campaign import Campaign

    def campaign(rms, named):
        c = Campaign.__new__(Campaign)
        c.cur = SimpleNamespace(rms=rms, effects=tuple(named))
        c.fits, c.refined_for, c.say, c.records = [c.cur], (), (lambda line: None), [None] * 3
        c.steps = [SimpleNamespace(effect=e) for e in named]
        c.candidate_models = lambda: [("creep", None, 0, [])]
        c.cap_factor_for, c.refit_current, c.within_noise = (lambda m: 1.0), (lambda factor: {}), (lambda m: False)
        c.ran, c.budget_hit, c.refinements = [], False, []
        # the last stages run (Campaign.last_stages), each stage itself stubbed: the shapes record
        # the named effects they were run for
        c.refine_shapes = lambda: c.ran.append(tuple(c.named()))
        c.rival_law = c.finer_bank = c.wider_laws = c.retest_after_refinements = lambda: None
        return c

    c = campaign(1.36, ("slack", "hysteresis"))
    assert c.step() is True and c.ran == [("slack", "hysteresis")] and len(c.steps) == 2
    assert not c.refine_first()                       # the same named effects: the step goes on
    c.steps.append(SimpleNamespace(effect="creep"))
    c.cur = SimpleNamespace(rms=1.2, effects=("slack", "hysteresis", "creep"))
    assert c.refine_first() and c.ran[-1] == ("slack", "hysteresis", "creep")
    for rms, named in ((1.5, ("slack", "hysteresis")), (1.2, ())):
        c = campaign(rms, named)
        assert not c.refine_first() and c.ran == []
    # the steps resumed after the last stages: not again for the effects they ran for
    c = campaign(1.2, ("slack", "hysteresis"))
    c.last_stages()
    assert not c.refine_first() and c.ran == [("slack", "hysteresis")]


def test_a_named_laws_refinement_is_led_by_the_worst_of_the_records_that_revealed_it():
    """A named law's shape, finer bank or wider law is fitted first to the record that shows the
    effect worst of those that revealed it (Campaign.revealed_named), not to a record missed for an
    effect the model still lacks: tuning campaign 3000's cubic, revealed by its free vibration and
    load test, with its creep test at 9.20 x noise for want of creep (docs/campaign-discovery.md,
    session 43)."""
    from types import SimpleNamespace

    from tether.discover.campaign import Campaign

    c = Campaign.__new__(Campaign)
    c.records = [SimpleNamespace(name=n, sigma=1.0) for n in ("fv", "load", "creep")]
    c.steps = [SimpleNamespace(effect="nonlinear_stiffness", revealed_by=["fv", "load"]),
               SimpleNamespace(effect=None, revealed_by=[])]
    cur = SimpleNamespace(rms_records=[1.68, 8.81, 9.20])
    assert c.worst_record(cur) == 2
    assert c.revealed_named("nonlinear_stiffness") == (0, 1)
    assert c.worst_record(cur, c.revealed_named("nonlinear_stiffness")) == 1
    c.able_to_reveal = lambda effect: (0, 2)      # an effect no step named: the records that can reveal it
    assert c.revealed_named("hysteresis") == (0, 2)


def test_a_shape_kept_before_an_effect_was_named_is_fitted_again_after_it():
    """A shape kept while a record was missed for an effect not yet named (the steps resumed after
    it) is fitted again from its lead record once that effect is named (Shapes.shape_open), once per
    set of named effects; a shape a finer Iwan bank replaced is not (forget_shapes). Tuning campaign
    3000: the cubic's power term kept before creep left its load test at 5.81 x noise."""
    from types import SimpleNamespace

    from tether.discover.campaign_shapes import Shapes

    class Stage(Shapes):
        pass

    stage = Stage()
    bank = ("iw_eps1", "iw_eps2", "iw_eps3", "iw_eps4", "iw_eps5", "iw_eps6", "iw_eps7", "iw_eps8")
    stage.cur = SimpleNamespace(spec=parse_model("cubic+iwan+creep"),
                                effects=("nonlinear_stiffness", "hysteresis", "creep"),
                                shape=("pow_F", "pow_n") + bank, free=["a1", "a3"], rms=3.0)
    stage.shaped_beside = {("pow_F", "pow_n"): ("nonlinear_stiffness",), bank: ("nonlinear_stiffness", "hysteresis")}
    stage.refinements, stage.budget_hit, stage.cur_held, fitted = [], False, 3.0, []
    stage.within_noise = lambda m: False
    stage.say = stage.per_record = lambda *a: ""
    stage.adopt = lambda m, held: None
    stage.shape_fit = lambda m, effect, group: fitted.append(group) or SimpleNamespace(ok=True, rms=3.5, params={})
    stage.shape_verdict = lambda cur, fm, refused: (False, "not kept", float("nan"), 10.0)
    stage.forget_shapes("hysteresis")
    stage.refine_shapes()
    assert fitted == [("pow_F", "pow_n")], fitted
    stage.refine_shapes()                        # nothing named since: not fitted again
    assert fitted == [("pow_F", "pow_n")], fitted


def test_two_effects_that_tie_on_the_campaign_are_neither_named_and_undetermined():
    """The tie rule of one record's step (judge.refuse_tied_effects) on a campaign's step: two effects
    that pass on the whole campaign and on their held-out parts, whose BIC changes by record lie less
    than CRITERIA.effect_tie_bic apart, are both refused; the campaign's verdict on each is
    undetermined, naming the other. Set wider apart, the better one wins as before."""
    from types import SimpleNamespace

    from tether.discover.campaign import Campaign, CampaignCandidate, CampaignFit
    from tether.discover.campaign_document import _not_earned
    from tether.discover.judge import CRITERIA

    def cand(effect, records_bic):
        f = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=1.0, rms_records=[1.0],
                        predicted=[])
        return CampaignCandidate(effect=effect, fit=f, added_parameters=2, bic_change=records_bic,
                                 records_bic_change=records_bic, verdict="gap 0.96 -> 0.00 sigma", accepted=True)

    camp = Campaign.__new__(Campaign)
    camp.say, camp.heldout_candidates, camp.records = (lambda s: None), 2, []
    camp.cur = CampaignFit(spec=parse_model("linear"), effects=(), params={}, free=[], rms=1.38, rms_records=[1.38],
                           predicted=[])
    camp.cur_held, camp.heldout_of = 1.5, (lambda f, among=None: 1.0)
    hyst, stiff = cand("hysteresis", -499.0), cand("nonlinear_stiffness", -499.0 + 0.5 * CRITERIA.effect_tie_bic)
    assert camp.heldout_tests([hyst, stiff]) is None
    assert not (hyst.accepted or stiff.accepted)
    assert (hyst.tied_with, stiff.tied_with) == ("nonlinear_stiffness", "hysteresis")
    step = SimpleNamespace(candidates=[hyst, stiff])
    d = SimpleNamespace(steps=[step], stop_reason="")
    for effect, other in (("hysteresis", "nonlinear_stiffness"), ("nonlinear_stiffness", "hysteresis")):
        v = _not_earned(d, effect)
        assert v["verdict"] == "undetermined" and other in v["evidence"] and "neither is named" in v["evidence"]
    hyst, stiff = cand("hysteresis", -499.0), cand("nonlinear_stiffness", -499.0 + CRITERIA.effect_tie_bic)
    assert camp.heldout_tests([hyst, stiff]) is hyst and hyst.accepted and not stiff.accepted
    assert not hyst.tied_with
    assert _not_earned(SimpleNamespace(steps=[SimpleNamespace(candidates=[hyst, stiff])], stop_reason=""),
                       "nonlinear_stiffness")["verdict"] == "absent"
