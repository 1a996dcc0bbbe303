"""Every JSON output has a `format` key, one name for the intervals, and validates against its
published schema (docs/schemas/FORMAT.schema.json); the outputs are real runs of the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

jsonschema = pytest.importorskip("jsonschema")

REPO = Path(__file__).resolve().parents[1]
SCHEMAS = REPO / "docs" / "schemas"
TRACE = REPO / "reference_results" / "stiffness_8m"      # a load test: fit, validate, discover in seconds


def schema_for(doc: dict) -> dict:
    """The schema the document's own `format` names: tether-X/1 -> docs/schemas/tether-X-1.schema.json."""
    assert "format" in doc, sorted(doc)
    path = SCHEMAS / (doc["format"].replace("/", "-") + ".schema.json")
    assert path.is_file(), f"no schema {path.name} for format {doc['format']!r}"
    schema = json.loads(path.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return schema


def assert_valid(doc: dict) -> None:
    jsonschema.Draft202012Validator(schema_for(doc)).validate(doc)


@pytest.fixture(scope="module")
def outputs(tmp_path_factory, fmu_path):
    from tether.cli import main

    d = tmp_path_factory.mktemp("json-outputs")
    assert main(["fit", str(TRACE), "--model", "cubic", "--out", str(d / "P.json"), "--report", str(d / "fit")]) == 0
    assert main(["validate", str(TRACE), "--report", str(d / "val")]) in (0, 1)
    assert main(["discover", str(TRACE), "--json", str(d / "D.json"), "--budget", "120"]) == 0
    return {"fit --out": json.loads((d / "P.json").read_text()),
            "fit --report fit.json": json.loads((d / "fit" / "fit.json").read_text()),
            "validate validation.json": json.loads((d / "val" / "validation.json").read_text()),
            "discover --json": json.loads((d / "D.json").read_text()),
            "_dir": d}


@pytest.mark.parametrize("which, fmt", [("fit --out", "tether-params/1"), ("fit --report fit.json", "tether-fit/1"),
                                        ("validate validation.json", "tether-validation/1"),
                                        ("discover --json", "tether-discovery/1")])
def test_output_has_its_format_and_follows_its_schema(outputs, which, fmt):
    doc = outputs[which]
    assert doc["format"] == fmt
    assert_valid(doc)


def test_one_name_for_the_intervals(outputs):
    for which in ("fit --out", "fit --report fit.json"):
        doc = outputs[which]
        assert "ci95" not in doc, which
        assert set(doc["intervals"]) == {"a1", "a2", "a3"}, which
        for lo, hi in doc["intervals"].values():
            assert lo <= hi
    # the two files give the same intervals
    assert outputs["fit --out"]["intervals"] == outputs["fit --report fit.json"]["intervals"]


def test_outputs_are_params_files(outputs, fmu_path):
    from tether.models import read_params

    d = outputs["_dir"]
    for name in ("P.json", "D.json"):
        pf = read_params(d / name)
        assert pf.model and pf.parameters


def test_older_ci95_reads_as_intervals(tmp_path, fmu_path):
    from tether.models import read_params

    p = tmp_path / "old.json"
    p.write_text(json.dumps({"model": "linear", "parameters": {"EA": 5e4}, "ci95": {"EA": [4e4, 6e4]}}))
    assert read_params(p).extra["intervals"] == {"EA": [4e4, 6e4]}


def test_bundled_trace_json_follows_the_trace_schema():
    files = sorted((REPO / "reference_results").glob("**/*.json")) + sorted((REPO / "datasets").glob("**/*.json"))
    traces = [f for f in files if json.loads(f.read_text()).get("format") == "tether-trace/1"]
    assert len(traces) >= 19          # 15 paper experiments, the discovery record, 3 benchmark records
    for f in traces:
        assert_valid(json.loads(f.read_text()))


@pytest.mark.parametrize("doc, fragment", [
    ({"format": "tether-params/1", "parameters": {"EA": 1.0}}, "'model' is a required property"),
    ({"format": "tether-params/1", "model": "linear", "parameters": {"EA": "big"}}, "'big' is not of type 'number'"),
    ({"format": "tether-trace/1", "experiment": "forced", "tether": {"length_m": 1.0}}, "'payload_mass_kg' is a required"),
    ({"format": "tether-validation/1", "traces": [{"trace": "x"}]}, "is a required property"),
])
def test_schemas_refuse_what_is_wrong(doc, fragment):
    with pytest.raises(jsonschema.ValidationError, match=fragment):
        assert_valid(doc)
