"""docs/results-schema.json is generated from app/io/result.py (scripts/results_schema.py), and real
results.json files (a small block study, two particles) validate against those models, strictly:
numbers are JSON numbers, non-finite ones null and listed in ``non_finite``."""
import json
import pathlib
import sys

import pydantic
import pytest
from conftest import run_scene

from app.io.result import StateResult, StudyResult, json_schema, validate
from app.io.results import write_results

ROOT = pathlib.Path(__file__).resolve().parents[1]
BLOCK = {"name": "block", "mu": 1.0, "system": {"type": "block", "nx": 4, "ny": 2, "nu": 0.3},
         "loading": {"normal_force": 55.0, "normal_steps": 2, "tangential_step": 0.5, "tangential_max": 1.0},
         "analyses": ["necessary", "sufficient", "mceip_lambda2", "mceip_mu"]}
TWO_PARTICLES = {"name": "two-particles", "mu": 2.5,
                 "system": {"type": "two_particles", "k": 1000.0, "m": 2.0, "phi_deg": 35.0, "signs": [1, -1]},
                 "analyses": ["necessary", "sufficient", "mceip_lambda2", "mceip_mu", "enumerate"]}


def _script():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import results_schema
    finally:
        sys.path.pop(0)
    return results_schema


def test_results_schema_is_generated_from_the_models():
    """docs/results-schema.json is the output of scripts/results_schema.py (regenerate: run it)."""
    gen = _script()
    assert (ROOT / "docs" / "results-schema.json").read_text(encoding="utf-8") == gen.generate(), \
        "docs/results-schema.json is stale: run .venv/bin/python scripts/results_schema.py"
    assert gen.main(["--check"]) == 0
    schema = json.loads(gen.generate())
    assert schema["properties"]["format_version"]["const"] == 3 and "states" in schema["required"]
    sol = schema["$defs"]["MceipSolution"]["properties"]
    assert {"type": "number"} in sol["value"]["anyOf"] and {"type": "null"} in sol["value"]["anyOf"]
    assert {"onset", "complete", "certificate", "search", "solutions"} <= schema["$defs"]["MceipMuResult"]["properties"].keys()
    assert "non_finite" in schema["properties"] and schema == json_schema()


@pytest.fixture(scope="module", params=[BLOCK, TWO_PARTICLES], ids=["block", "two_particles"])
def document(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("schema")
    write_results(StudyResult.from_dict(run_scene(request.param)), out)
    return (out / "results.json").read_text()


def test_results_json_validates_against_the_schema(document):
    doc = validate(document)
    data = json.loads(document)
    assert len(doc.states) == len(data["states"]) and doc.format_version == 3
    # every top-level key and every state key the run wrote is described by the schema
    assert set(data) <= StudyResult.model_fields.keys()
    assert set().union(*(s.keys() for s in data["states"])) <= StateResult.model_fields.keys()
    for s in data["states"]:
        assert set(s["analyses"]) <= {"necessary", "sufficient", "mceip_mu", "mceip_lambda2", "enumerate"}
    if "enumerate" in data["analyses_requested"]:          # two particles: proofs with infinite intervals
        assert doc.non_finite is not None and doc.states[0].analyses.enumerate.complete is True
        assert doc.states[0].analyses.mceip_mu.onset is not None


def test_the_schema_refuses_what_results_json_never_holds(document):
    data = json.loads(document)
    bad = json.loads(document)
    bad["states"][0]["nodes"][0]["u_N"] = "inf"                     # format 1's strings: not a number
    with pytest.raises(pydantic.ValidationError, match="u_N"):
        validate(json.dumps(bad))
    bad = json.loads(document)
    del bad["states"][0]["classification"]
    with pytest.raises(pydantic.ValidationError, match="classification"):
        validate(json.dumps(bad))
    with pytest.raises(pydantic.ValidationError, match="format_version"):
        validate(json.dumps({**data, "format_version": 2}))
    bad = json.loads(document)
    bad["states"][0]["nodes"][0]["status"] = "sliding"
    with pytest.raises(pydantic.ValidationError, match="status"):
        validate(json.dumps(bad))
