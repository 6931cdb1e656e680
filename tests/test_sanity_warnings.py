"""Runs whose numbers would mean nothing say so (issue 35): one warning line each in the summary
and in results.json ``warnings``, never a silent exit 0 with "proven on [0, inf]".

- a body that never touches the obstacle;
- a path that slides grossly at its first loading step (E typed in Pa with lengths in mm);
- a Young's modulus or density no real solid has in the scene's units;
- MCEIP-mu asked for on a path where no node ever slips (no unknowns: "no solution" is trivial).

The paper's default study and the shipped scenes raise none of them."""
import json
import pathlib

import pytest
import yaml
from conftest import ROOT, run_cli_here

from app.systems.units import implausible_material

EX = ROOT / "app" / "scenes" / "gmsh"
NEW = ("no contact node touches", "gross sliding at the first loading step", "outside the range of real solids",
       "no contact node slips")


def _run(tmp_path: pathlib.Path, scene: dict) -> tuple[dict, str]:
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    p = run_cli_here("run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "out"))
    assert p.returncode == 0, p.stderr
    return json.loads((tmp_path / "out" / "results.json").read_text()), p.stdout


def _sanity(res: dict) -> list[str]:
    return [w for w in res["warnings"] if any(k in w for k in NEW)]


def _half_disk(tmp_path: pathlib.Path, **changes) -> dict:
    (tmp_path / "half_disk.geo").write_text((EX / "half_disk.geo").read_text().replace("h = 0.04;", "h = 0.5;"))
    s = yaml.safe_load((EX / "half_disk.yaml").read_text())
    s.pop("outputs", None)
    s.update(changes)
    return s


def test_a_body_that_never_touches(tmp_path):
    s = _half_disk(tmp_path, mu=0.5, analyses=["necessary", "sufficient", "mceip_mu", "mceip_lambda2"])
    s["system"]["obstacle"]["point"] = [0.0, -5.0]                   # 5 mm below the disk
    s["system"]["program"] = [{"name": "drag", "steps": 3, "displacement": {"top": {"translation": [1.0, 0.0]}}}]
    res, out = _run(tmp_path, s)
    assert _sanity(res) == [f"no contact node touches the obstacle in any of the {len(res['states'])} states: there "
                            "is no contact to analyse (check the obstacle's position and the loading)"]
    assert "WARNING: no contact node touches the obstacle" in out
    assert "proven on" not in out and out.count("[no slip node: no unknowns, nothing to prove]") == 2


def test_no_node_ever_slips(tmp_path):
    # pressed with friction and never dragged: every node in contact sticks
    res, out = _run(tmp_path, _half_disk(tmp_path, mu=0.5, analyses=["mceip_mu"]))
    assert any(n["status"] == "stick" for n in res["states"][-1]["nodes"])
    assert _sanity(res) == [f"no contact node slips in any of the {len(res['states'])} states: MCEIP-mu and "
                            "MCEIP-lambda^2 have no unknowns, so their 'no solution' holds trivially (nothing was "
                            "proven about slip)"]
    assert "[no slip node: no unknowns, nothing to prove]" in out


def test_young_modulus_in_pascal_with_millimetres(tmp_path):
    """E = 5e6 "MPa" (5 MPa typed in Pa): the block slides grossly at the first 0.02 mm step."""
    s = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
    s.pop("outputs", None)
    s["system"]["E"] = 5.0e6
    res, out = _run(tmp_path, s)
    warnings = _sanity(res)
    assert len(warnings) == 2, warnings
    assert warnings[0].startswith("system.E = 5e+06 MPa is outside the range of real solids (0.0001 to 1.5e+06 MPa)")
    last = res["states"][-1]
    assert warnings[1].startswith(f"gross sliding at the first loading step of its phase (state {last['index']}, "
                                  "phase 'tangential')")
    assert last["load"]["u_x"] == pytest.approx(-s["loading"]["tangential_step"])
    assert all(f"WARNING: {w}" in out for w in warnings)


def test_material_values_no_real_solid_has():
    assert implausible_material("system", 5.0, 1.2e-9, "m-N-Pa-kg-s") == [
        "system.E = 5 Pa is outside the range of real solids (100 to 1.5e+12 Pa) in the scene's units "
        "(m-N-Pa-kg-s): was it given in another unit?",
        "system.density = 1.2e-09 kg/m^3 is outside the range of real solids (0.1 to 25000 kg/m^3) in the scene's "
        "units (m-N-Pa-kg-s): was it given in another unit?"]
    assert implausible_material("system", 5.0e6, 1200.0, "m-N-Pa-kg-s") == []         # rubber in SI
    assert implausible_material("system", 210e3, 7.85e-9, "mm-N-MPa-tonne-s") == []   # steel in mm
    assert len(implausible_material("system", 210e9, 7850.0, "mm-N-MPa-tonne-s")) == 2   # steel in SI, declared mm


def test_the_default_study_raises_none(tmp_path):
    s = yaml.safe_load((ROOT / "app/scenes/villechaise_block.yaml").read_text())
    s.pop("outputs", None)
    res, out = _run(tmp_path, s)
    assert _sanity(res) == [] and "proven on [0, 11]" in out



def test_a_final_stick_zone_one_node_wide():
    """app/loading/sanity.py ``check_final_stick_zone``: one warning naming the state and where a
    lone stuck node is; none for a zone two nodes wide or a state without one."""
    from app.loading.classify import FREE, SLIP, STICK, Classification
    from app.loading.sanity import check_final_stick_zone
    x = [4.0, 0.0, 1.0, 2.0, 3.0]                       # node 1 is at one end of the contact curve
    lone = Classification(status=(FREE, STICK, SLIP, SLIP, FREE), signs=(0, 0, 1, 1, 0))
    w = check_final_stick_zone(lone, x, 12, "mm")
    assert len(w) == 1 and "state 12" in w[0] and "at x = 0 mm" in w[0] and "1 stick zone(s)" in w[0]
    wide = Classification(status=(FREE, STICK, STICK, SLIP, FREE), signs=(0, 0, 0, 1, 0))
    assert check_final_stick_zone(wide, x, 12, "mm") == []
    assert check_final_stick_zone(Classification(status=(SLIP,) * 5, signs=(1,) * 5), x, 3) == []

@pytest.mark.parametrize("scene", sorted(p.name for p in EX.glob("*.yaml")) + ["../villechaise_block.yaml",
                                                                              "../sweep_mu.yaml",
                                                                              "../sweep_aspect_ratio.yaml",
                                                                              "../refinement.yaml",
                                                                              "../refinement_mixed.yaml",
                                                                              "../block_incompressible.yaml",
                                                                              "../block_plane_strain_mixed.yaml"])
def test_shipped_materials_are_real_solids(scene):
    s = yaml.safe_load((EX / scene).read_text())
    system, units = s["system"], s.get("units", "mm-N-MPa-tonne-s")
    materials = [system] if "E" in system else ([system["material"]] if "material" in system
                                                 else list(system.get("materials", {}).values()))
    assert materials
    for m in materials:
        assert implausible_material("system", m["E"], m.get("density"), units) == []
