"""Units live in results.json's ``units`` block, not in key names (format 3); the CSV headers and
the report name the scene's units (``u_x_CD [m]`` in an SI scene); files of formats 1 and 2 still
load, with the old key names mapped to the new ones."""
import csv
import json
import re

import pytest
from conftest import run_scene

from app.io.document import FORMAT_VERSION, RENAMED, from_document
from app.io.report import write_report
from app.io.result import StudyResult
from app.io.results import csv_header, write_results

#: a small block in metres, newtons and pascals (the mm block of tests/test_invariance.py, scaled)
SI_BLOCK = {"name": "si-block", "units": "m-N-Pa-kg-s", "mu": 1.0,
            "system": {"type": "block", "nx": 4, "ny": 2, "length": 0.08, "height": 0.04, "thickness": 0.0096,
                       "E": 5.0e6, "nu": 0.3, "density": 1200.0},
            "loading": {"normal_force": 55.0, "normal_steps": 2, "tangential_step": 0.0005, "tangential_max": 0.001},
            "analyses": ["necessary", "sufficient", "mceip_mu"]}
#: a unit at the end of a key (the paper's u_N, r_N, x_N are components, not units)
UNIT_SUFFIX = re.compile(r"..._(mm|m|N|MPa|Pa|kg|tonne|per_s2)$")


def _keys(obj):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield k
            if k not in ("scene_config", "x_c", "by_method"):   # the scene's own keys; data-keyed maps
                yield from _keys(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _keys(v)


@pytest.fixture(scope="module")
def si_outputs(tmp_path_factory):
    out = tmp_path_factory.mktemp("si")
    write_results(StudyResult.from_dict(run_scene(SI_BLOCK)), out)
    return out


def test_si_results_json_has_units_in_the_units_block_only(si_outputs):
    doc = json.loads((si_outputs / "results.json").read_text())
    assert doc["format_version"] == FORMAT_VERSION == 3
    assert doc["units"]["length"] == "m" and doc["units"]["force"] == "N" and doc["units"]["stress"] == "Pa"
    assert {"normal_displacement", "normal_force", "tangential_step"} <= doc["path"].keys()
    assert doc["path"]["tangential_step"] == 0.0005 and doc["path"]["normal_force"] == pytest.approx(55.0)
    assert not [k for k in _keys(doc) if UNIT_SUFFIX.search(str(k))]
    assert " mm" not in doc["path"]["end"] and " mm" not in doc["system"]


def test_si_steps_csv_headers_name_the_scenes_units(si_outputs):
    with open(si_outputs / "steps.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    head = list(rows[0])
    assert head[:6] == ["index", "phase", "u_x_CD [m]", "u_y_CD [m]", "normal_resultant [N]", "tangential_resultant [N]"]
    assert "sufficient_max_lambda2 [1/s^2]" in head and "mceip_mu_min" in head
    assert not [h for h in head if "mm" in h]
    doc = json.loads((si_outputs / "results.json").read_text())
    assert [float(r["u_x_CD [m]"]) for r in rows] == [s["load"]["u_x"] for s in doc["states"]]


def test_si_report_names_the_scenes_units(si_outputs, tmp_path):
    """report.md of the SI study: its units line and its table's CD displacement are in metres."""
    study = StudyResult.load(si_outputs)
    text = write_report(study, tmp_path, [], [], [], []).read_text()
    assert "Units: length m, force N, time s, lambda2 1/s^2, mu 1," in text and "stress Pa" in text
    assert "| states | CD u_x [m] | stick / slip / free |" in text
    assert "[mm]" not in text and " mm" not in text


def test_two_particles_units_are_the_scenes():
    """The two particles' units block follows the scene's ``units`` (it said mm in an SI scene)."""
    scene = {"name": "tp", "system": {"type": "two_particles", "k": 1000.0, "m": 2.0, "phi_deg": 35.0,
                                      "signs": [1, -1]}, "mu": 2.5, "analyses": ["mceip_mu"]}
    mm, si = run_scene(scene), run_scene({**scene, "units": "m-N-Pa-kg-s"})
    assert mm["units"]["length"] == "mm" and mm["units"]["stiffness"] == "N/mm" and "N/mm" in mm["system"]
    assert si["units"] == {"length": "m", "force": "N", "stiffness": "N/m", "mass": "kg", "time": "s",
                           "lambda2": "1/s^2", "mu": "1"}
    assert "k=1000.0 N/m," in si["system"] and "kg" in si["system"]
    a, b = (r["states"][0]["analyses"]["mceip_mu"] for r in (mm, si))     # labels only: the same answers
    assert [(x["value"], x["pattern"]) for x in a["solutions"]] == [(x["value"], x["pattern"]) for x in b["solutions"]]
    assert a["certificate"]["status"] == b["certificate"]["status"] and a["solutions"]


def test_csv_header_convention():
    units = {"length": "mm", "force": "N", "mu": "1"}
    assert csv_header("u_x_CD", "length", units) == "u_x_CD [mm]"
    assert csv_header("mceip_mu_min", "mu", units) == "mceip_mu_min"          # dimensionless: no brackets
    assert csv_header("n_slip", None, units) == "n_slip"
    assert csv_header("lambda2", "lambda2", units) == "lambda2"               # a unit the system lacks


def test_format_2_names_are_read_as_format_3_names(si_outputs, tmp_path):
    doc = json.loads((si_outputs / "results.json").read_text())
    old = json.loads(json.dumps(doc))
    old["format_version"] = 2
    old["path"] = {{v: k for k, v in RENAMED["path"].items()}.get(k, k): v for k, v in doc["path"].items()}
    assert "normal_displacement_mm" in old["path"] and "normal_displacement" not in old["path"]
    old["path"]["tangential_step_mm"] = None      # a non-finite value under an old name: its pointer is the old name's
    old.setdefault("non_finite", {"reason": "", "values": {}})["values"]["/path/tangential_step_mm"] = "+inf"
    back = from_document(old)
    assert back["path"]["normal_displacement"] == doc["path"]["normal_displacement"]
    assert back["path"]["tangential_step"] == float("inf") and "tangential_step_mm" not in back["path"]
    v1 = {"format_version": 1, "path": {"normal_force_N": 55.0, "end": "x"}, "states": []}
    assert from_document(v1)["path"] == {"normal_force": 55.0, "end": "x"}
    (tmp_path / "results.json").write_text(json.dumps(old))
    r = StudyResult.load(tmp_path)
    assert r.path.normal_force == doc["path"]["normal_force"] and r.units.length == "m"
    assert r.to_json()["format_version"] == 3
